"""A mission document's raw state tree (before the shape check: any value may be of any type), walked:
each state's sub-machines (its ``states`` or its parallel regions' ``states``), every state name, every
transition's target, the loop items, how deep a state sits, how many states there are.  Used by the
expansion of sub-missions (:mod:`taskflow.mission.submission`), which runs before the document is
validated."""

from __future__ import annotations

from typing import Any

from taskflow.mission.model import YPath

MAX_STATE_DEPTH = 32
"""States nest at most this many levels, sub-missions' included (the passes walk the tree recursively)."""


def loop_items(states: Any) -> set[str]:
    """Every ``foreach as:`` name under ``states`` (the loop items a mission's ``with:`` may pass)."""
    out: set[str] = set()
    for st in (states.values() if isinstance(states, dict) else []):
        if isinstance(st, dict):
            fe = st.get("foreach")
            if isinstance(fe, dict) and isinstance(fe.get("as"), str):
                out.add(fe["as"])
            for sub, _ in sub_machines(st, ()):
                out |= loop_items(sub)
    return out


def sub_machines(st: dict[str, Any], ypath: YPath) -> list[tuple[Any, YPath]]:
    """A state's sub-machines with where they are: its ``states``, or each parallel region's ``states``."""
    regions = st.get("regions")
    if isinstance(regions, dict) and regions:
        return [(r.get("states"), ypath + ("regions", name, "states")) for name, r in regions.items()
                if isinstance(r, dict)]
    return [(st.get("states"), ypath + ("states",))]


def state_names(states: Any) -> set[str]:
    """Every state name at any depth under ``states``."""
    out: set[str] = set()
    for name, st in (states.items() if isinstance(states, dict) else []):
        out.add(str(name))
        if isinstance(st, dict):
            for sub, _ in sub_machines(st, ()):
                out |= state_names(sub)
    return out


def targets(states: Any, ypath: YPath) -> list[tuple[YPath, str]]:
    """``(where, to)`` of every transition under ``states``."""
    out: list[tuple[YPath, str]] = []
    for name, st in (states.items() if isinstance(states, dict) else []):
        if not isinstance(st, dict):
            continue
        for i, tr in enumerate(st.get("transitions") or [] if isinstance(st.get("transitions"), list) else []):
            if isinstance(tr, dict) and isinstance(tr.get("to"), str):
                out.append((ypath + (name, "transitions", i, "to"), tr["to"]))
        for sub, where in sub_machines(st, ypath + (name,)):
            out += targets(sub, where)
    return out


def state_level(ypath: YPath) -> int:
    """How many states deep ``ypath`` (``machine, states, a, states, b`` or ``…regions, r, states, b``) is."""
    return sum(1 for i in range(2, len(ypath)) if ypath[i - 1] == "states")


def too_deep(states: Any, ypath: YPath) -> YPath | None:
    """The first state under ``states`` nested more than :data:`MAX_STATE_DEPTH` levels deep (found without
    recursion, so a document nested hundreds of levels deep gets this answer instead of a ``RecursionError``)."""
    todo: list[tuple[Any, YPath, int]] = [(states, ypath, 1)]
    while todo:
        here, where, level = todo.pop()
        if not isinstance(here, dict):
            continue
        for name, st in here.items():
            if not isinstance(st, dict):
                continue
            if level > MAX_STATE_DEPTH:
                return where + (name,)
            todo += [(sub, w, level + 1) for sub, w in sub_machines(st, where + (name,))]
    return None


def count_states(states: Any) -> int:
    """How many states, at any depth, ``states`` holds (depth already bounded by :func:`too_deep`)."""
    return sum(1 + sum(count_states(sub) for sub, _ in sub_machines(st, ()))
               for st in (states.values() if isinstance(states, dict) else []) if isinstance(st, dict))
