"""Reading a record's files as untrusted input: only inside its folder, bounded, one clear error.

Records travel (a colleague's run, a CI artifact, a campaign from a cluster), so every reader of a run
or batch directory (:mod:`taskflow.readers.recorded`, :mod:`taskflow.operate.view`, :mod:`taskflow.execution.frames`,
:mod:`taskflow.campaigns.compare`, :mod:`taskflow.campaigns.campaign`) opens its files through this module:

* :func:`inside` resolves a name the record gives (``frames.jsonl``'s ``file``, ``trace.csv`` itself)
  and refuses one that leads outside the folder — ``..`` in it, an absolute path, or a symbolic link
  whose target is elsewhere (a link that stays inside is followed);
* :func:`read_bytes` / :func:`read_json` refuse a file larger than its cap (:data:`MAX_JSON_BYTES`,
  :data:`MAX_FRAME_BYTES` …) before reading it, and :func:`lines` reads a line at most
  :data:`MAX_LINE_BYTES` long (no unbounded read of a multi-GB line);
* :func:`check_summary` checks the fields of ``summary.json`` its readers use have their types.

Every problem is a :class:`RunDirError` whose message is one line ``FILE[:LINE]: what is wrong — what
would be valid``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError

MAX_LINE_BYTES = 1 << 20
"""Longest line of ``trace.csv``, ``transitions.jsonl`` or ``frames.jsonl`` read (1 MiB; a recorded row
is a few kB)."""
MAX_TABLE_BYTES = 2 << 30
"""Largest ``trace.csv`` / ``*.jsonl`` read (2 GiB)."""
MAX_JSON_BYTES = 256 << 20
"""Largest JSON document read whole (``summary.json``, ``batch.json``, a trial record: 256 MiB)."""
MAX_FRAME_BYTES = 64 << 20
"""Largest recorded camera frame or ``mission.yaml`` read (64 MiB)."""


class RunDirError(ValueError):
    """A folder that is not a readable record, or a record that is malformed or hostile: the message is
    one line naming the file (and line) and what is wrong."""


class NotJSONError(RunDirError):
    """A file or line that is not (whole) JSON: a :class:`RunDirError` a reader may take for a record cut
    short by a crash."""


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.0f} MiB"


def inside(root: Path, name: str | Path) -> Path:
    """The real path of ``root / name``, refused (:class:`RunDirError`) when it leads outside ``root``."""
    base = Path(root).resolve()
    given = Path(root) / name
    try:
        real = given.resolve()
    except (OSError, RuntimeError) as exc:  # a loop of links
        raise RunDirError(f"{given}: cannot be resolved ({type(exc).__name__}) — a record names plain files "
                          "inside its folder") from None
    if real != base and base not in real.parents:
        how = "a link to a file" if given.is_symlink() or any(p.is_symlink() for p in given.parents) else "a path"
        raise RunDirError(f"{given}: {how} outside the record's folder {root} — a record names only files "
                          "inside its folder")
    return real


def _regular(root: Path, name: str | Path) -> Path:
    """:func:`inside`, and refused when it exists but is no regular file (a folder, a FIFO, a device)."""
    path = inside(root, name)
    if path.exists() and not path.is_file():
        raise RunDirError(f"{Path(root) / name}: not a regular file — a run record holds plain files")
    return path


def read_bytes(root: Path, name: str | Path, limit: int) -> bytes:
    """The bytes of ``root / name`` (inside ``root``, at most ``limit`` of them)."""
    path = _regular(root, name)
    where = Path(root) / name
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
    except FileNotFoundError:
        raise RunDirError(f"{where}: missing — a run record has it") from None
    except OSError as exc:
        raise RunDirError(f"{where}: unreadable ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise RunDirError(f"{where}: larger than {_mib(limit)} — not a file taskflow writes")
    return data


def read_json(root: Path, name: str | Path, limit: int | None = None) -> Any:
    """The JSON document ``root / name`` (:func:`read_bytes`, at most ``limit`` bytes, default
    :data:`MAX_JSON_BYTES`), its syntax errors as ``FILE:LINE:COL``."""
    data = read_bytes(root, name, MAX_JSON_BYTES if limit is None else limit)
    try:
        return json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise RunDirError(f"{Path(root) / name}: byte {exc.start} is not UTF-8 — JSON text was expected") from None
    except json.JSONDecodeError as exc:
        raise NotJSONError(f"{Path(root) / name}:{exc.lineno}:{exc.colno}: not JSON ({exc.msg})") from None
    except RecursionError:
        raise RunDirError(f"{Path(root) / name}: nested too deep — not a file taskflow writes") from None


def lines(root: Path, name: str | Path, *, offset: int = 0, first_line: int = 1, complete_only: bool = False,
          line_limit: int | None = None, file_limit: int | None = None) -> Iterator[tuple[int, str, int]]:
    """``(line number, text without its newline, offset after it)`` of ``root / name`` from byte
    ``offset`` (numbered from ``first_line``).  A line longer than ``line_limit``, a file larger than
    ``file_limit`` (defaults :data:`MAX_LINE_BYTES`, :data:`MAX_TABLE_BYTES`) or bytes that are not UTF-8
    are a :class:`RunDirError`; with ``complete_only`` a last line without its newline (the recorder
    half-way through it) is left for the next read."""
    line_limit = MAX_LINE_BYTES if line_limit is None else line_limit
    file_limit = MAX_TABLE_BYTES if file_limit is None else file_limit
    path = _regular(root, name)
    where = Path(root) / name
    try:
        f = open(path, "rb")  # noqa: SIM115 - closed below on every path
    except FileNotFoundError:
        raise RunDirError(f"{where}: missing — a run record has it") from None
    except OSError as exc:
        raise RunDirError(f"{where}: unreadable ({exc.strerror or exc})") from None
    with f:
        size = f.seek(0, 2)
        if size > file_limit:
            raise RunDirError(f"{where}: larger than {_mib(file_limit)} — not a file taskflow writes")
        if size < offset:
            raise RunDirError(f"{where}: shorter than when it was last read — a record being written only grows")
        f.seek(offset)
        n = first_line
        while True:
            raw = f.readline(line_limit + 1)
            if not raw:
                return
            if len(raw) > line_limit:
                raise RunDirError(f"{where}:{n}: a line longer than {_mib(line_limit)} — not a line taskflow writes")
            if not raw.endswith(b"\n") and complete_only:
                return
            offset += len(raw)
            try:
                text = raw.decode("utf-8").rstrip("\r\n")
            except UnicodeDecodeError as exc:
                raise RunDirError(f"{where}:{n}: byte {exc.start} is not UTF-8 — a line of text was expected") from None
            yield n, text, offset
            n += 1


def json_line(where: str, text: str) -> Any:
    """One line of a ``.jsonl`` file parsed (``where`` is ``FILE:LINE`` for the error)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise NotJSONError(f"{where}:{exc.colno}: not JSON ({exc.msg})") from None
    except RecursionError:
        raise RunDirError(f"{where}: nested too deep — not a line taskflow writes") from None


