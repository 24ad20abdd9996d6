"""What a place in a mission's text means, for completion and hover: which state of the compiled mission a
document path is in (also inside a sub-mission file opened on its own), the metrics, slots, profiles and
transition targets there, and the registered classes' parameters as catalogue :class:`Param` rows.

Everything reads the workspace's latest analysis that compiled (:meth:`Workspace.context`), so it keeps
answering while the buffer is half-typed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from taskflow.catalogue.catalogue import Catalogue, build
from taskflow.catalogue.declarations import Param, params_of
from taskflow.lsp.analysis import Analysis, Workspace, same_file
from taskflow.lsp.document import DocumentIndex
from taskflow.mission.model import CompiledMission, StateNode, YPath
from taskflow.mission.submission import use_path
from taskflow.mission.yamlsrc import load_yaml_text


@functools.lru_cache(maxsize=1)
def catalogue() -> Catalogue:
    """The catalogue of everything registered (built once per server: entry points are imported)."""
    return build()


@functools.lru_cache(maxsize=256)
def params_table(model: type | None) -> tuple[Param, ...]:
    """The catalogue's rows (type, default, unit, bounds, description) for the fields of a pydantic model."""
    if model is None:
        return ()
    try:
        return params_of(model)
    except Exception:  # a plugin's odd model: no rows rather than a failed request
        return ()


def param_detail(p: Param) -> str:
    """A parameter's one-line detail: type, unit, bounds and default."""
    bits = [p.type]
    if p.unit:
        bits.append(f"[{p.unit}]")
    if p.bounds:
        bits.append(p.bounds)
    bits.append("required" if p.required else f"default {p.default!r}")
    return " ".join(bits)


