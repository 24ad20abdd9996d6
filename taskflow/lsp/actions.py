"""Quick fixes for the problems the load path found, for the language server's code actions.

Each fix reads a problem shown in the requested span (the current analysis's diagnostics, :meth:`Workspace.diagnostics
<taskflow.lsp.analysis.Workspace.diagnostics>`) and the document index of the buffer, and answers a
:class:`~lsprotocol.types.WorkspaceEdit`:

* "did you mean 'X'": the name the message quotes, replaced by the suggestion;
* a state with no way out: a ``{to: TARGET, after: 10 s}`` transition added to it, TARGET the nearest final
  failed state among its siblings and its ancestors' siblings (else the nearest final state);
* a guard number without a unit: the unit of the compared metric (the state's task declares it; else the
  message's example) written after the number.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING

from lsprotocol import types

from taskflow.lsp.analysis import Analysis, Diagnostic
from taskflow.lsp.document import DocumentIndex, Entry, Span
from taskflow.lsp.navigation import children_map
from taskflow.mission.model import YPath

if TYPE_CHECKING:
    from taskflow.lsp.context import Context

TIMEOUT = "10 s"
"""The ``after:`` of an added timeout transition: a placeholder for the author to tune."""

_DID_YOU_MEAN = re.compile(r"did you mean '([^']+)'")
_QUOTED = re.compile(r"'([^']+)'")
_NO_WAY_OUT = re.compile(r"state '([^']+)' has no way out")
_NEEDS_UNIT = re.compile(r"(?P<number>[-+]?[0-9][0-9.eE+-]*) needs a unit: (?P<metric>\S+) is an? \w+"
                         r"(?: — write e\.g\. '[^' ]+ (?P<example>[^']+)')?")


def _lines(text: str) -> list[str]:
    return text.split("\n")


def _entry_at(index: DocumentIndex, span: Span) -> Entry | None:
    """The node whose key (or, for a list item, value) starts where ``span`` starts."""
    for e in index.entries.values():
        if e.key is not None and (e.key.line, e.key.col) == (span.line, span.col):
            return e
    for e in index.entries.values():
        if (e.value.line, e.value.col) == (span.line, span.col):
            return e
    return None


def _fix(ctx: Context, file: str, d: Diagnostic, title: str, edits: list[types.TextEdit]) -> types.CodeAction:
    return types.CodeAction(
        title=title, kind=types.CodeActionKind.QuickFix, is_preferred=True,
        diagnostics=[types.Diagnostic(range=ctx.range(file, d.span), message=d.message, source="taskflow")],
        edit=types.WorkspaceEdit(changes={ctx.uri_of(file): edits}))


def _insert(ctx: Context, file: str, line: int, col: int, text: str) -> types.TextEdit:
    at = ctx.range(file, Span(line, col, line, col))
    return types.TextEdit(range=at, new_text=text)


# -- did you mean ----------------------------------------------------------------------------------------------

def _did_you_mean(ctx: Context, file: str, a: Analysis, d: Diagnostic) -> types.CodeAction | None:
    """Replace the unknown name the message quotes first by the one it suggests."""
    suggestion = _DID_YOU_MEAN.search(d.message)
    wrong = _QUOTED.search(d.problem.message)
    if suggestion is None or wrong is None:
        return None
    lines = _lines(a.text)
    for line in range(d.span.line, min(d.span.end_line, len(lines) - 1) + 1):
        start = d.span.col if line == d.span.line else 0
        end = d.span.end_col if line == d.span.end_line else len(lines[line])
        m = re.search(rf"(?<![\w.$]){re.escape(wrong.group(1))}(?![\w])", lines[line][start:end])
        if m is not None:
            span = Span(line, start + m.start(), line, start + m.end())
            edit = types.TextEdit(range=ctx.range(file, span), new_text=suggestion.group(1))
            return _fix(ctx, file, d, f"Change '{wrong.group(1)}' to '{suggestion.group(1)}'", [edit])
    return None


# -- a timeout for a state with no way out ---------------------------------------------------------------------

def _exit_target(index: DocumentIndex, kids: dict[YPath, list[Entry]], state: YPath) -> str | None:
    """The state a stuck state should time out into: the nearest final failed state among its siblings and
    its ancestors' siblings, else the nearest final state."""
    fallback: str | None = None
    container = state[:-1]
    while len(container) >= 2 and container[-1] == "states":
        for e in kids.get(container, []):
            if e.path == state or not isinstance(e.path[-1], str):
                continue
            final = index.get(e.path + ("final",))
            if final is not None and final.text in ("failed", "aborted"):
                return str(e.path[-1])
            if final is not None and fallback is None:
                fallback = str(e.path[-1])
        container = container[:-2]  # the parent state's own siblings
        if container and container[-1] == "regions":
            container = container[:-2]  # a region's: those of its parallel state
    return fallback


