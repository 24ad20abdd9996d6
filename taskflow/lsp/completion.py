"""Completion in a mission or sub-mission file: what may be typed at the cursor (:func:`cursor_at`, which reads
half-typed text), from the schema's keys, the registries and the latest compiled mission
(:class:`~taskflow.lsp.knowledge.Knowledge`).  Every item replaces the whole word at the cursor."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from lsprotocol import types
from pydantic import BaseModel

from taskflow.catalogue.declarations import type_label
from taskflow.lsp.document import Cursor, cursor_at
from taskflow.lsp.knowledge import Knowledge, param_detail, params_table, submission_parameters
from taskflow.mission import schema
from taskflow.mission.submission import use_path
from taskflow.mission.submission_file import Submission
from taskflow.registry import ROBOTS, TASKS, WORLDS
from taskflow.units import _UNITS_OF, UNITS

Item = tuple[str, str, str, types.CompletionItemKind]
"""(label, detail, documentation, kind) of one completion."""

GUARD_KEYS = ("when", "never", "while", "always", "after", "then", "only_after", "occurs")
"""Keys whose value is a guard expression (``after`` only under ``properties:``)."""
_COMPARISON = re.compile(r"([A-Za-z_][A-Za-z0-9_.]*)\s*(?:<=|>=|==|!=|<|>)\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*$")
_KEYWORD = types.CompletionItemKind.Keyword
_FIELD = types.CompletionItemKind.Field


def _keys_of(model: type[BaseModel]) -> list[Item]:
    """The keys a pydantic schema model takes (aliases as written in YAML), with their descriptions."""
    out = []
    for name, f in model.model_fields.items():
        label = f.alias or name
        out.append((label, type_label(f.annotation), f.description or "", _FIELD))
    return out


def _names(registry: Any, what: str) -> list[Item]:
    """The registered names of a registry, with each class's summary (the class is not imported)."""
    return [(n, what, "", types.CompletionItemKind.Class) for n in registry.names()]


def _params(model: type | None) -> list[Item]:
    return [(p.name, param_detail(p), p.description, types.CompletionItemKind.Property) for p in params_table(model)]


def _class(registry: Any, name: str | None) -> Any:
    try:
        return registry.get(name) if name else None
    except Exception:
        return None


def _written(k: Knowledge, path: tuple[Any, ...]) -> str | None:
    """The scalar written at ``path`` of the text as it is now (else of its latest analysis; None when not
    there)."""
    for index in (k.written, k.analysis.index if k.analysis is not None else None):
        entry = index.get(path) if index is not None else None
        if entry is not None:
            return entry.text
    return None


def _task_name(k: Knowledge, cur: Cursor, text: str) -> str | None:
    """The task named in the state holding the cursor (as typed, else the compiled state's effective task)."""
    keys = cur.keys()
    if "task" in keys:
        at = keys.index("task")
        m = re.search(r"task:\s*\{?\s*(?:name:\s*)?([A-Za-z0-9_]+)", text.split("\n")[cur.span.line])
        if m:
            return m.group(1)
        task_path = cur.path[:cur.path.index("task") + 1]
        written = _written(k, task_path + ("name",)) or _written(k, task_path)  # block `name:` or `task: NAME`
        if written:
            return written
        node = k.state_at(keys[:at])
    else:
        node = k.state_at(keys)
    return node.task_cls.name if node is not None and node.task_cls is not None else None


def _written_metrics(k: Knowledge, cur: Cursor) -> dict[str, tuple[str, str]]:
    """Metric → (unit, publisher) of the task and world written in the text, for a mission that has not
    compiled yet (a new file): the state's ``task`` (block ``name:``, flow or bare name) and ``world``."""
    out: dict[str, tuple[str, str]] = {}
    state = cur.path[:cur.path.index("transitions")] if "transitions" in cur.path else None
    task = state is not None and (_written(k, state + ("task", "name")) or _written(k, state + ("task",)))
    for registry, name, what in ((TASKS, task, "task"),
                                 (WORLDS, _written(k, ("world", "name")) or _written(k, ("world",)), "world")):
        cls = _class(registry, name or None)
        for metric, unit in (getattr(cls, "metrics", None) or {}).items():
            out.setdefault(metric, (str(unit), f"{what} {name}"))
    return out


