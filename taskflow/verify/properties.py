"""A mission's declared properties (``properties:``, :mod:`taskflow.mission.properties`) decided on its model.

A property whose atoms are states, events and outcomes only (``Property.structural``) is decided on the model of
:mod:`taskflow.verify.model`; one that compares metrics is left to the runtime monitor of every run
(:mod:`taskflow.execution.monitors`), because the model does not interpret metrics.  In a configuration,
``state(P)`` holds when ``P`` or a state below it is active, ``outcome(O)`` when the run has ended with ``O``, and
``event(E)`` may hold or not — the environment's choice — when ``E`` can arrive there (the world's and the
mission's events, an active task's, an active action's end events), and does not otherwise.  So each expression
has a set of possible values in a configuration, and:

* **absence** (``never: A``, ``while: B``) is violated when a reachable configuration lets ``A and B`` hold;
* **universality** (``always: A``) when one lets ``A`` fail;
* **precedence** (``only_after: A``, ``occurs: B``) when a path reaches a configuration that lets ``B`` hold
  with ``A`` false, through configurations that all let ``A`` be false;
* **response** (``after: A``, ``within: T``, ``then: B``) when, from a configuration that lets ``A`` hold and ``B``
  fail, the model can keep ``B`` false until the run ends, or for more ticks than ``T`` spans (each tick is
  :attr:`~taskflow.verify.model.Model.quantum` seconds: a deadline shorter than a tick is decided to within one).
  An event that makes ``A`` hold is taken as the engine takes it: where an active state has a transition on it,
  that transition (or one checked before it) fires in the same control period — time does not pass first; where
  none has, the event is ignored.

Absence, universality and precedence go to Storm (``Pmax=? [F bad]``, ``Pmax=? [notA U bad]``) on labels built
here; a response is a search over (configuration, ticks elapsed) on the model.  A violation's counterexample is the
shortest path of the model to it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Iterator
from itertools import product
from typing import Any

from taskflow.mission.guards import Atom, Guard, Predicate, compile_guard
from taskflow.mission.model import EventTransition
from taskflow.verify.counterexample import Counterexample
from taskflow.verify.model import TICK, Config, Model, Step, _Explorer
from taskflow.verify.results import FAILS, HOLDS, MONITORED, CheckResult
from taskflow.verify.storm import StormModel

__all__ = ["check_properties"]


class _Evaluator:
    """The possible values of a property's expressions in each configuration of a model."""

    def __init__(self, model: Model, states: dict[str, str]) -> None:
        self.model = model
        self.states = states  # state(NAME) as written → path
        self.explorer = _Explorer(model.mission, model.max_time, model.operator)
        self._choices: dict[tuple[Any, ...], list[frozenset[str]]] = {}
        self._events: dict[int, set[str]] = {}
        self._preds: dict[int, Predicate] = {}  # id(guard) → its predicate over the facts below
        self.facts_active: frozenset[str] = frozenset()  # what the atoms read: the configuration's active states, its
        self.facts_outcome: str | None = None  # outcome, and the events chosen to arrive
        self.facts_events: frozenset[str] = frozenset()

    def _pred(self, g: Guard) -> Predicate:
        """``g`` compiled once by the guards' own compiler, its atoms reading the facts of the configuration."""
        pred = self._preds.get(id(g))
        if pred is None:
            def atom(a: Atom) -> Predicate:
                if a.kind == "state":
                    path = self.states.get(a.name, a.name)
                    return lambda m, d: path in self.facts_active
                if a.kind == "outcome":
                    return lambda m, d: self.facts_outcome == a.name
                return lambda m, d: a.name in self.facts_events

            pred = self._preds[id(g)] = compile_guard(g, atom)
        return pred

    def events(self, s: int) -> set[str]:
        got = self._events.get(s)
        if got is None:
            c: Config = self.model.configs[s]
            world, ends = self.explorer.events_possible(c)
            got = set() if c.outcome is not None else world | ends
            self._events[s] = got
        return got

    def possible(self, s: int, exprs: list[Guard], wanted: list[bool]) -> bool:
        """Whether, in configuration ``s``, some choice of the arriving events gives each of ``exprs`` its
        ``wanted`` value at once."""
        return next(self.choices(s, exprs, wanted), None) is not None

    def choices(self, s: int, exprs: list[Guard], wanted: list[bool]) -> Iterator[frozenset[str]]:
        """Each set of arriving events (among those the expressions name) that gives each of ``exprs`` its ``wanted``
        value in configuration ``s``.  The answer depends only on what the atoms read — the active states, the
        outcome, the events that can arrive — which configurations differing by clocks or counters alone (most of
        a large model) share: it is kept per set of active leaves and outcome, which decide all three."""
        c: Config = self.model.configs[s]
        key = (tuple(map(id, exprs)), tuple(wanted), c.leaves, c.outcome)  # what decides active states and events
        got = self._choices.get(key)
        if got is None:
            names = tuple(sorted({a.name for e in exprs for a in e.atoms() if a.kind == "event"} & self.events(s)))
            active, outcome = self.model.active_states(s), c.outcome
            preds = [self._pred(e) for e in exprs]
            got = []
            for choice in product((False, True), repeat=len(names)):
                self.facts_active, self.facts_outcome = active, outcome
                self.facts_events = frozenset(n for n, v in zip(names, choice) if v)
                if all(p({}, {}) == w for p, w in zip(preds, wanted)):
                    got.append(self.facts_events)
            self._choices[key] = got
        return iter(got)

    def first_steps(self, s: int, arriving: frozenset[str]) -> list[Step]:
        """The steps the machine can take in the control period ``arriving`` events arrive in configuration ``s``:
        where an active leaf's table has a transition on one of them, that transition or one checked before it
        fires (no time passes first); where none has, the events are ignored and anything may happen."""
        allowed: set[int] = set()
        handled = False
        for leaf in self.model.configs[s].leaves:
            table = self.explorer.tables.get(leaf, [])
            first = next((k for k, tr in enumerate(table) if isinstance(tr, EventTransition) and tr.event in arriving),
                         None)
            if first is None:
                allowed.update(tr.index for tr in table)
            else:
                handled = True
                allowed.update(tr.index for tr in table[:first + 1])
        steps = self.model.steps[s]
        if not handled:
            return steps
        return [st for st in steps if st.cause != TICK and st.transition is not None and st.transition in allowed]