@dataclass
class Knowledge:
    """The compiled mission behind one file and where that file sits in it: ``offset`` maps a path of the
    file's document onto the expanded document (empty for a mission; for a sub-mission file, the ``use:``
    state's path replaces the file's leading ``machine``)."""

    analysis: Analysis | None
    mission: CompiledMission | None
    offset: tuple[YPath, YPath] = ((), ())  # (document prefix, expanded prefix)
    written: DocumentIndex | None = None  # the index of the text as it is now (``analysis`` may be older)

    @classmethod
    def of(cls, ws: Workspace, file: str) -> Knowledge:
        a = ws.context(file)
        now = ws.index_of(file)
        if a is not None and a.mission is not None:
            return cls(a, a.mission, written=now)
        if a is not None and a.kind == "submission":
            for user in ws.missions_using(file):
                assert user.mission is not None
                for node in user.mission.states.values():
                    if node.use and same_file(str(use_path(node.use, user.file)), file):
                        return cls(a, user.mission, (("machine",), node.ypath), now)
        return cls(a, None, written=now)

    def expanded(self, path: YPath) -> YPath:
        """``path`` of the file's document as a path of the mission's expanded document."""
        doc, exp = self.offset
        keys = tuple(p for p in path if isinstance(p, str))
        return exp + keys[len(doc):] if keys[:len(doc)] == doc else keys

    def state_at(self, path: YPath) -> StateNode | None:
        """The innermost state whose text holds ``path``."""
        if self.mission is None:
            return None
        keys = self.expanded(path)
        best: StateNode | None = None
        for node in self.mission.states.values():
            n = len(node.ypath)
            if keys[:n] == tuple(node.ypath) and (best is None or n > len(best.ypath)):
                best = node
        return best

    def parameters(self) -> dict[str, Any]:
        """``$name`` → value of the mission's (or the sub-mission file's) ``parameters`` as written, and each
        ``foreach`` item (→ a description of what it iterates)."""
        params: dict[str, Any] = {}
        if self.analysis is not None and isinstance(self.analysis.data, dict):
            raw = self.analysis.data.get("parameters")
            params.update(raw if isinstance(raw, dict) else {})
        if self.mission is not None:
            params.update({n: v for n, v in self.mission.spec.parameters.items() if n not in params})
            for node in self.mission.states.values():
                if node.loop is not None:
                    params.setdefault(node.loop.item, f"item of ${node.loop.items} (foreach in {node.path})")
        return params

    def event_sources(self, event: str) -> list[str]:
        """Who raises ``event`` in this mission: the world, its actions, the states' tasks, or the mission's own
        ``events:`` (for the operator)."""
        m = self.mission
        if m is None:
            return []
        out = [f"world `{m.world_cls.name}`"] if event in m.world_cls.events else []
        out += [f"the end of action `{a}`" for a, ends in m.world_cls.actions.items() if event in ends]
        tasks = sorted({n.task_cls.name for n in m.states.values() if n.task_cls is not None and event in n.task_cls.events})
        out += [f"task `{name}`" for name in tasks]
        if event in m.spec.events:
            out.append("the mission's `events:` (raised by the operator: `taskflow ctl RUN inject`)")
        return out

    # -- what a state offers ------------------------------------------------------------------------------
    def metrics_in(self, node: StateNode | None) -> dict[str, tuple[str, str]]:
        """Metric → (unit, publisher) a guard of ``node`` can read: its task's and the world's (every metric of
        the mission when ``node`` is None or has no task)."""
        if self.mission is None:
            return {}
        out: dict[str, tuple[str, str]] = {}
        if node is not None and node.task_cls is not None:
            out.update({k: (str(u), f"task {node.task_cls.name}") for k, u in node.task_cls.metrics.items()})
            out.update({k: (str(u), f"world {self.mission.world_cls.name}")
                        for k, u in self.mission.world_cls.metrics.items()})
            return out
        for n in self.mission.states.values():
            if n.task_cls is not None:
                for k, u in n.task_cls.metrics.items():
                    out.setdefault(k, (str(u), f"task {n.task_cls.name}"))
        for k, u in self.mission.world_cls.metrics.items():
            out.setdefault(k, (str(u), f"world {self.mission.world_cls.name}"))
        for k, u in self.mission.metric_units.items():
            out.setdefault(k, (u, ""))
        return out

    def publisher_of(self, metric: str) -> str:
        """Who publishes ``metric`` (``task NAME`` / ``world NAME``, comma-separated), empty when no one."""
        if self.mission is None:
            return ""
        who = sorted({f"task {n.task_cls.name}" for n in self.mission.states.values()
                      if n.task_cls is not None and metric in n.task_cls.metrics})
        if metric in self.mission.world_cls.metrics:
            who.append(f"world {self.mission.world_cls.name}")
        return ", ".join(who)

    def slots_of(self, node: StateNode | None) -> dict[str, type]:
        """Profile slot → its model, for the effective task of ``node``."""
        if node is None or node.task_cls is None:
            return {}
        return dict(node.task_cls.slots)

    def slot_kind(self, model: type) -> str:
        return getattr(model, "kind", None) or ""

    def kind_of_slot(self, node: StateNode | None, slot: str) -> str:
        """The ``profiles:`` kind a slot's profile names (the slot's model's ``kind``, else the slot's name)."""
        model = self.slots_of(node).get(slot)
        return (self.slot_kind(model) if model is not None else "") or slot

    def model_of_kind(self, kind: str) -> type | None:
        """The slot model of any task of the mission whose profiles are ``profiles.<kind>``."""
        if self.mission is None:
            return None
        for node in self.mission.states.values():
            for slot, model in self.slots_of(node).items():
                if (self.slot_kind(model) or slot) == kind:
                    return model
        return None

    def profiles_of_kind(self, kind: str) -> dict[str, dict[str, Any]]:
        """Profile name → its fields as written, of ``profiles.<kind>`` (the mission's and its sub-missions')."""
        if self.mission is None:
            return {}
        table = self.mission.spec.profiles.get(kind, {})
        return dict(table) if isinstance(table, dict) else {}

    def resolved_profile(self, kind: str, name: str) -> BaseModel | None:
        """The profile ``name`` of ``kind`` as a state that binds it sees it: its model with every default
        filled (None when no state binds it)."""
        if self.mission is None:
            return None
        for node in self.mission.states.values():
            for slot, (_, bound, _) in node.bind.items():
                if bound == name and slot in node.profiles and self.kind_of_slot(node, slot) == kind:
                    return node.profiles[slot]
        return None

    def targets_from(self, node: StateNode | None) -> dict[str, str]:
        """Transition target → what it is, for a transition of ``node``: siblings, ancestors' siblings, then
        every state by its dotted path."""
        if self.mission is None:
            return {}
        out: dict[str, str] = {}
        walk = node
        while walk is not None and walk.parent is not None:
            for name, sib in walk.parent.children.items():
                if sib is not node:
                    out.setdefault(name, "sibling" if walk is node else f"state in {walk.parent.path or 'the machine'}")
            walk = walk.parent
        for path in self.mission.states:
            out.setdefault(path, "state (dotted path)")
        return out


def submission_parameters(file: str) -> dict[str, Any]:
    """The ``parameters:`` of a sub-mission file (name → default; None: required); empty when unreadable."""
    try:
        data, _ = load_yaml_text(Path(file).read_text(encoding="utf-8"), file)
    except Exception:
        return {}
    params = data.get("parameters") if isinstance(data, dict) else None
    return dict(params) if isinstance(params, dict) else {}
