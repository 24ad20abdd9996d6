"""A run directory's ``trace.csv`` and ``transitions.jsonl`` parsed back (the formats
:mod:`taskflow.execution.records` writes), as untrusted input through :mod:`taskflow.execution.record_io`:
one parse of a ``transitions.jsonl`` line (:func:`record_from_dict`: an
:class:`~taskflow.execution.records.OperatorRecord`, a :class:`~taskflow.execution.records.PropertyRecord` or a
:class:`~taskflow.execution.records.TransitionRecord`),
one of a trace row (:func:`parse_trace_row`, :func:`read_trace`)."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from taskflow.execution.record_io import RunDirError, json_line, lines
from taskflow.execution.records import CAUSES, OPERATOR, PROPERTY, OperatorRecord, PropertyRecord, TransitionRecord

TRACE_FIXED = ("t", "state", "events")
"""The first three columns of every ``trace.csv``."""


def check_trace_header(cells: list[str], where: str) -> list[str]:
    """``trace.csv``'s header ``cells``, or a :class:`~taskflow.execution.record_io.RunDirError` (at ``where``) when it
    does not start with :data:`TRACE_FIXED` or names a column twice."""
    if cells[:3] != list(TRACE_FIXED) or len(set(cells)) != len(cells):
        raise RunDirError(f"{where}: header {','.join(cells)[:80]!r} — a trace starts t,state,events and names "
                          "each column once")
    return cells


def parse_trace_row(header: list[str], cells: list[str], where: str) -> list[Any]:
    """One row of ``trace.csv``: ``[t, state, events, numbers…]`` (NaN where a cell is empty); a row of
    more cells than columns, or a cell that is no number where one belongs, is a
    :class:`~taskflow.execution.record_io.RunDirError` at ``where`` (``FILE:LINE``)."""
    if len(cells) > len(header):
        raise RunDirError(f"{where}: {len(cells)} cells for {len(header)} columns")
    out: list[Any] = []
    for j, name in enumerate(header):
        x = cells[j] if j < len(cells) else ""
        if j in (1, 2):
            out.append(x)
            continue
        try:
            out.append(float(x) if x else math.nan)
        except ValueError:
            raise RunDirError(f"{where}: column {name}: {x[:40]!r} is not a number") from None
    return out


def read_trace(run_dir: str | Path) -> dict[str, np.ndarray]:
    """The trace as columns of numpy arrays (numeric columns as float, NaN where empty).

    Read as untrusted input (:mod:`taskflow.execution.record_io`): inside the run directory, bounded, and a cell
    that is no number where one belongs is a :class:`~taskflow.execution.record_io.RunDirError` naming its line;
    a last row cut short by a crash (no newline) is left out."""
    where = Path(run_dir) / "trace.csv"
    header: list[str] = []
    rows: list[list[Any]] = []
    for n, text, _ in lines(Path(run_dir), "trace.csv", complete_only=True):
        if not text:
            continue
        cells = next(csv.reader([text]))
        if not header:
            header = check_trace_header(cells, f"{where}:{n}")
        else:
            rows.append(parse_trace_row(header, cells, f"{where}:{n}"))
    if not header:
        raise RunDirError(f"{where}: empty — a trace has a header line t,state,events,…")
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] for r in rows]
        out[name] = np.array(col, dtype=object) if name in ("state", "events") else np.array(col, dtype=float)
    return out


def _typed(d: dict[str, Any], key: str, types: tuple[type, ...], what: str, default: Any = ...) -> Any:
    """``d[key]`` when it is one of ``types`` (a bool is no number), ``default`` when absent (required
    when no default); else :class:`ValueError` saying what it should be."""
    if key not in d or (d[key] is None and default is None):
        if default is ...:
            raise ValueError(f"no {key!r} — a {what} is required")
        return default
    v = d[key]
    if isinstance(v, bool) and bool not in types or not isinstance(v, types):
        raise ValueError(f"{key!r} is {type(v).__name__} {str(v)[:40]!r} — {what} was expected")
    return v


_NUMBER = (int, float)
OPERATOR_ACTIONS = ("pause", "hold", "resume", "preempt", "inject")


Record = TransitionRecord | OperatorRecord | PropertyRecord
"""What one line of ``transitions.jsonl`` holds."""
RECORD_CAUSES = (*CAUSES, PROPERTY)
_ATOM_VALUE = (bool, int, float, str)


def record_from_dict(d: Any) -> Record:
    """One line of ``transitions.jsonl`` (parsed JSON) as the record that wrote it: an
    :class:`OperatorRecord` (``cause: operator`` with an ``action``), a :class:`PropertyRecord` (``cause:
    property``: a declared property's first violation) or a :class:`TransitionRecord` (every other line, the
    operator's pre-emption included).  The one parse of that file every reader uses; a line of other shape
    or types is a :class:`ValueError` saying what is wrong."""
    if not isinstance(d, dict):
        raise ValueError(f"a JSON object was expected, got {type(d).__name__}")
    cause = _typed(d, "cause", (str,), "one of " + ", ".join(RECORD_CAUSES))
    if cause not in RECORD_CAUSES:
        raise ValueError(f"cause {cause[:40]!r} — valid: {', '.join(RECORD_CAUSES)}")
    t = float(_typed(d, "t", _NUMBER, "a sim time in s"))
    if not math.isfinite(t):
        raise ValueError(f"'t' is {t} — a finite sim time in s was expected")
    if cause == PROPERTY:
        atoms = _typed(d, "atoms", (dict,), "an object of atom values", {})
        if not all(v is None or isinstance(v, _ATOM_VALUE) for v in atoms.values()):
            raise ValueError("'atoms' holds a value that is no number, truth value or text — atom → value was expected")
        return PropertyRecord(t=t, property=_typed(d, "property", (str,), "a property name"),
                              pattern=_typed(d, "pattern", (str,), "a property pattern", ""),
                              state=_typed(d, "state", (str,), "a state path", ""), atoms=dict(atoms),
                              reason=_typed(d, "reason", (str,), "why", ""),
                              verdict=_typed(d, "verdict", (str,), "a verdict", "violated"))
    if cause == OPERATOR and "action" in d:
        action = _typed(d, "action", (str,), "an operator action")
        if action not in OPERATOR_ACTIONS:
            raise ValueError(f"action {action[:40]!r} — valid: {', '.join(OPERATOR_ACTIONS)}")
        args = _typed(d, "args", (dict,), "an object of strings", {})
        if not all(isinstance(v, str) for v in args.values()):
            raise ValueError("'args' holds a value that is no string — an object of strings was expected")
        return OperatorRecord(t, _typed(d, "tick", (int,), "a tick index"), action,
                              _typed(d, "who", (str,), "a name"), _typed(d, "state", (str,), "a state path", ""),
                              dict(args), _typed(d, "refused", (str,), "why the run could not take it", None))
    metrics = _typed(d, "metrics", (dict,), "an object of metric values", None)
    if metrics is not None and not all(v is None or isinstance(v, _NUMBER) and not isinstance(v, bool)
                                       for v in metrics.values()):
        raise ValueError("'metrics' holds a value that is no number — metric name → number was expected")
    return TransitionRecord(t=t, source=_typed(d, "from", (str,), "a state path"),
                            target=_typed(d, "to", (str,), "a state path"), cause=cause,
                            state=_typed(d, "state", (str,), "a state path", ""),
                            label=_typed(d, "label", (str,), "a transition's label", ""),
                            index=_typed(d, "index", (int,), "a transition index", None), metrics=metrics,
                            event=_typed(d, "event", (str,), "an event name", None),
                            outcome=_typed(d, "outcome", (str,), "an outcome", None),
                            item=_typed(d, "item", (int,), "an item index", None),
                            attempt=_typed(d, "attempt", (int,), "an attempt number", None),
                            resumed=_typed(d, "resumed", (bool,), "true or false", False),
                            who=_typed(d, "who", (str,), "a name", None))


def read_transitions(run_dir: str | Path, *, offset: int = 0, first_line: int = 1,
                     complete_only: bool = False) -> Iterator[tuple[Record, int, int]]:
    """The records of ``transitions.jsonl`` (:func:`record_from_dict`) from byte ``offset``, each with
    its line number and the offset after its line; a malformed line is a
    :class:`~taskflow.execution.record_io.RunDirError` naming it."""
    where = Path(run_dir) / "transitions.jsonl"
    for n, text, end in lines(Path(run_dir), "transitions.jsonl", offset=offset, first_line=first_line,
                              complete_only=complete_only):
        if not text.strip():
            continue
        try:
            yield record_from_dict(json_line(f"{where}:{n}", text)), n, end
        except ValueError as exc:
            if isinstance(exc, RunDirError):
                raise
            raise RunDirError(f"{where}:{n}: {exc}") from None
