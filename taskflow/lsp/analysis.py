"""The load path on an editor's unsaved text, and what it found, for the language server.

:func:`analyse` runs exactly what ``taskflow validate`` runs — ``yamlsrc`` → ``submission`` (the ``use:``
files, read from the editor's open buffers where it has them) → ``schema`` → the compile passes — on the text
of one buffer and keeps the result: the compiled mission when it compiles, every
:class:`~taskflow.errors.Problem` when it does not.  A sub-mission file (``submission:``) opened on its own is
checked as the loader checks a used file (:func:`~taskflow.mission.submission_file.check_submission`).

:class:`Workspace` holds the latest analysis of every open buffer and the latest one that compiled (the
context completion, hover and navigation read while the buffer is half-typed), and turns problems into
per-file diagnostics: a problem inside a used sub-mission is shown in that file and at the ``use:`` line of
the mission being edited.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from taskflow.errors import MissionError, Problem
from taskflow.lsp.document import DocumentIndex, Span
from taskflow.mission.loader import compile_mission
from taskflow.mission.model import CompiledMission
from taskflow.mission.submission_file import Submission, check_submission
from taskflow.mission.yamlsrc import SourceMap, gc_paused, load_yaml_text


@dataclass
class Analysis:
    """One buffer's text through the load path: what kind of file it is, its YAML data and source map when it
    parses, the compiled mission when it compiles, and every problem found (in any file)."""

    file: str  # the buffer's file path, as problems name it
    text: str
    index: DocumentIndex
    kind: str = "unknown"  # "mission" | "submission" | "unknown" (not a mapping, or does not parse)
    data: Any = None
    smap: SourceMap | None = None
    mission: CompiledMission | None = None
    submission: Submission | None = None
    problems: list[Problem] = field(default_factory=list)

    @property
    def used_files(self) -> set[str]:
        """The sub-mission files this analysis read (spliced in, or reported problems in)."""
        files = {g.smap.file for g in self.smap.grafts.values()} if self.smap is not None else set()
        files |= {p.file for p in self.problems if p.via}
        return {str(Path(f).resolve()) for f in files if not f.startswith("<")}


def analyse(text: str, file: str, sources: dict[Path, str] | None = None) -> Analysis:
    """``text`` (the buffer of ``file``) through the load path; ``sources``: other open buffers by resolved path,
    read instead of their files when the mission uses them.  Never raises for any text.  The garbage collector is
    held off throughout (:func:`~taskflow.mission.yamlsrc.gc_paused`: a large machine's objects are not walked
    again and again while they are built)."""
    with gc_paused():
        return _analyse(text, file, sources)


def _analyse(text: str, file: str, sources: dict[Path, str] | None) -> Analysis:
    nodes: list[Any] = []
    try:
        data, smap = load_yaml_text(text, file, nodes)
    except MissionError as exc:
        index = DocumentIndex.of_node(text, nodes[0]) if nodes else DocumentIndex.build(text)
        return Analysis(file, text, index, problems=list(exc.problems))
    out = Analysis(file, text, DocumentIndex.of_node(text, nodes[0]) if nodes else DocumentIndex.build(text))
    out.data, out.smap = data, smap
    if isinstance(data, dict) and "submission" in data and "mission" not in data:
        out.kind = "submission"
        doc, problems = check_submission(data, smap, ())
        out.submission, out.problems = doc, problems
        return out
    out.kind = "mission" if isinstance(data, dict) else "unknown"
    try:
        out.mission = compile_mission(data, smap, None, sources)
    except MissionError as exc:
        out.problems = list(exc.problems)
    except RecursionError:
        out.problems = [Problem(file, 1, 1, "the document nests too deeply")]
    return out


@dataclass(frozen=True)
class Diagnostic:
    """A problem placed in one file: its span there, its one-line text, and the problem it came from."""

    file: str
    span: Span
    message: str
    problem: Problem
    at_use: bool = False  # shown at the `use:` line for a problem inside the used file


def problem_text(p: Problem) -> str:
    """What a diagnostic says: the message and, after a dash, what would be valid (the CLI's wording)."""
    return f"{p.message} — {p.hint}" if p.hint else p.message


def _split_via(via: str) -> tuple[str, int, int]:
    file, line, col = via.rsplit(":", 2)
    return file, int(line), int(col)


def same_file(a: str, b: str) -> bool:
    if a == b:
        return True
    if a.startswith("<") or b.startswith("<"):
        return False
    return Path(a).resolve() == Path(b).resolve()


class Workspace:
    """The open buffers' texts and analyses; indexes of other files (read from disk) on demand."""

    def __init__(self) -> None:
        self.texts: dict[str, str] = {}  # file → unsaved text of an open buffer
        self.analyses: dict[str, Analysis] = {}
        self.good: dict[str, Analysis] = {}  # file → its latest analysis that compiled (or checked, a sub-mission)
        self._disk: dict[str, tuple[float, DocumentIndex]] = {}

    # -- buffers -------------------------------------------------------------------------------------------
    def close(self, file: str) -> None:
        self.texts.pop(file, None)
        self.analyses.pop(file, None)

    def update(self, file: str) -> Analysis:
        """Analyse the buffer of ``file`` again (after a change)."""
        sources = {Path(f).resolve(): t for f, t in self.texts.items() if f != file and not f.startswith("<")}
        a = analyse(self.texts[file], file, sources)
        self.analyses[file] = a
        if a.mission is not None or (a.kind == "submission" and a.submission is not None):
            self.good[file] = a
        return a

    def text_of(self, file: str) -> str | None:
        """The buffer's text if open, else the file's (None when unreadable)."""
        if file in self.texts:
            return self.texts[file]
        try:
            return Path(file).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return None

    def index_of(self, file: str) -> DocumentIndex | None:
        """The :class:`DocumentIndex` of an open buffer, or of a file on disk (cached while unchanged)."""
        if file in self.analyses and self.analyses[file].text == self.texts.get(file):
            return self.analyses[file].index
        if file in self.texts:
            return DocumentIndex.build(self.texts[file])
        try:
            mtime = Path(file).stat().st_mtime
        except OSError:
            return None
        cached = self._disk.get(file)
        if cached is not None and cached[0] == mtime:
            return cached[1]
        text = self.text_of(file)
        if text is None:
            return None
        index = DocumentIndex.build(text)
        self._disk[file] = (mtime, index)
        return index

    def context(self, file: str) -> Analysis | None:
        """What completion, hover and navigation read for ``file``: its latest analysis when that compiled,
        else its latest one that did (the buffer is being typed), else the latest analysis."""
        a = self.analyses.get(file)
        if a is not None and (a.mission is not None or a.submission is not None):
            return a
        return self.good.get(file, a)

    def missions_using(self, file: str) -> list[Analysis]:
        """Compiled missions (open buffers) into which ``file`` is spliced as a sub-mission."""
        out = []
        for a in self.good.values():
            if a.mission is not None and a.smap is not None and any(
                    same_file(g.smap.file, file) for g in a.smap.grafts.values()):
                out.append(a)
        return out

    # -- diagnostics ---------------------------------------------------------------------------------------
    def diagnostics(self, file: str) -> dict[str, list[Diagnostic]]:
        """The diagnostics of the analysis of ``file``, by the file they are shown in: its own problems in
        ``file``; a problem inside a used sub-mission in that file and at the outermost ``use:`` of ``file``
        it came through."""
        a = self.analyses.get(file)
        out: dict[str, list[Diagnostic]] = {file: []}
        if a is None:
            return out
        for p in a.problems:
            if same_file(p.file, file) or p.file.startswith("<"):
                out[file].append(Diagnostic(file, a.index.span_of_problem(p.line, p.col), problem_text(p), p))
                continue
            index = self.index_of(p.file)
            span = index.span_of_problem(p.line, p.col) if index is not None else Span(0, 0, 0, 0)
            out.setdefault(p.file, []).append(Diagnostic(p.file, span, problem_text(p), p))
            uses = [_split_via(v) for v in p.via]
            mine = [(line, col) for f, line, col in uses if same_file(f, file)]
            if mine:
                line, col = mine[-1]
                where = f"{Path(p.file).name}:{p.line}:{p.col}" if p.line else Path(p.file).name
                out[file].append(Diagnostic(file, a.index.span_of_problem(line, col),
                                            f"in the used sub-mission {where}: {problem_text(p)}", p, at_use=True))
        return out