def problem(exc: ValidationError) -> str:
    """The first error pydantic found, in one line: ``field.path: what (got TYPE)``."""
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"]) or "the document"
    return f"{loc}: {err['msg'].lower()} (got {type(err.get('input')).__name__})"


class _Items(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    attempted: int
    succeeded: int
    required: int = 0
    rule: str = ""


class SummaryFields(BaseModel):
    """The fields of ``summary.json`` (and of a trial in ``batch.json``) that readers use, with their types;
    others are kept as they are.  A summary written at the start of a run has only the first few."""

    model_config = ConfigDict(extra="allow", strict=True)
    outcome: str = ""
    reason: str = ""
    mission: str = ""
    file: str = ""
    seed: int | None = None
    final_state: str = ""
    sim_time_s: float | None = None
    ticks: int = 0
    items: dict[str, _Items] = {}
    metrics: dict[str, Any] = {}


def check_summary(data: Any, where: str | Path, require: tuple[str, ...] = ()) -> dict[str, Any]:
    """``data`` (a parsed ``summary.json``) when its fields have their types and those in ``require``
    are there, else :class:`RunDirError`."""
    if not isinstance(data, dict):
        raise RunDirError(f"{where}: a JSON object was expected, got {type(data).__name__}")
    missing = [k for k in require if data.get(k) is None]
    if missing:
        raise RunDirError(f"{where}: no {missing[0]!r} — a finished run's summary has it")
    try:
        SummaryFields.model_validate(data)
    except ValidationError as exc:
        raise RunDirError(f"{where}: {problem(exc)}") from None
    return data


__all__ = ["MAX_FRAME_BYTES", "MAX_JSON_BYTES", "MAX_LINE_BYTES", "MAX_TABLE_BYTES", "NotJSONError", "RunDirError",
           "SummaryFields",
           "check_summary", "inside", "json_line", "lines", "problem", "read_bytes", "read_json"]
