"""Compile pass: every transition as a typed record (:mod:`taskflow.mission.model`) — its target resolved
(sibling, ancestor's sibling, or dotted path), its guard parsed, checked against the metrics published
where it is declared, converted to base units and compiled, its event known, its clock named."""

from __future__ import annotations

from typing import TypedDict

from taskflow.api import Metric
from taskflow.mission import model
from taskflow.mission.compile.context import Compilation
from taskflow.mission.compile.dataflow import data_hint
from taskflow.mission.compile.tree import metrics_under, sibling_metrics
from taskflow.mission.guards import (
    Comparison,
    Guard,
    GuardSyntaxError,
    Predicate,
    bind_units,
    compile_guard,
    never_holds,
    parse_guard,
)
from taskflow.mission.model import StateNode, Transition, YPath
from taskflow.mission.schema import SINCE_ENTRY, SINCE_FIRST_ENTRY, State
from taskflow.mission.schema import Transition as TransitionSpec
from taskflow.registry import describe_choices
from taskflow.units import UnitError, parse_quantity


def compile_transitions(c: Compilation, root: StateNode, events: set[str]) -> None:
    quantities, not_quantities = guard_params(c)
    for n in root.walk():
        if n.parent is None:
            continue
        spec = c.spec_of(n)
        if n.owns is not None:  # a region: no transitions of its own (the schema has none)
            continue
        assert isinstance(spec, State)
        for i, tr in enumerate(spec.transitions):
            where = n.ypath + ("transitions", i)
            target = _resolve_target(c, n, tr.to)
            if target is None:
                valid = sorted({s for a in [n.parent, *n.parent.ancestors()] for s in a.children} | set(c.states))
                c.err(where + ("to",), f"unknown target state {tr.to!r}", describe_choices(tr.to, valid))
                continue
            region = _region_entered_from_outside(n, target)
            if region is not None:
                parallel = region.parent
                assert parallel is not None
                c.err(where + ("to",), (f"{target.path!r} is a parallel region" if region is target else
                                        f"{target.path!r} is inside region {region.path!r}, which this transition does "
                                        "not start from") + ": a region is entered only with its parallel state",
                      f"target {parallel.path!r} (every region starts at its initial state), or a state outside it")
                continue
            compiled = _compile_one(c, n, target, tr, where, events, quantities, not_quantities)
            if compiled is not None:
                n.transitions.append(compiled)
                c.transitions.append(compiled)


class _Common(TypedDict):
    """The fields every transition record has (:class:`taskflow.mission.model.Transition`)."""

    index: int
    source: StateNode
    target: StateNode
    resume: bool
    blend: float


def _compile_one(c: Compilation, n: StateNode, target: StateNode, tr: TransitionSpec, where: YPath, events: set[str],
                 quantities: dict[str, tuple[float, str]], not_quantities: dict[str, str]) -> Transition | None:
    common = _Common(index=len(c.transitions), source=n, target=target, resume=tr.resume, blend=float(tr.blend or 0.0))
    guard: tuple[Guard, Predicate] | None = None
    if tr.when is not None:
        guard = _compile_guard(c, n, tr.when, where + ("when",), quantities, not_quantities)
        if guard is None:
            return None
    if tr.on is not None:
        if tr.on not in events:
            c.err(where + ("on",), f"unknown event {tr.on!r}: no world, sensor, action or task of this mission emits it",
                  f"{describe_choices(tr.on, sorted(events))}; `taskflow describe NAME` lists a world's or task's events")
            return None
        label = f"on {tr.on}" + (f" when {tr.when}" if tr.when else "")
        return model.EventTransition(**common, label=label, event=tr.on, guard=guard[0] if guard else None,
                               predicate=guard[1] if guard else None)
    if guard is not None:
        dwell = float(tr.for_ or 0.0)
        label = str(tr.when) + (f" for {dwell:g} s" if dwell else "")
        return model.GuardTransition(**common, label=label, guard=guard[0], predicate=guard[1], dwell=dwell)
    if tr.after is not None:
        after = float(tr.after)
        label = f"after {after:g} s"
        since, first = n, False
        if tr.since is not None and tr.since != SINCE_ENTRY:
            label += f" since {tr.since}"
            first = tr.since == SINCE_FIRST_ENTRY
            if not first:
                found = _enclosing(n, tr.since)
                if found is None:
                    valid = [SINCE_ENTRY, SINCE_FIRST_ENTRY] + [a.name for a in n.ancestors()[1:]]
                    c.err(where + ("since",), f"since {tr.since!r}: neither 'entry', 'first_entry' nor a state "
                          f"enclosing {n.path!r}", describe_choices(tr.since, valid))
                    return None
                since = found
        return model.TimeoutTransition(**common, label=label, after=after, since=since, since_first=first)
    if n.is_leaf:
        c.err(where + ("done",), "`done` waits for a sub-machine to finish, but this state has no sub-states",
              "use `when`, `after` or `on`")
        return None
    outcome = None if tr.done is True else str(tr.done)
    return model.DoneTransition(**common, label="done" if outcome is None else f"done {outcome}", outcome=outcome)