def _guard_items(k: Knowledge, cur: Cursor) -> list[Item]:
    """Inside a guard: units after ``METRIC OP NUMBER``, else metrics of the state, ``$parameters``, ``data.`` keys."""
    before = cur.value[:len(cur.value) - len(cur.prefix)] if cur.prefix else cur.value
    metrics = k.metrics_in(k.state_at(cur.path) if "transitions" in cur.path else None) or _written_metrics(k, cur)
    m = _COMPARISON.search(before)
    if m:
        unit = metrics.get(m.group(1), ("", ""))[0]
        if m.group(1).startswith("data.") and k.mission is not None:
            unit = k.mission.data.guard_units().get(m.group(1)[5:], "")
        dim = UNITS[unit][0] if unit in UNITS else None
        units = _UNITS_OF.get(dim, {}) if dim else {u: f for d in _UNITS_OF.values() for u, f in d.items()}
        return [(u, f"{dim or 'unit'}: × {f:g} → {unit or 'base'}", "", types.CompletionItemKind.Unit)
                for u, f in units.items() if u]
    items: list[Item] = [(name, unit or "dimensionless", f"published by {who}" if who else "",
                          types.CompletionItemKind.Variable) for name, (unit, who) in metrics.items()]
    items += _dollar(k)
    if k.mission is not None:
        items += [(f"data.{n}", u or "dimensionless", "mission data", types.CompletionItemKind.Variable)
                  for n, u in k.mission.data.guard_units().items()]
    return items


def _dollar(k: Knowledge) -> list[Item]:
    """``$parameters`` of the mission (and sub-mission) with their values, and foreach items."""
    return [(f"${n}", "parameter", repr(v), types.CompletionItemKind.Variable) for n, v in k.parameters().items()]


def _use_files(file: str) -> list[Item]:
    """Sub-mission files (``submission:`` at the top) under the mission's folder, relative to it."""
    base = Path(file).parent
    out = []
    for p in sorted(base.rglob("*.yaml"))[:500]:
        try:
            head = p.read_text(encoding="utf-8")[:4000]
        except (OSError, UnicodeDecodeError):
            continue
        if re.search(r"^submission:", head, re.M) and p.resolve() != Path(file).resolve():
            out.append((p.relative_to(base).as_posix(), "sub-mission", "", types.CompletionItemKind.File))
    return out


def _key_items(k: Knowledge, cur: Cursor, text: str) -> list[Item]:
    path, keys = cur.path, cur.keys()
    if not keys:
        kind = k.analysis.kind if k.analysis is not None else "mission"
        if kind == "submission" or re.search(r"^submission:", text, re.M):
            return _keys_of(Submission)
        return _keys_of(schema.Mission)
    if keys == ("machine",):
        return _keys_of(schema.Machine)
    if path and isinstance(path[-1], int) and keys[-1] == "transitions":
        return _keys_of(schema.Transition)
    if len(keys) >= 2 and keys[-2] == "regions":
        return _keys_of(schema.Region)
    if len(keys) >= 2 and keys[-2] == "states":
        return _keys_of(schema.State)
    if keys[-1] == "foreach":
        return _keys_of(schema.Foreach)
    if keys[-2:] == ("foreach", "retry"):
        return _keys_of(schema.Retry)
    if len(keys) >= 2 and keys[-2] == "properties" and keys[0] == "properties":
        return _keys_of(schema.Property)
    if keys[-1] == "params" and len(keys) >= 2:
        if keys[-2] == "task":
            return _params(getattr(_class(TASKS, _task_name(k, cur, text)), "Params", None))
        if keys == ("world", "params"):
            world = _class(WORLDS, _written(k, ("world", "name"))) or (k.mission and k.mission.world_cls)
            return _params(getattr(world, "Params", None))
        if keys == ("robot", "params"):
            robot = _class(ROBOTS, _written(k, ("robot", "name"))) or (k.mission and k.mission.robot_cls)
            return _params(getattr(robot, "Params", None))
        if keys[-2] == "action" and k.mission is not None:
            line = text.split("\n")[cur.span.line]
            m = re.search(r"name:\s*([A-Za-z0-9_]+)", line)
            return _params(k.mission.world_cls.action_params.get(m.group(1)) if m else None)
    if keys[-1] in ("task", "world", "robot", "action"):
        return [("name", "registered name", "", _FIELD), ("params", "parameters", "", _FIELD)]
    if keys[-1] == "bind":
        node = k.state_at(path)
        return [(slot, f"profiles.{k.kind_of_slot(node, slot)} ({model.__name__})", "", _FIELD)
                for slot, model in k.slots_of(node).items()]
    if keys[0] == "profiles" and len(keys) == 3:
        return _params(k.model_of_kind(keys[1]))
    if keys[-1] == "with":
        use = _written(k, tuple(path[:-1]) + ("use",))
        if use is None:
            m = re.search(r"use:\s*(\S+)", text)
            use = m.group(1) if m else None
        params = submission_parameters(str(use_path(use, k.analysis.file if k.analysis else ""))) if use else {}
        return [(n, "required" if v is None else f"default {v!r}", "", types.CompletionItemKind.Property)
                for n, v in params.items()]
    return []


