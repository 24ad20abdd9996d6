"""Read a YAML mission with the safe loader and remember where every value came from.

The result is the plain Python data plus a map ``path → (line, col)`` (1-based) so that validation
errors can point at the offending key.  Only the safe loader is used: ``!!python/...`` tags are refused.
Aliases are allowed (handy for sharing gains), but a document of more than ``MAX_NODES`` nodes as written is
refused before it is composed, and one that expands past them (an alias bomb) while the source map is walked,
before anything else expands it; no more than ``MAX_BYTES`` are ever read (a device such as ``/dev/zero`` is refused before reading).
"""

from __future__ import annotations

import gc
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from taskflow.errors import MissionError, Problem

Path_ = tuple[Any, ...]
MAX_NODES = 250_000
"""YAML nodes a document may hold (as written, and again with aliases expanded): a 10,000-state machine has about
170,000 (issue 24 asks that it validate in a few seconds), the largest shipped file about 600 — a bigger
document is refused in one line."""
MAX_BYTES = 5_000_000


class MissionLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` with YAML 1.2 booleans: only ``true``/``false`` are booleans, so
    ``on: target_lost`` keeps its key (YAML 1.1 would read ``on``/``off``/``yes``/``no`` as booleans)."""


MissionLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:bool"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
MissionLoader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
# YAML 1.2 floats too: `1e5` and `1.0e5` are numbers (YAML 1.1 wants a dot and a signed exponent)
MissionLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+$"), list("-+0123456789."))


def _construct_bool(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> bool:
    value = str(loader.construct_scalar(node))
    if value.lower() not in ("true", "false"):
        raise yaml.constructor.ConstructorError(None, None, f"{value!r} is not a boolean (true or false)", node.start_mark)
    return value.lower() == "true"


MissionLoader.add_constructor("tag:yaml.org,2002:bool", _construct_bool)

try:
    from yaml._yaml import CParser as _CParser  # libyaml, shipped in PyYAML's wheels
except ImportError:  # pragma: no cover - pure-Python PyYAML: every document takes the Python path
    _CParser = None  # type: ignore[misc, assignment]  # no libyaml: None marks its absence

COMPOSER = "libyaml" if _CParser is not None else "pure Python"
"""Which composer reads a mission that is valid YAML: libyaml's (C, PyYAML's wheels ship it) or, when PyYAML was
built without it, PyYAML's pure-Python one (the same nodes, marks and messages, several times slower)."""

if _CParser is not None:
    class _FastLoader(_CParser, yaml.constructor.SafeConstructor, yaml.resolver.Resolver):
        """:class:`MissionLoader`'s resolvers and constructors over libyaml's composer (about four times
        faster on a big document); used only for text the Python reader accepts, and any YAML error is
        re-read by :class:`MissionLoader` so that messages and positions are its own."""

        yaml_implicit_resolvers = MissionLoader.yaml_implicit_resolvers
        yaml_constructors = MissionLoader.yaml_constructors

        def __init__(self, stream: str) -> None:
            _CParser.__init__(self, stream)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)


def _compose(text: str) -> tuple[Any, yaml.Node | None]:
    """A loader over ``text`` and its one document's node tree: libyaml's when it reads the text without
    error, else the Python one (which then raises the error the messages below are written for)."""
    if _CParser is not None and not yaml.reader.Reader.NON_PRINTABLE.search(text):
        fast = _FastLoader(text)
        try:
            return fast, fast.get_single_node()
        except yaml.YAMLError:
            fast.dispose()
    slow = MissionLoader(text)
    return slow, slow.get_single_node()


def compose_text(text: str) -> yaml.Node | None:
    """The node tree of ``text``'s one document (None when empty), composed with the mission reader's safe
    resolvers; raises ``yaml.YAMLError`` as :func:`load_yaml_text` would see it.  For tools that need every
    node's start and end (the language server); the loader itself goes through :func:`load_yaml_text`."""
    loader, node = _compose(text)
    loader.dispose()
    return node


@dataclass(frozen=True)
class Graft:
    """Values spliced into a document from elsewhere (a used sub-mission, :mod:`taskflow.mission.submission`):
    whatever sits under ``prefix`` came from ``smap`` under ``base``; ``via`` is where that file was used
    from (``FILE:LINE:COL``, innermost first; empty when ``smap`` is the same document)."""

    prefix: Path_
    smap: SourceMap
    base: Path_
    via: tuple[str, ...] = ()


class SourceMap:
    """Where each value of a loaded document sits in its file — or, under a :class:`Graft`, in the file
    it was spliced from."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.marks: dict[Path_, tuple[int, int]] = {}
        self.overrides: dict[Path_, str] = {}  # path → the --set KEY=VALUE that wrote it
        self.grafts: dict[Path_, Graft] = {}  # prefix → the graft spliced there (the first one wins)
        self.uses: dict[Path_, str] = {}  # state path → the sub-mission file it uses, as written (graphs)

    def graft(self, graft: Graft) -> None:
        """Record ``graft`` (a lookup walks the prefixes of a path, longest first: no scan of every graft)."""
        self.grafts.setdefault(graft.prefix, graft)

    def where(self, path: Path_) -> tuple[int, int]:
        """Line and column of ``path``, or of its nearest ancestor that has a mark."""
        p = tuple(path)
        while p:
            if p + ("__key__",) in self.marks:
                return self.marks[p + ("__key__",)]
            if p in self.marks:
                return self.marks[p]
            p = p[:-1]
        return self.marks.get((), (1, 1))

    def problem(self, path: Path_, message: str, hint: str = "") -> Problem:
        p = tuple(path)
        for opath, item in self.overrides.items():
            # inside the overridden value, or the mapping it was written into (e.g. a missing key there)
            if p[: len(opath)] == opath or (len(p) == len(opath) - 1 and opath[: len(p)] == p and p):
                return Problem(self.file, 0, 0, f"--set {item}: {message}", hint)
        graft = next((g for k in range(len(p), -1, -1) if (g := self.grafts.get(p[:k])) is not None), None)
        if graft is not None:
            inner = graft.smap.problem(graft.base + p[len(graft.prefix):], message, hint)
            return replace(inner, via=inner.via + graft.via)
        line, col = self.where(path)
        return Problem(self.file, line, col, message, hint)


def _walk(node: yaml.Node, path: Path_, smap: SourceMap, budget: list[int]) -> None:
    budget[0] -= 1
    if budget[0] < 0:
        raise _TooBig()
    smap.marks.setdefault(path, (node.start_mark.line + 1, node.start_mark.column + 1))
    if isinstance(node, yaml.MappingNode):
        seen: dict[str, int] = {}
        for key_node, value_node in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else str(key_node.value)
            line = key_node.start_mark.line + 1
            if key in seen and isinstance(key_node, yaml.ScalarNode) and key != "<<":
                raise _Duplicate(key, line, key_node.start_mark.column + 1, seen[key])
            seen[key] = line
            smap.marks.setdefault(path + (key, "__key__"), (line, key_node.start_mark.column + 1))
            _walk(value_node, path + (key,), smap, budget)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _walk(item, path + (i,), smap, budget)


class _TooBig(Exception):
    pass


class _Duplicate(Exception):
    def __init__(self, key: str, line: int, col: int, first: int) -> None:
        self.key, self.line, self.col, self.first = key, line, col, first


def _bad_scalar(node: yaml.Node, loader: yaml.SafeLoader, budget: list[int]) -> tuple[yaml.Node, Exception] | None:
    """The first scalar whose explicit tag cannot be constructed (``!!float fast``), with its error."""
    budget[0] -= 1
    if budget[0] < 0:
        return None
    if isinstance(node, yaml.ScalarNode):
        try:
            loader.construct_object(node, deep=True)
        except Exception as exc:
            return node, exc
        return None
    children: list[yaml.Node] = []
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            children += [k, v]
    elif isinstance(node, yaml.SequenceNode):
        children = list(node.value)
    for child in children:
        found = _bad_scalar(child, loader, budget)
        if found is not None:
            return found
    return None


_NODE_EVENTS = (yaml.ScalarEvent, yaml.MappingStartEvent, yaml.SequenceStartEvent, yaml.AliasEvent)


def too_many_nodes(text: str, limit: int) -> bool:
    """Whether the document has more than ``limit`` nodes as written (aliases counted once), found with
    libyaml's event parser before anything is built — composing a huge document in Python would take
    seconds and hundreds of MB only to be refused.  A syntax error stops the count (the loader reports it).

    libyaml first counts every event in C (``raw_parse``, a few ms for a 10,000-state machine): each node is
    at least one event and the stream and its document add four, so ``events - 4 <= limit`` answers "no" without
    a Python loop over the events; only a document that may be over the limit (or has a syntax error) is
    counted node by node."""
    try:
        from yaml._yaml import CParser  # libyaml, shipped in PyYAML's wheels
    except ImportError:  # pragma: no cover - pure-Python PyYAML: the walk's budget still applies
        return False
    parser = CParser(text)
    try:
        if parser.raw_parse() - 4 <= limit:
            return False
    except yaml.YAMLError:
        pass  # counted below up to the error, as written before it
    finally:
        parser.dispose()
    parser = CParser(text)
    n = 0
    try:
        while True:
            event = parser.get_event()
            if event is None or isinstance(event, yaml.StreamEndEvent):
                return False
            if isinstance(event, _NODE_EVENTS):
                n += 1
                if n > limit:
                    return True
    except yaml.YAMLError:
        return False
    finally:
        parser.dispose()


def _node_limit_problem(file: str) -> MissionError:
    return MissionError([Problem(file, 1, 1, f"the document has more than {MAX_NODES} YAML nodes (keys, values "
                                 "and list items, counted after aliases expand): over the limit",
                                 f"a mission may have at most {MAX_NODES} nodes; split it, or share less through "
                                 "nested aliases")])


@contextmanager
def gc_paused() -> Iterator[None]:
    """Python's cyclic garbage collector held off for the block (and restored as it was).  A load builds objects by
    the hundred thousand (nodes, marks, the data, the compiled tree) that all live until it ends: each collection
    the allocations trigger walks every one of them again, which made loading superlinear — a 10,000-state
    mission's YAML composed in 9-13 s with the collector on, 1.6 s with it off (libyaml).  Reference counting
    still frees what the block drops; cycles made in it are collected after it."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def load_yaml_text(text: str, file: str, nodes: list[yaml.Node] | None = None) -> tuple[Any, SourceMap]:
    """``text``'s data and source map; ``nodes``, when given, receives the composed node tree (for a tool that
    needs every node's extent too: the language server, which then composes the text once)."""
    with gc_paused():
        return _load_yaml_text(text, file, nodes)


def _load_yaml_text(text: str, file: str, nodes: list[yaml.Node] | None) -> tuple[Any, SourceMap]:
    smap = SourceMap(file)
    if len(text) > MAX_BYTES:
        raise MissionError([Problem(file, 1, 1, f"file is {len(text)} bytes", f"a mission must be under {MAX_BYTES} bytes")])
    if too_many_nodes(text, MAX_NODES):
        raise _node_limit_problem(file)
    loader: Any = None
    node: yaml.Node | None = None
    try:
        loader, node = _compose(text)
        if node is None:
            raise MissionError([Problem(file, 1, 1, "the file is empty", "a mission needs at least `mission`, `robot`, `world`, `rate_hz` and `machine`")])
        if nodes is not None:
            nodes.append(node)
        try:
            _walk(node, (), smap, [MAX_NODES])  # again with aliases expanded
        except _Duplicate as dup:
            raise MissionError([Problem(file, dup.line, dup.col, f"duplicate key {dup.key!r}",
                                        f"it is already given on line {dup.first}; keep one")]) from None
        data = loader.construct_document(node)
    except _TooBig:
        raise _node_limit_problem(file) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        col = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        char = chr(exc.character) if isinstance(exc.character, int) else exc.character
        raise MissionError([Problem(file, line, col, f"character {char!r} is not allowed in YAML",
                                    "remove control characters from the file")]) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        what = exc.problem or "malformed YAML"
        hint = exc.context or ""
        if exc.context_mark is not None and exc.problem_mark is not None and exc.context_mark.line != exc.problem_mark.line:
            hint = f"{hint} started at line {exc.context_mark.line + 1}, column {exc.context_mark.column + 1}".strip()
        if isinstance(exc, yaml.constructor.ConstructorError):
            hint = "only plain YAML is accepted (no !!python tags or custom tags)"
            if "not a boolean" in what:
                hint = "write true or false"
        raise MissionError([Problem(file, line, col, f"YAML error: {what}", hint)]) from None
    except yaml.YAMLError as exc:
        raise MissionError([Problem(file, 1, 1, f"YAML error: {exc}")]) from None
    except RecursionError:
        raise MissionError([Problem(file, 1, 1, "the document nests too deeply")]) from None
    except (ValueError, TypeError, KeyError, AttributeError, OverflowError) as exc:
        # an explicit tag PyYAML cannot construct (``!!float fast``, ``!!int 0x``): find which one
        found = _bad_scalar(node, MissionLoader(""), [MAX_NODES]) if node is not None else None
        if found is not None:
            bad, err = found
            raise MissionError([Problem(file, bad.start_mark.line + 1, bad.start_mark.column + 1,
                                        f"YAML error: {bad.value!r} cannot be read as {bad.tag.rsplit(':', 1)[-1]}",
                                        "fix the value or drop the explicit !! tag")]) from None
        raise MissionError([Problem(file, 1, 1, f"YAML error: {exc}")]) from None
    finally:
        if loader is not None:
            loader.dispose()
    return data, smap


def load_yaml_file(path: str | Path) -> tuple[Any, SourceMap, str]:
    """Read ``path``; every I/O problem becomes a :class:`MissionError`, never a traceback."""
    p = Path(path)
    file = str(path)
    if not p.exists():
        raise MissionError([Problem(file, 0, 0, "no such file", "check the path")])
    if p.is_dir():
        raise MissionError([Problem(file, 0, 0, "is a directory, not a mission file", "give a .yaml file")])
    if not p.is_file():
        raise MissionError([Problem(file, 0, 0, "is not a regular file (a device, pipe or socket)",
                                    "give a .yaml file")])
    try:
        with open(p, "rb") as f:
            raw = f.read(MAX_BYTES + 1)  # never more than the limit, whatever the file claims to be
    except OSError as exc:
        raise MissionError([Problem(file, 0, 0, f"cannot read: {exc.strerror or exc}")]) from None
    if len(raw) > MAX_BYTES:
        raise MissionError([Problem(file, 1, 1, f"file is larger than {MAX_BYTES} bytes",
                                    f"a mission must be under {MAX_BYTES} bytes")])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MissionError([Problem(file, 1, 1, f"not UTF-8 text (byte {exc.start})", "save the file as UTF-8")]) from None
    data, smap = load_yaml_text(text, file)
    return data, smap, text