def _where(model: Model, ev: _Evaluator, pred: Any) -> list[int]:
    return [s for s in range(model.n_states) if pred(s)]


def check_property(model: Model, prop: Any) -> CheckResult:
    name = f"property:{prop.name}"
    if not prop.structural:
        metrics = sorted({a.name for a in prop.atoms() if a.kind == "metric"})
        return CheckResult(name, MONITORED, f"{prop.pattern}: compares {', '.join(metrics)} — decided in every run by "
                           "its monitor, not on the model (which does not interpret metrics)")
    if all(a.kind == "event" for a in prop.atoms()):
        events = sorted({a.name for a in prop.atoms()})
        return CheckResult(name, MONITORED, f"{prop.pattern}: reads only the events {', '.join(events)}, which the world "
                           "sends whatever the machine does — decided in every run by its monitor")
    ev = _Evaluator(model, prop.states)
    e = dict(prop.exprs)
    pattern = prop.pattern
    if pattern in ("absence", "universality"):
        if pattern == "absence":
            exprs = [e["never"]] + ([e["while"]] if "while" in e else [])
            bad = _where(model, ev, lambda s: ev.possible(s, exprs, [True] * len(exprs)))
            what = (f"`{e['never'].text}` and `{e['while'].text}` can hold" if "while" in e
                    else f"`{e['never'].text}` can hold")
        else:
            bad = _where(model, ev, lambda s: ev.possible(s, [e["always"]], [False]))
            what = f"`{e['always'].text}` can fail"
        return _reach_result(model, name, pattern, bad, what)
    if pattern == "precedence":
        a, b = e["only_after"], e["occurs"]
        not_a = _where(model, ev, lambda s: ev.possible(s, [a], [False]))
        bad = _where(model, ev, lambda s: ev.possible(s, [a, b], [False, True]))
        storm = StormModel(model, extra_labels={"prop_not_a": not_a, "prop_bad": bad})
        if storm.values('Pmax=? ["prop_not_a" U "prop_bad"]')[model.initial] <= 0.0:
            return CheckResult(name, HOLDS, f"precedence: `{b.text}` can hold only after `{a.text}` has (on every path "
                               "of the model)")
        path = [] if model.initial in bad else model.path_to(bad, avoid=set(range(model.n_states)) - set(not_a))
        assert path is not None  # Storm found one
        return CheckResult(name, FAILS, f"precedence: `{b.text}` can hold before `{a.text}` ever has",
                           Counterexample(model, path, f"`{b.text}` holds here and `{a.text}` has not held on the way"))
    return _response(model, name, prop, ev, e["after"], e["then"])


def _reach_result(model: Model, name: str, pattern: str, bad: list[int], what: str) -> CheckResult:
    storm = StormModel(model, extra_labels={"prop_bad": bad})
    if storm.values('Pmax=? [F "prop_bad"]')[model.initial] <= 0.0:
        return CheckResult(name, HOLDS, f"{pattern}: no reachable configuration where {what}")
    path = model.path_to(bad) or []
    end = path[-1][1].target if path else model.initial
    return CheckResult(name, FAILS, f"{pattern}: {len(bad)} reachable configurations where {what}, e.g. "
                       f"{model.configs[end].describe()}",
                       Counterexample(model, path, f"here {what}", list(model.configs[end].leaves)))


