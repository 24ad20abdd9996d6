"""Navigation in mission files, for the language server: go to definition, find references, the state tree as
document symbols, and renaming a state.

What a name under the cursor means is read from the compiled mission (:attr:`Workspace.context
<taskflow.lsp.analysis.Workspace.context>`: the latest analysis that compiled, so navigation keeps working while
the buffer is half-typed): a transition's target is the state its compiled :class:`~taskflow.mission.model.Transition`
enters, not a re-resolution of the name.  A sub-mission file is read through an open mission that uses it (its
paths mapped into the expanded document by the source map's grafts); with none open, its own text answers what
it can (its parameters and profiles).  Where a path of the expanded document is written — in the mission or in
a used sub-mission — comes from the source map (:func:`written_at`).
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lsprotocol import types

from taskflow.lsp.analysis import Analysis, same_file
from taskflow.lsp.document import DocumentIndex, Entry, Span, cursor_at
from taskflow.mission.guards import DATA_PREFIX, Atom, Node
from taskflow.mission.model import CompiledMission, StateNode, YPath
from taskflow.mission.submission import use_path
from taskflow.mission.yamlsrc import SourceMap

if TYPE_CHECKING:
    from taskflow.lsp.context import Context

_NAME_CHARS = re.compile(r"[A-Za-z0-9_.$\-]+")
_STATE_CONTAINERS = ("states", "regions")
_MAX_USE_DEPTH = 8  # sub-missions shown in the outline inside sub-missions, at most this deep


# -- what the cursor is on -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Spot:
    """The name under the cursor: the path of its node in its own file, whether it is a key, the word (a run
    of name characters: ``a.b.c``, ``$name``, ``data.key``) with its span, and — when a compiled mission covers
    the file — that mission's analysis and the node's path in the expanded document."""

    path: YPath
    on_key: bool
    word: str
    span: Span
    mission: Analysis | None = None
    ypath: YPath = ()

    def component(self, col: int) -> tuple[int, str, Span]:
        """The dotted component of the word at column ``col``: (its index, its text, its span)."""
        start = self.span.col
        for i, part in enumerate(self.word.split(".")):
            end = start + len(part)
            if col <= end or i == self.word.count("."):
                return i, part, Span(self.span.line, start, self.span.line, end)
            start = end + 1
        return 0, self.word, self.span


def word_at(text: str, line: int, col: int) -> tuple[str, Span] | None:
    """The run of name characters around (``line``, ``col``) and its span; None on blank or punctuation."""
    lines = text.split("\n")
    if not 0 <= line < len(lines):
        return None
    for m in _NAME_CHARS.finditer(lines[line]):
        if m.start() <= col <= m.end():
            return m.group(0), Span(line, m.start(), line, m.end())
    return None


def _in_comment(line_text: str, col: int) -> bool:
    """Whether column ``col`` of a line is in a comment (a ``#`` at the line's start or after a blank)."""
    return any(ch == "#" and (i == 0 or line_text[i - 1].isspace()) for i, ch in enumerate(line_text[:col]))


def _spot(ctx: Context, file: str, line: int, col: int) -> Spot | None:
    text = ctx.ws.text_of(file)
    if text is None:
        return None
    found = word_at(text, line, col)
    if found is None:
        return None
    word, span = found
    index = ctx.ws.index_of(file)
    hit = index.at(line, col) if index is not None and index.error is None else None
    if hit is not None:
        entry, on_key = hit
        path = entry.path
    else:  # half-typed text: the path from the lines above
        if _in_comment(text.split("\n")[line], span.col):
            return None
        cur = cursor_at(text, line, span.col)
        on_key = cur.role == "key"
        path = cur.path + (word,) if on_key else cur.path
    mission, ypath = _expanded(ctx, file, path)
    return Spot(path, on_key, word, span, mission, ypath)


def _expanded(ctx: Context, file: str, path: YPath) -> tuple[Analysis | None, YPath]:
    """The compiled mission that covers ``file`` and ``path`` in its expanded document: the file's own, or an
    open mission's into which the file is spliced as a sub-mission."""
    a = ctx.ws.context(file)
    if a is not None and a.mission is not None:
        return a, path
    for m in ctx.ws.missions_using(file):
        assert m.smap is not None
        for g in m.smap.grafts.values():
            if same_file(g.smap.file, file) and path[:len(g.base)] == g.base:
                return m, g.prefix + path[len(g.base):]
    return None, path


# -- where things are written ----------------------------------------------------------------------------------

def written_at(smap: SourceMap, ypath: YPath) -> tuple[str, YPath]:
    """The file a path of the expanded document is written in and its path in that file (through the grafts
    of used sub-missions, innermost last)."""
    p = tuple(ypath)
    while True:
        graft = next((g for k in range(len(p), -1, -1) if (g := smap.grafts.get(p[:k])) is not None), None)
        if graft is None:
            return smap.file, p
        smap, p = graft.smap, graft.base + p[len(graft.prefix):]


def _entry(ctx: Context, a: Analysis, ypath: YPath) -> tuple[str, Entry] | None:
    assert a.smap is not None
    file, local = written_at(a.smap, ypath)
    index = ctx.ws.index_of(file)
    entry = index.get(local) if index is not None else None
    if entry is None and same_file(file, a.file):
        entry = a.index.get(local)  # the buffer does not parse now: the text that compiled
        file = a.file
    elif entry is None and index is not None and index.error is not None:
        # a used sub-mission's buffer that does not parse now: the text of its latest analysis that checked
        good = next((g for f, g in ctx.ws.good.items() if same_file(f, file)), None)
        if good is not None:
            entry, file = good.index.get(local), good.file
    return (file, entry) if entry is not None else None


def _key_span(ctx: Context, a: Analysis, ypath: YPath) -> tuple[str, Span] | None:
    """Where the key of ``ypath`` is written (its value, for a list item)."""
    found = _entry(ctx, a, ypath)
    if found is None:
        return None
    file, entry = found
    return file, entry.key or entry.value


def _value_text(ctx: Context, file: str, span: Span) -> tuple[str, int]:
    """The text of a one-line scalar at ``span`` without its quotes, and the column it starts at."""
    text = ctx.ws.text_of(file) or ""
    lines = text.split("\n")
    raw = lines[span.line][span.col:span.end_col] if span.line < len(lines) and span.end_line == span.line else ""
    if len(raw) >= 2 and raw[0] == raw[-1] and raw[0] in "\"'":
        return raw[1:-1], span.col + 1
    return raw, span.col


def _raw_at(data: Any, ypath: YPath) -> Any:
    for k in ypath:
        found = (isinstance(data, dict) and k in data
                 or isinstance(data, list) and isinstance(k, int) and 0 <= k < len(data))
        if found:
            data = data[k]
        else:
            return None
    return data


def _states_by_ypath(m: CompiledMission) -> dict[YPath, StateNode]:
    return {n.ypath: n for n in m.root.walk()}


def _spec_transition(n: StateNode, m: CompiledMission, i: int) -> Any:
    """The compiled transition written at index ``i`` of ``n``'s ``transitions`` (None when some of them did not
    compile, so the indices do not line up)."""
    written = _raw_at(m.raw, n.ypath + ("transitions",))
    if isinstance(written, list) and len(written) == len(n.transitions) and 0 <= i < len(n.transitions):
        return n.transitions[i]
    return None


def _transition_index(t: Any) -> int | None:
    """The index in its source's ``transitions:`` where a compiled transition is written."""
    try:
        return int(t.source.transitions.index(t))
    except ValueError:
        return None


# -- states -----------------------------------------------------------------------------------------------------

def _named_chain(target: StateNode, written: str) -> list[StateNode] | None:
    """The states a dotted name written for ``target`` names, one per component (the target last); None when
    the name is not the tail of the target's path (the buffer names another state than the compiled mission)."""
    parts = written.split(".")
    chain = target.ancestors()[-len(parts):]
    if len(chain) != len(parts) or [n.name for n in chain] != parts:
        return None
    return chain


def _state_atoms(node: Node) -> Iterator[Atom]:
    """Every ``state(PATH)`` of a property's expression tree."""
    if node.atom is not None and node.atom.kind == "state":
        yield node.atom
    for child in node.children:
        yield from _state_atoms(child)


def _state_of(spot: Spot, col: int) -> StateNode | None:
    """The state the name under the cursor names: a state's key, a component of a transition target or of a
    property's ``state(PATH)`` (the state or one of its ancestors), or an ``initial:``."""
    if spot.mission is None or spot.mission.mission is None:
        return None
    m = spot.mission.mission
    by_ypath = _states_by_ypath(m)
    yp = spot.ypath
    if spot.on_key and len(yp) >= 2 and yp[-2] in _STATE_CONTAINERS:
        return by_ypath.get(yp)
    if spot.on_key:
        return None
    target: StateNode | None = None
    if len(yp) >= 4 and yp[-1] == "to" and yp[-3] == "transitions" and isinstance(yp[-2], int):
        source = by_ypath.get(yp[:-3])
        if source is None:
            return None
        t = _spec_transition(source, m, yp[-2])
        target = t.target if t is not None else next(
            (t.target for t in source.transitions if ("." + t.target.path).endswith("." + spot.word)), None)
    elif len(yp) == 3 and yp[0] == "properties":
        prop = next((p for p in m.properties if p.ypath == yp[:2]), None)
        path = prop.states.get(spot.word) if prop is not None else None
        target = m.states.get(path) if path is not None else None
    elif yp and yp[-1] == "initial":
        owner = by_ypath.get(yp[:-1])
        return owner.children.get(spot.word) if owner is not None else None
    chain = _named_chain(target, spot.word) if target is not None else None
    if chain is None:
        return None
    k, _, _ = spot.component(col)
    return chain[k]


def _component_span(ctx: Context, file: str, value: Span, written: str, offset: int,
                    target: StateNode, state: StateNode) -> Span | None:
    """The span of the component naming ``state`` in the dotted name ``written`` for ``target``, found at or
    after character ``offset`` of the scalar at ``value``."""
    chain = _named_chain(target, written)
    if chain is None or state not in chain:
        return None
    text, start = _value_text(ctx, file, value)
    at = text.find(written, offset)
    if at < 0:
        return None
    k = chain.index(state)
    col = start + at + sum(len(n.name) + 1 for n in chain[:k])
    return Span(value.line, col, value.line, col + len(state.name))


def _state_references(ctx: Context, a: Analysis, state: StateNode) -> list[tuple[str, Span]]:
    """Every place a name of ``state`` is written: the component of each transition target and of each
    property's ``state(PATH)`` that names it (the state itself or, in a dotted path, an ancestor of the named
    state) and each ``initial:`` naming it."""
    assert a.mission is not None
    out: list[tuple[str, Span]] = []
    for t in a.mission.transitions:
        i = _transition_index(t)
        if state not in t.target.ancestors() or i is None:
            continue
        found = _entry(ctx, a, t.source.ypath + ("transitions", i, "to"))
        if found is not None:
            written, _ = _value_text(ctx, found[0], found[1].value)
            span = _component_span(ctx, found[0], found[1].value, written, 0, t.target, state)
            if span is not None:
                out.append((found[0], span))
    for prop in a.mission.properties:
        for fname, guard in prop.exprs.items():
            found = _entry(ctx, a, prop.ypath + (fname,))
            for atom in _state_atoms(guard.tree) if found is not None else ():
                named = a.mission.states.get(prop.states.get(atom.name, ""))
                span = _component_span(ctx, found[0], found[1].value, atom.name, atom.offset, named, state) \
                    if found is not None and named is not None else None
                if found is not None and span is not None:
                    out.append((found[0], span))
    parent = state.parent
    if parent is not None and parent.initial == state.name:
        found = _entry(ctx, a, parent.ypath + ("initial",))
        if found is not None:
            file, entry = found
            text, start = _value_text(ctx, file, entry.value)
            if text == state.name:
                out.append((file, Span(entry.value.line, start, entry.value.line, start + len(text))))
    return out


# -- profiles, parameters, data, tasks, files ---------------------------------------------------------------

def _profile_definitions(ctx: Context, file: str, spot: Spot) -> list[tuple[str, Span]]:
    out: list[tuple[str, Span]] = []
    a = spot.mission
    if a is not None and a.mission is not None:
        for kind, named in (a.mission.raw.get("profiles") or {}).items():
            if isinstance(named, dict) and spot.word in named:
                found = _key_span(ctx, a, ("profiles", kind, spot.word))
                if found is not None:
                    out.append(found)
        return out
    index = ctx.ws.index_of(file)
    if index is not None:  # no mission covers the file: its own `profiles:`
        out = [(file, e.key) for e in index.entries.values()
               if len(e.path) == 3 and e.path[0] == "profiles" and e.path[2] == spot.word and e.key is not None]
    return out


def _profile_references(ctx: Context, a: Analysis, name: str) -> list[tuple[str, Span]]:
    """Every ``bind:`` entry that names profile ``name`` (where it is written, not where it is inherited)."""
    assert a.mission is not None
    out: list[tuple[str, Span]] = []
    for n in a.mission.states.values():
        for slot, (_kind, ref, where) in n.bind.items():
            if ref == name and where == n.ypath + ("bind", slot):
                found = _entry(ctx, a, where)
                if found is not None:
                    out.append((found[0], found[1].value))
    return out


def _parameter_definitions(ctx: Context, file: str, spot: Spot) -> list[tuple[str, Span]]:
    """``$name``: the enclosing foreach's ``as:``, else the ``parameters:`` entry of the document it is written in
    (a sub-mission's, with the ``with:`` of the state that uses it), else the mission's."""
    name = spot.word[1:]
    a = spot.mission
    if a is None or a.mission is None or a.smap is None:
        index = ctx.ws.index_of(file)
        entry = index.get(("parameters", name)) if index is not None else None
        return [(file, entry.key)] if entry is not None and entry.key is not None else []
    by_ypath = _states_by_ypath(a.mission)
    yp = spot.ypath
    owner = next((by_ypath[yp[:k]] for k in range(len(yp), 0, -1) if yp[:k] in by_ypath), None)
    if owner is not None:
        for n in reversed(owner.ancestors()):
            if n.loop is not None and n.loop.item == name:
                found = _entry(ctx, a, n.ypath + ("foreach", "as"))
                return [(found[0], found[1].value)] if found is not None else []
    out: list[tuple[str, Span]] = []
    here, _ = written_at(a.smap, yp)
    if not same_file(here, a.file):  # inside a used sub-mission: its parameter and the `with:` binding it
        index = ctx.ws.index_of(here)
        entry = index.get(("parameters", name)) if index is not None else None
        if entry is not None and entry.key is not None:
            out.append((here, entry.key))
        graft = next((g for k in range(len(yp), -1, -1) if (g := a.smap.grafts.get(yp[:k])) is not None), None)
        if graft is not None:
            binding = _key_span(ctx, a, graft.prefix[:-1] + ("with", name))
            if binding is not None:
                out.append(binding)
        return out
    declared = _key_span(ctx, a, ("parameters", name))
    return [declared] if declared is not None else []


def _data_definitions(ctx: Context, spot: Spot, name: str) -> list[types.Location]:
    """``data.KEY``: the mission's ``data:`` entry for it, and the class of each task that declares it."""
    a = spot.mission
    if a is None or a.mission is None:
        return []
    key = re.sub(r"\[\d+\]$", "", name)
    out: list[types.Location] = []
    found = _key_span(ctx, a, ("data", key)) if isinstance(a.mission.raw.get("data"), dict) and \
        key in a.mission.raw["data"] else None
    if found is not None:
        out.append(ctx.location(*found))
    classes = {n.task_cls for n in a.mission.states.values() if n.task_cls is not None
               and any(k.name == key for k in (*n.task_cls.writes, *n.task_cls.reads))}
    for cls in sorted(classes, key=lambda c: c.__name__):
        loc = class_location(ctx, cls)
        if loc is not None:
            out.append(loc)
    return out


def class_location(ctx: Context, cls: type) -> types.Location | None:
    """Where a Python class is defined (its source file and the line of its ``class``, after its decorators)."""
    try:
        src = inspect.getsourcefile(cls)
        lines, first = inspect.getsourcelines(cls)
    except (OSError, TypeError):
        return None
    if src is None:
        return None
    past_decorators = next((i for i, ln in enumerate(lines) if ln.lstrip().startswith("class ")), 0)
    line = max(first - 1, 0) + past_decorators
    return types.Location(uri=ctx.uri_of(src), range=types.Range(
        start=types.Position(line=line, character=0), end=types.Position(line=line, character=0)))


def _task_definition(ctx: Context, name: str) -> list[types.Location]:
    from taskflow.registry import TASKS

    try:
        cls = TASKS.get(name)
    except Exception:
        return []
    loc = class_location(ctx, cls)
    return [loc] if loc is not None else []


def _use_definition(ctx: Context, file: str, spot: Spot) -> list[types.Location]:
    """``use: FILE``: the sub-mission file (the one the loader spliced in, else the path next to the mission)."""
    target: str | None = None
    a = spot.mission
    if a is not None and a.smap is not None:
        graft = a.smap.grafts.get(spot.ypath[:-1] + ("states",))
        target = graft.smap.file if graft is not None else None
    if target is None:
        target = str(use_path(spot.word, Path(file).resolve()))
    if not Path(target).is_file():
        return []
    return [ctx.location(target, Span(0, 0, 0, 0))]


# -- the features ---------------------------------------------------------------------------------------------

def definition(ctx: Context, file: str, line: int, col: int) -> list[types.Location] | None:
    """Where the name under the cursor is defined: a profile, a state, a sub-mission file, a ``$parameter``, a
    ``data.`` key or a task's Python class."""
    spot = _spot(ctx, file, line, col)
    if spot is None:
        return None
    keys = [k for k in spot.path if isinstance(k, str)]
    if spot.on_key:
        return None
    if len(spot.path) >= 2 and spot.path[-2] == "bind":
        return [ctx.location(*d) for d in _profile_definitions(ctx, file, spot)] or None
    if keys and keys[-1] == "use":
        return _use_definition(ctx, file, spot) or None
    if keys and (keys[-1] == "task" or keys[-2:] == ["task", "name"]):
        return _task_definition(ctx, spot.word) or None
    if spot.word.startswith("$" + DATA_PREFIX):
        return _data_definitions(ctx, spot, spot.word[1 + len(DATA_PREFIX):]) or None
    if spot.word.startswith("$"):
        return [ctx.location(*d) for d in _parameter_definitions(ctx, file, spot)] or None
    if spot.word.startswith(DATA_PREFIX) and keys and keys[-1] in ("when", "never", "while", "always"):
        return _data_definitions(ctx, spot, spot.word[len(DATA_PREFIX):]) or None
    state = _state_of(spot, col)
    if state is not None and spot.mission is not None:
        found = _key_span(ctx, spot.mission, state.ypath)
        return [ctx.location(*found)] if found is not None else None
    return None


def references(ctx: Context, file: str, line: int, col: int,
               include_declaration: bool) -> list[types.Location] | None:
    """Every place that names the state or the profile under the cursor (and its definition, if asked)."""
    spot = _spot(ctx, file, line, col)
    if spot is None or spot.mission is None or spot.mission.mission is None:
        return None
    a = spot.mission
    if not spot.on_key and len(spot.path) >= 2 and spot.path[-2] == "bind":
        found = _profile_references(ctx, a, spot.word)
        if include_declaration:
            found = _profile_definitions(ctx, file, spot) + found
        return [ctx.location(*f) for f in found]
    if spot.on_key and len(spot.ypath) == 3 and spot.ypath[0] == "profiles":
        found = _profile_references(ctx, a, spot.word)
        if include_declaration:
            found = _profile_definitions(ctx, file, spot) + found
        return [ctx.location(*f) for f in found]
    state = _state_of(spot, col)
    if state is None:
        return None
    found = _state_references(ctx, a, state)
    if include_declaration:
        decl = _key_span(ctx, a, state.ypath)
        found = ([decl] if decl is not None else []) + found
    return [ctx.location(*f) for f in found]


def _valid_state_name(name: str) -> bool:
    """The loader's rule for a state's name (:mod:`taskflow.mission.compile.tree`): letters, digits, '_', '-'."""
    return bool(name) and "." not in name and name.replace("_", "a").replace("-", "a").isalnum()


def prepare_rename(ctx: Context, file: str, line: int, col: int) -> types.Range | None:
    """The range of the state name under the cursor, when it names a state (else None: nothing to rename)."""
    spot = _spot(ctx, file, line, col)
    if spot is None or _state_of(spot, col) is None:
        return None
    _, _, span = spot.component(col)
    return ctx.range(file, span)


def rename(ctx: Context, file: str, line: int, col: int, new_name: str) -> types.WorkspaceEdit | None:
    """Rename the state under the cursor: its key, every transition target component and ``initial:`` naming it,
    in the mission and — when the state is defined there — in the sub-mission.  None when ``new_name`` is not a
    valid state name or a sibling already has it."""
    spot = _spot(ctx, file, line, col)
    if spot is None or spot.mission is None or not _valid_state_name(new_name):
        return None
    state = _state_of(spot, col)
    if state is None or state.parent is None:
        return None
    if new_name != state.name and new_name in state.parent.children:
        return None
    a = spot.mission
    decl = _key_span(ctx, a, state.ypath)
    if decl is None:
        return None
    editable = {str(Path(decl[0]).resolve()), str(Path(a.file).resolve())}
    changes: dict[str, list[types.TextEdit]] = {}
    for where, span in [decl, *_state_references(ctx, a, state)]:
        if str(Path(where).resolve()) not in editable:
            continue
        edits = changes.setdefault(ctx.uri_of(where), [])
        edit = types.TextEdit(range=ctx.range(where, span), new_text=new_name)
        if edit not in edits:
            edits.append(edit)
    return types.WorkspaceEdit(changes=changes)


# -- the outline ------------------------------------------------------------------------------------------------

_KINDS = {"composite": types.SymbolKind.Module, "parallel": types.SymbolKind.Struct,
          "region": types.SymbolKind.Namespace, "leaf": types.SymbolKind.Function, "final": types.SymbolKind.Event}
"""The symbol kind of each role a state plays."""


def children_map(index: DocumentIndex) -> dict[YPath, list[Entry]]:
    """The entries of the document by the path of the collection holding them, in document order."""
    out: dict[YPath, list[Entry]] = {}
    for e in index.entries.values():
        if e.path:
            out.setdefault(e.path[:-1], []).append(e)
    return out


def _whole(entry: Entry) -> Span:
    key = entry.key or entry.value
    return Span(key.line, key.col, entry.value.end_line, entry.value.end_col)


def _outline(ctx: Context, file: str, index: DocumentIndex, container: YPath, role: str, shown_in: str,
             at: tuple[Span, Span] | None, depth: int) -> list[types.DocumentSymbol]:
    """The states under ``container`` (a ``states:`` or ``regions:`` mapping of ``file``) as symbols of the
    document ``shown_in``; ``at``: the (range, selection) every symbol takes there (a sub-mission's states shown
    at the state that uses it)."""
    kids = children_map(index)
    out: list[types.DocumentSymbol] = []
    for e in kids.get(container, []):
        if not isinstance(e.path[-1], str) or e.key is None:
            continue
        keys = {c.path[-1]: c for c in kids.get(e.path, [])}
        children: list[types.DocumentSymbol] = []
        rng, sel = at if at is not None else (_whole(e), e.key)
        if role == "region":
            kind, detail = "region", "region"
        elif "final" in keys:
            kind, detail = "final", f"final: {keys['final'].text}"
        elif "regions" in keys:
            kind, detail = "parallel", "parallel"
        elif "states" in keys or "use" in keys:
            kind, detail = "composite", "composite"
        else:
            kind, detail = "leaf", "leaf"
        if "regions" in keys:
            children = _outline(ctx, file, index, e.path + ("regions",), "region", shown_in, at, depth)
        elif "states" in keys:
            children = _outline(ctx, file, index, e.path + ("states",), "state", shown_in, at, depth)
        elif "use" in keys and keys["use"].text and depth < _MAX_USE_DEPTH:
            used = str(use_path(keys["use"].text, Path(file).resolve()))
            used_index = ctx.ws.index_of(used)
            detail = f"use: {keys['use'].text}"
            if used_index is not None:
                children = _outline(ctx, used, used_index, ("machine", "states"), "state", shown_in,
                                    at or (rng, sel), depth + 1)
        out.append(types.DocumentSymbol(name=str(e.path[-1]), detail=detail, kind=_KINDS[kind],
                                        range=ctx.range(shown_in, rng), selection_range=ctx.range(shown_in, sel),
                                        children=children))
    return out


def symbols(ctx: Context, file: str) -> list[types.DocumentSymbol] | None:
    """The state tree of the machine as nested symbols (composite, parallel, region, leaf, final); a state that
    uses a sub-mission holds that file's states, placed at the using state."""
    index = ctx.ws.index_of(file)
    if index is None or index.error is not None:  # half-typed: the text that last compiled
        a = ctx.ws.context(file)
        index = a.index if a is not None else None
    if index is None or index.get(("machine", "states")) is None:
        return None
    return _outline(ctx, file, index, ("machine", "states"), "state", file, None, 0)