def _unknown_metric_hint(c: Compilation, n: StateNode, m: str, available: dict[str, str]) -> str:
    """What a guard on ``n`` may read instead of ``m``, where ``m`` is published, and — inside a region — how to
    read a metric while the region runs (a monitor region)."""
    hint = describe_choices(m, list(available))
    publishers = sorted(p.path for p in c.states.values() if p.is_leaf and p.task_cls is not None
                        and m in p.task_cls.metrics)
    if publishers:
        hint += (f"; {m!r} is published only in {', '.join(map(repr, publishers[:3]))}"
                 f"{' …' if len(publishers) > 3 else ''}, never active with {n.path!r}")
    if n.region is not None:
        siblings = sibling_metrics(n)
        listing = ", ".join(f"{k} ({r})" for k, (_, r) in sorted(siblings.items())) or "(none)"
        hint += (f"; a guard in region {n.region.path!r} reads the world's metrics, its own tasks' and those of its "
                 f"sibling regions' tasks: {listing}; to watch {m!r} while this region runs, run the task that "
                 "publishes it in a sibling region of its own (a monitor region, `owns` nothing)")
    else:
        hint += "; `taskflow describe TASK` lists a task's metrics"
    return hint


def _region_entered_from_outside(source: StateNode, target: StateNode) -> StateNode | None:
    """The region ``target`` lies in that ``source`` is not inside (None: the transition enters no region from
    outside).  A region starts only with its parallel state, so the others are entered with it."""
    inside = set(map(id, source.ancestors()))
    for a in target.ancestors()[1:]:
        if a.owns is not None and (id(a) not in inside or a is target):
            return a
    return None


def _resolve_target(c: Compilation, source: StateNode, name: str) -> StateNode | None:
    if "." in name:
        return c.states.get(name)
    scope: StateNode | None = source.parent
    while scope is not None:
        if name in scope.children:
            return scope.children[name]
        scope = scope.parent
    return None


def _enclosing(n: StateNode, name: str) -> StateNode | None:
    """``n`` or the ancestor of ``n`` called ``name`` (a bare name or a dotted path)."""
    for a in n.ancestors()[1:]:
        if name in (a.name, a.path):
            return a
    return None


def guard_params(c: Compilation) -> tuple[dict[str, tuple[float, str]], dict[str, str]]:
    """Parameters usable in guards (quantities), and why each other parameter is not."""
    out: dict[str, tuple[float, str]] = {}
    bad: dict[str, str] = {}
    for k, v in c.spec.parameters.items():
        try:
            if isinstance(v, bool) or not isinstance(v, (str, int, float)):
                raise UnitError(f"it is {type(v).__name__} {v!r}")
            out[k] = parse_quantity(v)
        except UnitError as exc:
            bad[k] = f"${k} is not a quantity like '2 mm' ({exc})"
    return out, bad


def _compile_guard(c: Compilation, n: StateNode, text: str, where: YPath, quantities: dict[str, tuple[float, str]],
                   not_quantities: dict[str, str]) -> tuple[Guard, Predicate] | None:
    """Parse, check and compile the guard ``text`` of a transition of ``n`` (None: reported)."""
    try:
        guard = parse_guard(text)
    except GuardSyntaxError as exc:
        c.err(where, f"guard {text!r}: {exc} (at character {exc.offset + 1})", exc.hint)
        return None
    available = metrics_under(c, n)
    unknown = [m for m in sorted(guard.metrics) if m not in available]
    for m in unknown:
        c.err(where, f"metric {m!r} is not published in state {n.path!r}", _unknown_metric_hint(c, n, m, available))
    readable = c.mission_data.guard_units()  # data.<key> names (taskflow.mission.compile.dataflow)
    unknown_data = sorted({cmp.metric for cmp in guard.comparisons()} - set(guard.metrics) - set(readable))
    for m in unknown_data:
        c.err(where, f"guard {text!r}: {m!r} is not mission data a guard can read", data_hint(c, m))
    if unknown or unknown_data:
        return None
    available = {**available, **readable}
    for cmp in guard.comparisons():
        if cmp.param is not None and cmp.param in not_quantities:
            c.err(where, f"guard {text!r}: {not_quantities[cmp.param]}", "give the parameter a number with a unit")
    for msg in bind_units(guard, available, quantities, skip=set(not_quantities)):
        c.err(where, f"guard {text!r}: {msg}")
    if any(cmp.value is None for cmp in guard.comparisons()):
        return None
    if not _reachable(c, guard, available, where):
        return None
    return guard, compile_guard(guard)


def _reachable(c: Compilation, guard: Guard, units: dict[str, str], where: YPath) -> bool:
    """Report every comparison of ``guard`` that no value in its metric's declared range (:class:`Metric`)
    satisfies — ``pos_error < -1 mm``, ``heading_error > 4 rad``, ``abs(x) < 0`` — and say whether none was."""
    ok = True
    for cmp in guard.comparisons():
        unit = units.get(cmp.metric, "")
        low, high = (unit.low, unit.high) if isinstance(unit, Metric) else (None, None)
        if not never_holds(cmp, low, high):
            continue
        ok = False
        shown = f"abs({cmp.metric})" if cmp.absolute else cmp.metric
        rng = f"{unit.reason or 'declared'}: {unit.bounds()}{' ' + unit if unit else ''}" \
            if isinstance(unit, Metric) and unit.bounds() else ""
        if cmp.absolute:
            why = "an absolute value is never negative" + (f"; {cmp.metric} is {rng}" if rng else "")
        else:
            why = f"{cmp.metric} is {rng}"
        given = ("parameters", cmp.param)  # a threshold a --set gave: name the --set, not the file's guard
        at = given if cmp.param is not None and given in c.smap.overrides else where
        c.err(at, f"guard {guard.text!r}: {shown} {cmp.op} {_threshold(cmp, unit)} can never hold ({why})",
              "a threshold inside the metric's range (`taskflow describe TASK` lists each metric's range)")
    return ok


def _threshold(cmp: Comparison, unit: str) -> str:
    """The compared value as the guard gave it, in base units (``-0.001 m``, ``$eps_t = -0.001 m``)."""
    text = f"{cmp.value:g}" + (f" {unit}" if str(unit) else "")
    return f"${cmp.param} = {text}" if cmp.param is not None else text