def _response(model: Model, name: str, prop: Any, ev: _Evaluator, a: Guard, b: Guard) -> CheckResult:
    within = float(prop.within or 0.0)
    limit = int(math.floor(within / model.quantum + 1e-9))  # ticks the deadline spans
    not_b = set(_where(model, ev, lambda s: ev.possible(s, [b], [False])))
    longest, ends = _delays(model, not_b, limit)
    triggers = [(s, arriving) for s in range(model.n_states) for arriving in ev.choices(s, [a, b], [True, False])]
    depth = _depths(model)
    triggers.sort(key=lambda x: depth.get(x[0], model.n_states))  # the nearest first: the shortest counterexample
    for t, arriving in triggers:
        first = ev.first_steps(t, arriving)
        if not (model.configs[t].final or any(
                st.target in not_b and (ends.get(st.target, False) or
                                        (1 if st.cause == TICK else 0) + longest[st.target] > limit) for st in first)):
            continue
        found = _escape(model, t, first, not_b, limit, within, b.text)
        assert found is not None  # the delays above say there is one
        tail, why = found
        lead = model.path_to([t]) or []
        when = f" with {', '.join(sorted(arriving))} arriving" if arriving else ""
        return CheckResult(name, FAILS, f"response: `{a.text}` can hold in {model.configs[t].describe()}{when}, and then {why}",
                           Counterexample(model, lead + tail, why, list(model.configs[t].leaves)))
    tol = "" if limit * model.quantum == within else f" (decided to within one tick of {model.quantum:g} s)"
    return CheckResult(name, HOLDS, f"response: whenever `{a.text}` can hold, `{b.text}` follows within {within:g} s{tol}")


def _depths(model: Model) -> dict[int, int]:
    """Steps from the initial configuration to each configuration (breadth first)."""
    depth = {model.initial: 0}
    queue = deque([model.initial])
    while queue:
        s = queue.popleft()
        for st in model.steps[s]:
            if st.target not in depth:
                depth[st.target] = depth[s] + 1
                queue.append(st.target)
    return depth


def _delays(model: Model, not_b: set[int], limit: int) -> tuple[dict[int, int], dict[int, bool]]:
    """For each configuration where B can be false: the most ticks the model can keep it false from there (capped
    at ``limit + 1``), and whether it can reach the run's end with B false — a fixpoint over the steps between
    such configurations (each value only grows, at most ``limit + 1`` times)."""
    preds: dict[int, list[tuple[int, int]]] = {s: [] for s in not_b}
    for s in not_b:
        for st in model.steps[s]:
            if st.target in not_b:
                preds[st.target].append((s, 1 if st.cause == TICK else 0))
    cap = limit + 1
    longest = {s: 0 for s in not_b}
    work = deque(not_b)
    queued = set(not_b)
    while work:
        n = work.popleft()
        queued.discard(n)
        for s, w in preds[n]:
            v = min(cap, w + longest[n])
            if v > longest[s]:
                longest[s] = v
                if s not in queued:
                    queued.add(s)
                    work.append(s)
    ends = {s: model.configs[s].final for s in not_b}
    stack = [s for s in not_b if ends[s]]
    while stack:
        n = stack.pop()
        for s, _ in preds[n]:
            if not ends[s]:
                ends[s] = True
                stack.append(s)
    return longest, ends


def _escape(model: Model, t: int, first: list[Step], not_b: set[int], limit: int,
            within: float, b_text: str) -> tuple[list[tuple[int, Step]], str] | None:
    """A path from ``t`` (its first step among ``first``) that keeps B false past the deadline or to the run's end,
    breadth first over (configuration, ticks elapsed): the steps and why it violates, or None."""
    if model.configs[t].final:
        return [], f"the run has ended and `{b_text}` does not hold"
    back: dict[tuple[int, int], tuple[tuple[int, int], Step]] = {}
    seen = {(t, 0)}
    queue = deque([(t, 0)])
    while queue:
        s, k = queue.popleft()
        for step in (first if (s, k) == (t, 0) else model.steps[s]):
            k2 = k + (1 if step.cause == TICK else 0)
            n = step.target
            if n not in not_b or (n, k2) in seen:
                continue
            back[(n, k2)] = ((s, k), step)
            why = None
            if k2 > limit:
                why = f"`{b_text}` has not held {k2 * model.quantum:g} s later (deadline {within:g} s)"
            elif model.configs[n].final:
                why = f"the run ends and `{b_text}` never held"
            if why is not None:
                path: list[tuple[int, Step]] = []
                node = (n, k2)
                while node in back:
                    prev, st = back[node]
                    path.append((prev[0], st))
                    node = prev
                return path[::-1], why
            seen.add((n, k2))
            queue.append((n, k2))
    return None


def check_properties(model: Model) -> list[CheckResult]:
    """One result per declared property of the model's mission (:func:`check_property`)."""
    props = list(getattr(model.mission, "properties", []) or [])
    if not props:
        return []
    out = []
    for p in props:
        t0 = time.perf_counter()
        res = check_property(model, p)
        res.seconds = time.perf_counter() - t0
        out.append(res)
    return out