def _value_items(k: Knowledge, cur: Cursor, file: str, text: str) -> list[Item]:
    path, keys = cur.path, cur.keys()
    key = keys[-1] if keys else None
    if cur.prefix.startswith("$"):
        return _dollar(k)
    if keys in (("robot",), ("robot", "name")):
        return _names(ROBOTS, "robot")
    if keys in (("world",), ("world", "name")):
        return _names(WORLDS, "world")
    if keys[-1:] == ("task",) or keys[-2:] == ("task", "name"):
        return _names(TASKS, "task")
    if keys[-2:] == ("action", "name") and k.mission is not None:
        return [(a, "action", f"ends with {', '.join(ends)}", types.CompletionItemKind.Function)
                for a, ends in k.mission.world_cls.actions.items()]
    if keys[-2:] == ("params", "fidelity") and keys[0] == "world":
        world = _class(WORLDS, _written(k, ("world", "name"))) or (k.mission and k.mission.world_cls)
        names = getattr(getattr(world, "Params", None), "fidelity_names", None)
        levels = getattr(getattr(world, "Params", None), "FIDELITY", {})
        return [(n, "fidelity level", ", ".join(f"{p} = {s.value!r} ({s.source})" for p, s in levels.get(n, {}).items())
                 or "the parameters' defaults", types.CompletionItemKind.EnumMember) for n in (names() if names else ())]
    if len(keys) >= 2 and keys[-2] == "bind":
        kind = k.kind_of_slot(k.state_at(path), keys[-1])
        return [(n, f"profiles.{kind}", ", ".join(f"{f}: {v}" for f, v in fields.items()) if isinstance(fields, dict)
                 else "", types.CompletionItemKind.Value) for n, fields in k.profiles_of_kind(kind).items()]
    if key == "to" and "transitions" in keys:
        node = k.state_at(path)
        items = [(t, what, "", types.CompletionItemKind.Reference) for t, what in k.targets_from(node).items()]
        data = k.analysis.data if k.analysis is not None else None
        exits = data.get("exits") if isinstance(data, dict) else None
        items += [(e, "exit (a state of the using mission)", "", types.CompletionItemKind.Reference)
                  for e in (exits if isinstance(exits, list) else []) if isinstance(e, str)]
        return items
    if key == "on" and "transitions" in keys:
        return [(e, "event", "", types.CompletionItemKind.Event) for e in sorted(k.mission.events)] if k.mission else []
    if key in GUARD_KEYS and ("transitions" in keys or keys[:1] == ("properties",)) and not (
            key == "after" and "transitions" in keys):
        return _guard_items(k, cur)
    if key == "use":
        return _use_files(file)
    if key == "initial":
        node = k.state_at(path[:-1])
        children = node.children if node is not None and tuple(node.ypath) == k.expanded(path[:-1]) else (
            k.mission.root.children if k.mission is not None and keys[:-1] == ("machine",) else {})
        return [(n, "child state", "", types.CompletionItemKind.Reference) for n in children]
    return []


def _keys_written(k: Knowledge, cur: Cursor) -> set[str]:
    """The keys already written in the mapping the cursor types a key of (a key is not offered twice); the one
    being typed stays (its own entry, where the cursor's word is)."""
    if k.written is None:
        return set()
    n = len(cur.path)
    return {p[n] for p, e in k.written.entries.items()
            if len(p) == n + 1 and p[:n] == cur.path and isinstance(p[n], str)
            and not (e.key is not None and (e.key.line, e.key.col) == (cur.span.line, cur.span.col))}


def complete(ctx: Any, file: str, line: int, col: int) -> types.CompletionList | None:
    """What may be typed at (``line``, ``col``) of ``file``, each item replacing the word at the cursor."""
    text = ctx.ws.text_of(file)
    if text is None:
        return None
    cur = cursor_at(text, line, col)
    k = Knowledge.of(ctx.ws, file)
    items = _key_items(k, cur, text) if cur.role == "key" else _value_items(k, cur, file, text)
    if not items:
        return None
    rng = ctx.range(file, cur.span)
    seen = _keys_written(k, cur) if cur.role == "key" else set()
    out = []
    for label, detail, doc, kind in items:
        if label in seen:
            continue
        seen.add(label)
        insert = f"{label}: " if cur.role == "key" else label
        out.append(types.CompletionItem(
            label=label, kind=kind, detail=detail or None,
            documentation=types.MarkupContent(types.MarkupKind.Markdown, doc) if doc else None,
            text_edit=types.TextEdit(rng, insert), filter_text=label))
    return types.CompletionList(is_incomplete=False, items=out)