def _last_line(index: DocumentIndex, prefix: YPath) -> int:
    """The last line holding text of the node at ``prefix`` (its scalars and keys)."""
    last = 0
    for e in index.entries.values():
        if e.path[:len(prefix)] != prefix:
            continue
        end = e.value if e.kind == "scalar" else (e.key or e.value)
        last = max(last, end.end_line - 1 if end.end_col == 0 and end.end_line > end.line else end.end_line)
    return last


def _indent(lines: list[str], line: int) -> str:
    text = lines[line] if 0 <= line < len(lines) else ""
    return text[:len(text) - len(text.lstrip())]


def _add_timeout(ctx: Context, file: str, a: Analysis, d: Diagnostic) -> types.CodeAction | None:
    """Add ``{to: TARGET, after: 10 s}`` to the transitions of a state that has no way out."""
    m = _NO_WAY_OUT.search(d.message)
    state = _entry_at(a.index, d.span) if m is not None else None
    if state is None or state.kind != "mapping" or m is None:
        return None
    kids = children_map(a.index)
    target = _exit_target(a.index, kids, state.path)
    if target is None:
        return None
    item = f"{{to: {target}, after: {TIMEOUT}}}"
    lines = _lines(a.text)
    flow = lines[state.value.line][state.value.col:].startswith("{")
    transitions = a.index.get(state.path + ("transitions",))
    if transitions is not None and transitions.kind == "sequence":
        items = kids.get(transitions.path, [])
        if lines[transitions.value.line][transitions.value.col:].startswith("["):
            close = transitions.value.end_col - 1
            edit = _insert(ctx, file, transitions.value.end_line, close, (", " if items else "") + item)
        elif items:
            edit = _insert(ctx, file, _last_line(a.index, transitions.path) + 1, 0,
                           f"{_indent(lines, items[0].value.line)}- {item}\n")
        else:
            return None
    elif transitions is not None:
        return None
    elif flow:
        close = state.value.end_col - 1
        empty = not kids.get(state.path)
        edit = _insert(ctx, file, state.value.end_line, close, ("" if empty else ", ") + f"transitions: [{item}]")
    else:
        keys = kids.get(state.path, [])
        if not keys or keys[0].key is None:
            return None
        indent = " " * keys[0].key.col
        edit = _insert(ctx, file, _last_line(a.index, state.path) + 1, 0,
                       f"{indent}transitions:\n{indent}  - {item}\n")
    return _fix(ctx, file, d, f"Add a timeout: after {TIMEOUT} go to '{target}'", [edit])


# -- a unit for a bare number ----------------------------------------------------------------------------------

def _metric_unit(index: DocumentIndex, state: YPath, metric: str) -> str | None:
    """The unit the task of the state at ``state`` (or of an enclosing one) declares for ``metric``."""
    from taskflow.registry import TASKS

    for k in range(len(state), 1, -1):
        name = index.get(state[:k] + ("task",)) or index.get(state[:k] + ("task", "name"))
        if name is None or name.kind != "scalar" or name.text is None:
            continue
        try:
            unit = TASKS.get(name.text).metrics.get(metric)
        except Exception:
            return None
        return unit if isinstance(unit, str) and unit else None
    return None


def _add_unit(ctx: Context, file: str, a: Analysis, d: Diagnostic) -> types.CodeAction | None:
    """Write the compared metric's unit after a guard's bare number."""
    m = _NEEDS_UNIT.search(d.message)
    guard = _entry_at(a.index, d.span) if m is not None else None
    if m is None or guard is None or guard.kind != "scalar" or guard.value.line != guard.value.end_line:
        return None
    state = guard.path[:-3] if len(guard.path) >= 3 and guard.path[-3] == "transitions" else guard.path[:-1]
    unit = _metric_unit(a.index, state, m.group("metric")) or m.group("example")
    if not unit:
        return None
    text = _lines(a.text)[guard.value.line]
    start = guard.value.col
    after_metric = text.find(m.group("metric"), start)
    number = re.compile(rf"(?<![\w.$]){re.escape(m.group('number'))}(?![\w.])")
    found = number.search(text, max(after_metric, start), guard.value.end_col)
    if found is None:
        return None
    edit = _insert(ctx, file, guard.value.line, found.end(), f" {unit}")
    return _fix(ctx, file, d, f"Add the unit: {m.group('number')} {unit}", [edit])


_FIXES: tuple[Callable[[Context, str, Analysis, Diagnostic], types.CodeAction | None], ...] = (
    _did_you_mean, _add_timeout, _add_unit)


def code_actions(ctx: Context, file: str, span: Span) -> list[types.CodeAction] | None:
    """The quick fixes of the problems shown on the lines of ``span`` in ``file``."""
    a = ctx.ws.analyses.get(file)
    if a is None:
        return None
    shown = [d for d in ctx.ws.diagnostics(file).get(file, [])
             if not d.at_use and d.span.line <= span.end_line and span.line <= d.span.end_line]
    out: list[types.CodeAction] = []
    for d in shown:
        for fix in _FIXES:
            action = fix(ctx, file, a, d)
            if action is not None:
                out.append(action)
    return out
