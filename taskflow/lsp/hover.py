"""Hover in a mission or sub-mission file: the catalogue's text for the name under the cursor (a task, robot or
world with its parameters and fidelity sources, a parameter), a metric with its unit and publisher, a profile's
values after its model's defaults, a state's effective task and bindings, and a guard's threshold in base
units (``2 cm`` → 0.02 m)."""

from __future__ import annotations

import re
from typing import Any

from lsprotocol import types

from taskflow.catalogue.catalogue import UnknownEntry
from taskflow.catalogue.catalogue_render import describe_markdown
from taskflow.lsp.completion import GUARD_KEYS
from taskflow.lsp.document import Span
from taskflow.lsp.knowledge import Knowledge, catalogue, param_detail, params_table
from taskflow.mission.submission import PARAM_REF
from taskflow.units import BASE_UNIT_OF, UNITS

_QUANTITY = re.compile(r"(?<![A-Za-z0-9_.])([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z%/]+)")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")


def _entry_markdown(name: str, kind: Any) -> str | None:
    """The catalogue's page of a registered name."""
    try:
        return describe_markdown(catalogue().find(name, kind), anchored=False)
    except UnknownEntry:
        return None


def _parameter_markdown(k: Knowledge, line: str, col: int) -> str | None:
    """A ``$parameter`` under ``col``: its value (or what a foreach item iterates)."""
    for m in PARAM_REF.finditer(line):
        if m.start() <= col <= m.end():
            params = k.parameters()
            if m.group(1) not in params:
                return None
            return f"**parameter `${m.group(1)}`** = `{params[m.group(1)]!r}`"
    return None


def _threshold(line: str, col: int) -> tuple[str, Span] | None:
    """A quantity with a unit under ``col`` of ``line``, in its dimension's base unit."""
    for m in _QUANTITY.finditer(line):
        if m.start() <= col <= m.end() and m.group(2) in UNITS:
            dim, factor = UNITS[m.group(2)]
            base = BASE_UNIT_OF[dim]
            value = float(m.group(1)) * factor
            return f"`{m.group(0)}` = **{value:g} {base}** ({dim.replace('_', ' ')})", Span(0, m.start(), 0, m.end())
    return None


def _word(line: str, col: int) -> tuple[str, int, int] | None:
    for m in _NAME.finditer(line):
        if m.start() <= col <= m.end():
            return m.group(0), m.start(), m.end()
    return None


def _state_markdown(k: Knowledge, path: tuple[Any, ...]) -> str | None:
    node = k.state_at(path)
    if node is None:
        return None
    lines = [f"**state `{node.path}`**"]
    if node.task_cls is not None:
        lines.append(f"task: `{node.task_cls.name}`" + (f" with {node.task_params}" if node.task_params else ""))
    for slot, (_, bound, _) in node.bind.items():
        lines.append(f"- bind `{slot}` → {bound if isinstance(bound, str) else 'inline ' + repr(bound)}")
    if node.children:
        lines.append("children: " + ", ".join(f"`{c}`" for c in node.children))
    if node.final:
        lines.append(f"final: {node.final}")
    return "\n\n".join(lines)


def _markdown(k: Knowledge, path: tuple[Any, ...], on_key: bool, text: str | None, line: str, col: int) -> str | None:
    keys = tuple(p for p in path if isinstance(p, str))
    if not keys:
        return None
    if not on_key and "$" in line:
        param = _parameter_markdown(k, line, col)
        if param is not None:
            return param
    if not on_key and keys[-1] == "on" and "transitions" in keys and text:
        sources = k.event_sources(text)
        if sources:
            return f"**event `{text}`**, raised by " + "; ".join(sources)
    if not on_key and (keys in (("robot",), ("robot", "name"))):
        return _entry_markdown(text or "", "robot")
    if not on_key and (keys in (("world",), ("world", "name"))):
        return _entry_markdown(text or "", "world")
    if not on_key and (keys[-1] == "task" or keys[-2:] == ("task", "name")):
        return _entry_markdown(text or "", "task")
    if on_key and len(keys) >= 2 and keys[-2] == "params" and len(keys) >= 3:
        owner = keys[-3]
        model = None
        if owner == "task":
            node = k.state_at(keys)
            model = node.task_cls.Params if node is not None and node.task_cls is not None else None
        elif owner == "world" and k.mission is not None:
            model = k.mission.world_cls.Params
        elif owner == "robot" and k.mission is not None:
            model = k.mission.robot_cls.Params
        for p in params_table(model):
            if p.name == keys[-1]:
                extra = ""
                levels = getattr(model, "FIDELITY", {})
                sources = [f"- {lvl}: {s.value!r} — {s.source}" for lvl, vals in levels.items()
                           for n, s in vals.items() if n == p.name]
                if sources:
                    extra = "\n\nfidelity values:\n" + "\n".join(sources)
                return f"**{p.name}**: {param_detail(p)}\n\n{p.description}{extra}"
    if on_key and len(keys) >= 2 and keys[-2] in ("states", "regions"):
        return _state_markdown(k, keys)
    if len(keys) >= 2 and keys[-2] == "bind" and not on_key:
        kind = k.kind_of_slot(k.state_at(keys), keys[-1])
        return _profile_markdown(k, kind, text or "")
    if on_key and keys[0] == "profiles" and len(keys) == 3:
        return _profile_markdown(k, keys[1], keys[2])
    guard = keys[-1] in GUARD_KEYS and not (keys[-1] == "after" and "transitions" in keys)
    if not on_key and guard and ("transitions" in keys or keys[0] == "properties"):
        found = _threshold(line, col)
        if found is not None:
            return found[0]
        word = _word(line, col)
        if word is not None:
            metrics = k.metrics_in(k.state_at(keys) if "transitions" in keys else None)
            if word[0] in metrics:
                unit, _ = metrics[word[0]]
                who = k.publisher_of(word[0])
                return f"**metric `{word[0]}`** [{unit or 'dimensionless'}]" + (f"\n\npublished by {who}" if who else "")
    return None


def _profile_markdown(k: Knowledge, kind: str, name: str) -> str | None:
    """A profile's values after its model's defaults (as a state that binds it resolves it), else as written."""
    resolved = k.resolved_profile(kind, name)
    written = k.profiles_of_kind(kind).get(name)
    if resolved is None and written is None:
        return None
    lines = [f"**profile `{kind}.{name}`**" + (f" ({type(resolved).__name__})" if resolved is not None else "")]
    values = resolved.model_dump() if resolved is not None else dict(written or {})
    for field, value in values.items():
        mark = "" if isinstance(written, dict) and field in written else " *(default)*"
        lines.append(f"- `{field}`: {value!r}{mark}")
    return "\n".join(lines)


def hover(ctx: Any, file: str, line: int, col: int) -> types.Hover | None:
    """The markdown for what is under (``line``, ``col``) of ``file``, or None."""
    k = Knowledge.of(ctx.ws, file)
    index = ctx.ws.index_of(file)
    text = ctx.ws.text_of(file)
    if index is None or text is None:
        return None
    if not index.entries and k.analysis is not None:
        index = k.analysis.index
    found = index.at(line, col)
    if found is None:
        return None
    entry, on_key = found
    lines = text.split("\n")
    current = lines[line] if 0 <= line < len(lines) else ""
    md = _markdown(k, entry.path, on_key, entry.text, current, col)
    if md is None:
        return None
    span = entry.key if on_key and entry.key is not None else entry.value
    return types.Hover(types.MarkupContent(types.MarkupKind.Markdown, md), ctx.range(file, span))

