"""The compiled mission as a finite model: every configuration the machine can be in, and every step it can take.

:func:`build_model` explores the machine of a :class:`~taskflow.mission.model.CompiledMission` exhaustively
and gives a :class:`Model`, an explicit Markov decision process without probabilities (a transition system)
whose nondeterminism is the environment's.  It follows the statechart semantics of
:mod:`taskflow.execution.statechart` step by step (UML external transitions, deep history with the
``foreach`` position, ``done`` by outcome, a ``foreach``'s ``require`` rule, parallel regions and their
``outcome_map``) and reuses its outcome rules (:mod:`taskflow.execution.outcomes`); the abstraction test
(``tests/verify/test_abstraction.py``) runs the real engine on generated machines and checks that every run
is a path of the model (:meth:`Model.path_of`).

What is **kept**: the active leaves (one per active region), each history state's resume point, each
``foreach``'s item index, count of items that succeeded and the current item's attempt (``retry``), which regions of an active parallel state have
finished and how, the run's outcome, and the clocks the timers read, counted in ticks of the model's time
step :attr:`Model.quantum` — the greatest common divisor of the mission's ``after`` values (and the
``--max-time`` given), so that every timeout falls on a tick.

What is **abstracted**:

* **guards** are free: the environment may make any ``when`` true at any moment (its metric atoms are not
  interpreted); a ``for: T`` dwell may fire once its state has been active for ``T`` (rounded down to the
  time step), which is when the engine may first fire it;
* **events** are environment choices, limited to what can arrive in the configuration: the world's events
  and the mission's own ``events:`` at any time, an action's end events while its state is active, a task's
  events while its state is active;
* **time** moves in ticks of :attr:`Model.quantum`; transitions take no time, so the environment may fire
  several between two ticks (the engine fires at most one per region per control period, a finer grid the
  model covers); an action's end events count as the world's actuators reporting, not as sensing: they still
  arrive when the sensors are lost (:attr:`Step.timed`); a timer falls due at the tick its ``after`` is reached and must fire before the next tick
  (the engine fires it at the first control period past its deadline, which lies between those two ticks),
  unless a transition fired by the environment leaves its state first;
* **not modelled**: operator actions (pre-emption, hold, abort), ``$data`` values, and the control law.

A step of the model is one firing and everything it sets off at the same instant (entering a final state
finishes its parent: the item's retry, the next ``foreach`` item, a ``done`` transition, a region, the run), so that a step
writes the same records to ``transitions.jsonl`` as the engine does, in the same order.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import reduce
from typing import Any

from taskflow.execution.outcomes import loop_verdict, parallel_outcome, parallel_verdict
from taskflow.execution.records import DONE, EVENT, GUARD, NEXT_ITEM, OPERATOR, PROPERTY, RETRY, START_CAUSE, TIMEOUT
from taskflow.mission.model import (
    CompiledMission,
    DoneTransition,
    EventTransition,
    GuardTransition,
    StateNode,
    TimeoutTransition,
    Transition,
)

__all__ = ["MAX_TIME", "TICK", "Config", "Model", "NotAPath", "StateBudgetExceeded", "Step", "build_model", "entered_by"]

TICK = "tick"
"""The cause of a step in which time passes by one :attr:`Model.quantum`."""
MAX_TIME = "max_time"
"""The cause of the step in which ``--max-time`` ends the run (outcome ``timeout``)."""
ENVIRONMENT = frozenset({GUARD, EVENT, OPERATOR})
"""The causes the environment chooses (a guard it makes true, an event it sends)."""
DEFAULT_BUDGET = 2_000_000
"""Most configurations :func:`build_model` explores before it gives up."""


class NotAPath(ValueError):
    """A run's records that the model cannot follow (the abstraction test's failure)."""


class StateBudgetExceeded(RuntimeError):
    """The model has more configurations than the exploration's budget."""


@dataclass(frozen=True)
class Config:
    """One configuration of the machine: what the engine holds between two control periods.

    ``clocks`` and ``loops`` are indexed like the model's :attr:`Model.clocks` and :attr:`Model.loop_states`."""

    leaves: tuple[str, ...]  # the active leaves, one per active region, in declaration order (finals included)
    clocks: tuple[int, ...]  # ticks each clock has run, capped at the largest value it is compared with; -1: stopped
    history: tuple[tuple[str, str], ...]  # history state → the state it resumes (sorted)
    loops: tuple[tuple[int, int, int], ...]  # per foreach: (item index, items succeeded, the item's attempt)
    regions: tuple[tuple[str, tuple[tuple[str, str], ...]], ...]  # parallel state → finished region → outcome
    outcome: str | None = None  # the run ended with it
    mission_ticks: int = 0  # ticks since the start (only with a max time)
    skipped: tuple[tuple[str, str], ...] = ()  # with the operator: rule state an operator left → its verdict then
    grace: bool = False  # a firing just happened with a timer due: one tick may still pass before it fires

    @property
    def final(self) -> bool:
        return self.outcome is not None

    def describe(self) -> str:
        """The active leaves as the records write them (``|`` between regions), and the outcome once ended."""
        text = " | ".join(self.leaves) if self.leaves else "(start)"
        return f"{text} [{self.outcome}]" if self.outcome is not None else text


@dataclass(frozen=True)
class Step:
    """One step of the model from a configuration: its cause, the transition (index into the mission's, or
    None) and the records it writes — ``(cause, to)`` per record, as ``transitions.jsonl`` gives them."""

    cause: str  # guard | timeout | event | tick | max_time (a done, next_item or retry cascade is in ``records``)
    target: int  # index of the configuration it leads to
    transition: int | None = None
    label: str = ""
    event: str | None = None
    records: tuple[tuple[str, str], ...] = ()
    action_end: bool = False  # an event step whose event ends an action running in the configuration

    @property
    def environment(self) -> bool:
        """Whether the environment chose it (a guard made true, an event sent — an action's end included)."""
        return self.cause in ENVIRONMENT

    @property
    def timed(self) -> bool:
        """Whether it can happen with the sensors lost — every guard false and no event from the world, its
        sensors or a task: a tick, a timeout, the max time, and an action's end (the world's actuators still
        report how an action they run ends)."""
        return self.action_end or not self.environment


@dataclass(frozen=True)
class Clock:
    """A clock the model keeps: ticks since ``state`` was entered (``first``: first entered since its
    enclosing state was entered afresh), capped at ``cap``."""

    state: str
    first: bool
    cap: int

    @property
    def name(self) -> str:
        return f"{self.state}{'^first' if self.first else ''}"


@dataclass
class Model:
    """The explored model: configurations (index 0: after the start) and the steps from each."""

    mission: CompiledMission
    quantum: float  # seconds per tick
    clocks: tuple[Clock, ...]
    loop_states: tuple[str, ...]
    configs: list[Config] = field(default_factory=list)
    steps: list[list[Step]] = field(default_factory=list)
    initial: int = 0
    start_records: tuple[tuple[str, str], ...] = ()
    max_time: float | None = None
    operator: bool = False  # the operator's pre-emption and abort are steps of the model
    _active: dict[tuple[str, ...], frozenset[str]] = field(default_factory=dict, repr=False, compare=False)
    _storm_rows: dict[bool, Any] = field(default_factory=dict, repr=False, compare=False)  # StormModel's matrices
    _labels: dict[str, list[int]] = field(default_factory=dict, repr=False, compare=False)  # export.labels

    @property
    def n_states(self) -> int:
        return len(self.configs)

    @property
    def n_steps(self) -> int:
        return sum(len(s) for s in self.steps)

    def active_states(self, s: int) -> frozenset[str]:
        """The states active in configuration ``s``: its leaves and their ancestors, the root left out (kept per
        set of leaves, which a large model has few of)."""
        leaves = self.configs[s].leaves
        got = self._active.get(leaves)
        if got is None:
            states = self.mission.states
            got = self._active[leaves] = frozenset(a.path for leaf in leaves for a in states[leaf].ancestors()[1:])
        return got

    def finals(self) -> list[int]:
        return [i for i, c in enumerate(self.configs) if c.final]

    def outcomes(self) -> list[str]:
        """Every outcome the run can end with (those of the final states directly under the root, and those a
        composite can finish with that no ``done`` transition handles), in the order first declared."""
        return sorted({c.outcome for c in self.configs if c.outcome is not None})

    def timed_steps(self, s: int) -> list[Step]:
        """The steps configuration ``s`` has with the sensors lost (:attr:`Step.timed`); while an action can end,
        time does not pass there: its end comes (the model does not know an action's duration, so the time it
        takes is not counted)."""
        steps = [st for st in self.steps[s] if st.timed]
        if any(st.action_end for st in steps):
            steps = [st for st in steps if st.cause != TICK]
        return steps

    def path_to(self, goal: Iterable[int], start: int | None = None, *, timed_only: bool = False,
                avoid: Iterable[int] = ()) -> list[tuple[int, Step]] | None:
        """The shortest path (fewest steps) from ``start`` (default: the initial configuration) to one of
        ``goal``: ``[(from, step), …]``; ``timed_only``: only steps that need no guard and no event."""
        goals, blocked = set(goal), set(avoid)
        s0 = self.initial if start is None else start
        if s0 in goals:
            return []
        back: dict[int, tuple[int, Step]] = {}
        queue = deque([s0])
        seen = {s0}
        while queue:
            s = queue.popleft()
            for step in (self.timed_steps(s) if timed_only else self.steps[s]):
                n = step.target
                if n in seen or n in blocked:
                    continue
                seen.add(n)
                back[n] = (s, step)
                if n in goals:
                    out = []
                    while n != s0:
                        p, st = back[n]
                        out.append((p, st))
                        n = p
                    return out[::-1]
                queue.append(n)
        return None

    def reachable(self, start: int, *, timed_only: bool = False) -> set[int]:
        seen = {start}
        stack = [start]
        while stack:
            s = stack.pop()
            for step in (self.timed_steps(s) if timed_only else self.steps[s]):
                if step.target not in seen:
                    seen.add(step.target)
                    stack.append(step.target)
        return seen

    # -- a run's records as a path of the model ---------------------------------------------------------
    def path_of(self, records: Sequence[Mapping[str, Any]], outcome: str | None = None) -> list[int]:
        """The configurations a run passes through, from its ``transitions.jsonl`` records (as written).  An
        operator's pre-emption is taken only by a model built with ``operator=True``; the operator's other records
        and a property's violation are not firings, and the time between a ``hold`` and its ``resume`` does not
        count.  Between two records the model takes exactly the ticks of operating time that lie between their
        times.  ``outcome``: the run's, checked against the configuration it ends in when the machine ended it.
        Raises :class:`NotAPath` naming the first record the model cannot take."""
        recs = [r for r in records]
        if not recs:
            raise NotAPath("no records")
        first = recs[0]
        if first.get("cause") != START_CAUSE:
            raise NotAPath(f"record 1: the first record's cause is {first.get('cause')!r}, not 'start'")
        n0 = len(self.start_records)
        got0 = [(str(r.get("cause")), str(r.get("to"))) for r in recs[:n0]]
        if got0 != list(self.start_records):
            raise NotAPath(f"records 1-{n0}: the start writes {list(self.start_records)}, the run wrote {got0}")
        q = self.quantum

        def tick_of(t: Any) -> int:
            return int(math.floor(float(t) / q + 1e-6))

        current: dict[int, list[int]] = {self.initial: [self.initial]}  # configuration → one path to it
        k_prev = tick_of(recs[n0 - 1].get("t", 0.0))
        held, hold_from = 0.0, None  # time under operator hold so far (it does not count toward the timers)
        i = n0
        while i < len(recs):
            r = recs[i]
            cause = str(r.get("cause"))
            if cause == PROPERTY:  # a declared property's first violation: a record, not a firing
                i += 1
                continue
            if cause == OPERATOR and "to" not in r:  # hold, resume, pause, inject, abort: not a firing
                action = r.get("action")
                if action == "hold" and hold_from is None:
                    hold_from = float(r.get("t", 0.0))
                elif action == "resume" and hold_from is not None:
                    held += float(r.get("t", 0.0)) - hold_from
                    hold_from = None
                i += 1
                continue
            if cause == OPERATOR and not self.operator:
                raise NotAPath(f"record {i + 1}: an operator's pre-emption; this model has no operator "
                               "(build_model(operator=True))")
            k = tick_of(float(r.get("t", 0.0)) - held)
            ticks = k - k_prev
            if ticks < 0:
                raise NotAPath(f"record {i + 1}: time goes backwards")
            nxt: dict[int, list[int]] = {}
            best_len = 0
            for s, path in current.items():
                for s2, p2 in self._ticks(s, ticks, path):
                    for step in self.steps[s2]:
                        n = len(step.records)
                        if n == 0:  # a tick, the max time, an abort: no transition record
                            continue
                        got = [(str(x.get("cause")), str(x.get("to"))) for x in recs[i:i + n]]
                        if got != list(step.records) or not _same_transition(step, recs[i]):
                            continue
                        nxt.setdefault(step.target, p2 + [step.target])
                        best_len = n
            if not nxt:
                where = ", ".join(sorted({self.configs[s].describe() for s in current}))
                raise NotAPath(f"record {i + 1} ({cause} to {r.get('to')!r} at t = {r.get('t')}) cannot be taken "
                               f"{ticks} tick(s) of {q:g} s after the previous one from {where}")
            current = nxt
            k_prev = k
            i += best_len
        if outcome is not None:
            ended = [s for s in current if self.configs[s].outcome is not None]
            if ended and not any(self.configs[s].outcome == outcome for s in ended):
                raise NotAPath(f"the run ended {outcome!r}; the model ends this path "
                               f"{sorted({self.configs[s].outcome or '' for s in ended})}")
        return next(iter(current.values()))

    def _ticks(self, s: int, n: int, path: list[int]) -> list[tuple[int, list[int]]]:
        """The configurations ``n`` ticks after ``s`` with no firing in between (none: a timer falls due)."""
        for _ in range(n):
            tick = next((st for st in self.steps[s] if st.cause == TICK), None)
            if tick is None:
                return []
            s = tick.target
            path = path + [s]
        return [(s, path)]


def _same_transition(step: Step, record: Mapping[str, Any]) -> bool:
    """The record names the step's transition (by index) and event, where it names them."""
    idx = record.get("index")
    if step.transition is not None and idx is not None and int(idx) != step.transition:
        return False
    return not (step.event is not None and record.get("event") not in (None, step.event))


# -- exploring ------------------------------------------------------------------------------------------------
def _ms(seconds: float) -> int:
    return int(round(seconds * 1000.0))


def quantum_of(mission: CompiledMission, max_time: float | None = None) -> float:
    """The model's time step: the greatest common divisor of the mission's ``after`` values and the max time
    (to the millisecond); 1 s when it has none."""
    values = [_ms(t.after) for t in mission.transitions if isinstance(t, TimeoutTransition) and _ms(t.after) > 0]
    if max_time is not None and _ms(max_time) > 0:
        values.append(_ms(max_time))
    if not values:
        return 1.0
    return reduce(math.gcd, values) / 1000.0


class _Explorer:
    """The statechart's semantics on plain data (:mod:`taskflow.execution.statechart`, step for step)."""

    def __init__(self, mission: CompiledMission, max_time: float | None, operator: bool = False) -> None:
        self.m = mission
        self.operator = operator
        self.q = quantum_of(mission, max_time)
        self.qms = _ms(self.q)
        self.max_ticks = None if max_time is None else _ms(max_time) // self.qms
        self.states = mission.states
        self.order = {p: i for i, p in enumerate(mission.states)}
        # each state's ancestors, root first (StateNode.ancestors builds a list per call; a build asks ~400,000 times)
        self.anc: dict[str, tuple[StateNode, ...]] = {p: tuple(n.ancestors()) for p, n in mission.states.items()}
        caps: dict[tuple[str, bool], int] = {}
        for tr in mission.transitions:
            if isinstance(tr, TimeoutTransition):
                key = (tr.since.path, tr.since_first)
                caps[key] = max(caps.get(key, 0), _ms(tr.after) // self.qms)
            elif isinstance(tr, GuardTransition) and tr.dwell > 0.0:
                need = int(math.floor(_ms(tr.dwell) / self.qms + 1e-9))
                if need > 0:
                    key = (tr.source.path, False)
                    caps[key] = max(caps.get(key, 0), need)
        self.clocks = tuple(Clock(p, f, c) for (p, f), c in sorted(caps.items()))
        self.clock_index = {(c.state, c.first): i for i, c in enumerate(self.clocks)}
        self.loop_states = tuple(p for p, n in mission.states.items() if n.loop is not None)
        # a state a history resume can re-enter with its data kept: one with a history state at or above it
        self.resumable = {p: any(a.history for a in n.ancestors()[1:]) for p, n in mission.states.items()}
        self.loop_index = {p: i for i, p in enumerate(self.loop_states)}
        self.tables: dict[str, list[Transition]] = {
            p: [t for a in n.ancestors() for t in a.transitions if not isinstance(t, DoneTransition)]
            for p, n in mission.states.items() if n.is_leaf}
        world = mission.world_cls
        self.always_events = set(world.events) | set(mission.spec.events)
        self.action_events = {name: set(evs) for name, evs in world.actions.items()}
        self.params = mission.spec.parameters
        # memo tables (a build asks the same questions of configurations that differ only by their clocks):
        # the transitions that can fire from a set of active leaves, and a firing's effect on a configuration's
        # clock-free part (see :meth:`fire_from`)
        self._candidates: dict[tuple[str, ...], list[_Candidate]] = {}
        self._firings: dict[tuple[Any, ...], dict[int, _Firing]] = {}  # clock-free part → transition → effect
        self._tick_step = Step(TICK, -1, None, f"{self.q:g} s pass")

    # -- the working configuration (mutable while a step is computed) ----------------------------------------
    def thaw(self, c: Config) -> _Work:
        return _Work(list(c.leaves), list(c.clocks), dict(c.history), [list(x) for x in c.loops],
                     {p: dict(o) for p, o in c.regions}, c.outcome, c.mission_ticks, skipped=dict(c.skipped),
                     grace=c.grace)

    def freeze(self, w: _Work) -> Config:
        leaves = tuple(sorted(w.leaves, key=self.order.__getitem__))
        return Config(leaves, tuple(w.clocks), tuple(sorted(w.history.items())), tuple((a, b, k) for a, b, k in w.loops),
                      tuple(sorted((p, tuple(sorted(o.items()))) for p, o in w.regions.items())), w.outcome,
                      w.mission_ticks, tuple(w.skipped.items()), w.grace)

    def initial(self) -> tuple[Config, tuple[tuple[str, str], ...]]:
        w = _Work([], [-1] * len(self.clocks), {}, [[0, 0, 1] for _ in self.loop_states], {}, None, 0)
        root = self.m.root
        first = root.children[str(root.initial)]
        self.go(w, first.entry_point(), START_CAUSE, resume=False, keep=0)
        return self.freeze(w), tuple(w.records)

    # -- the configuration's structure ------------------------------------------------------------------------
    def active_under(self, w: _Work, node: StateNode) -> str:
        prefix = node.path + "."
        return next(p for p in sorted(w.leaves, key=self.order.__getitem__) if p.startswith(prefix) or p == node.path)

    def resume_point(self, w: _Work, node: StateNode) -> str:
        leaf = self.states[self.active_under(w, node)]
        for a in self.anc[leaf.path]:
            if a.parallel and a.depth > node.depth:
                return a.path
        return leaf.path

    def is_active(self, w: _Work, node: StateNode) -> bool:
        prefix = node.path + "."
        return any(p.startswith(prefix) for p in w.leaves)

    def destination(self, w: _Work, target: StateNode, resume: bool, keep: int) -> tuple[StateNode, bool]:
        if target.children and target.history and resume:
            if keep < target.depth and self.is_active(w, target):
                point = self.states[self.resume_point(w, target)]
                if point.final:
                    return target.entry_point(), False
                return point, True
            last = w.history.get(target.path)
            if last is not None:
                return self.states[last], True
        return target.entry_point(), False

    # -- entering and leaving ---------------------------------------------------------------------------------
    def go(self, w: _Work, dest: StateNode, cause: str, resume: bool, keep: int) -> None:
        kept = self.anc[dest.path][keep]  # the domain: it and its ancestors stay active
        prefix = kept.path + "." if kept.path else ""
        under = [p for p in w.leaves if p.startswith(prefix)] if prefix else list(w.leaves)
        exited: set[str] = set()
        for leaf in under:
            for a in self.anc[leaf]:
                if a.depth > keep:
                    exited.add(a.path)
        for path in exited:  # exits see the configuration before the change
            node = self.states[path]
            if node.history:
                w.history[path] = self.resume_point(w, node)
        for path in exited:
            self._stop_entry_clock(w, path)
            self._drop_dead(w, path, exited)
        gone = set(under)
        w.leaves = [p for p in w.leaves if p not in gone]
        chain = self.anc[dest.path][keep + 1:]
        for node in chain:
            self.enter(w, node, resume)
        if dest.parallel:
            self.enter_regions(w, dest, resume)
        elif dest.is_leaf:
            w.leaves.append(dest.path)
        w.records.append((cause, dest.path))
        if dest.final:
            self.finished(w, dest)

    def enter_regions(self, w: _Work, parallel: StateNode, resume: bool) -> None:
        for region in parallel.children.values():
            self.enter(w, region, resume)
            n = region
            while n.children and not n.parallel:
                n = n.initial_child()
                self.enter(w, n, resume)
            if n.parallel:
                self.enter_regions(w, n, resume)
            else:
                w.leaves.append(n.path)

    def enter(self, w: _Work, node: StateNode, resuming: bool) -> None:
        w.entered.append(node.path)
        i = self.clock_index.get((node.path, False))
        if i is not None:
            w.clocks[i] = 0
        j = self.clock_index.get((node.path, True))
        if j is not None:
            w.started.add(j)
            if w.clocks[j] < 0:
                w.clocks[j] = 0
        if not resuming and node.children:
            self.forget_first_entries(w, node)
        if node.loop is not None and not resuming:
            w.loops[self.loop_index[node.path]] = [0, 0, 1]
        if node.parallel:
            w.regions.pop(node.path, None)
        if (node.loop is not None or node.parallel) and not resuming:
            w.skipped.pop(node.path, None)

    def forget_first_entries(self, w: _Work, node: StateNode) -> None:
        prefix = node.path + "."
        for k, c in enumerate(self.clocks):
            if c.first and c.state.startswith(prefix):
                w.clocks[k] = -1

    def _drop_dead(self, w: _Work, path: str, exited: set[str]) -> None:
        """Forget what a state left for good holds that nothing can read again: without a history state at or
        above it, its loop counters are reset and (its parent left too) its first-entry clock is forgotten before
        it is next entered, and a parallel state's finished regions are cleared on every entry.  Same behaviour,
        fewer configurations (the engine keeps the stale values, unread)."""
        node = self.states[path]
        if node.parallel:
            w.regions.pop(path, None)
        if self.resumable[path]:
            return
        if node.loop is not None:
            w.loops[self.loop_index[path]] = [0, 0, 1]
        j = self.clock_index.get((path, True))
        if j is not None and node.parent is not None and node.parent.path in exited:
            w.clocks[j] = -1

    def _stop_entry_clock(self, w: _Work, path: str) -> None:
        i = self.clock_index.get((path, False))
        if i is not None:
            w.clocks[i] = -1

    # -- firing and finishing ---------------------------------------------------------------------------------
    def fire(self, w: _Work, tr: Transition, cause: str) -> None:
        leaf, resumed = self.destination(w, tr.target, tr.resume, tr.domain_depth)
        self.go(w, leaf, cause, resume=resumed, keep=tr.domain_depth)

    def finished(self, w: _Work, leaf: StateNode) -> None:
        parent = leaf.parent
        outcome = leaf.final or "succeeded"
        if parent is not None and parent.owns is not None:
            self.region_finished(w, parent, outcome)
            return
        if parent is None or parent.parent is None:
            self.end(w, outcome)
            return
        if parent.loop is not None:
            loop = parent.loop
            li = self.loop_index[parent.path]
            item, succeeded, attempt = w.loops[li]
            n = len(self.params[loop.items])
            if outcome != "succeeded" and loop.retries_after(leaf, attempt):
                w.loops[li] = [item, succeeded, attempt + 1]
                self.forget_first_entries(w, parent)
                self.go(w, parent.entry_point(), RETRY, resume=False, keep=parent.depth)
                return
            if outcome == "succeeded":
                succeeded += 1
            w.loops[li] = [item, succeeded, 1]
            if outcome == "succeeded" or loop.on_failure == "continue":
                if item + 1 < n:
                    w.loops[li] = [item + 1, succeeded, 1]
                    self.forget_first_entries(w, parent)
                    self.go(w, parent.entry_point(), NEXT_ITEM, resume=False, keep=parent.depth)
                    return
                outcome, _ = loop_verdict(loop, succeeded, n)
        self.complete(w, parent, outcome)

    def region_finished(self, w: _Work, region: StateNode, outcome: str) -> None:
        parallel = region.parent
        assert parallel is not None
        finished = w.regions.setdefault(parallel.path, {})
        finished[region.name] = outcome
        result = parallel_outcome(parallel, finished)
        if result is not None:
            self.complete(w, parallel, result)

    def end(self, w: _Work, outcome: str) -> None:
        """The run ends with ``outcome`` — a ``succeeded`` one yields to the first rule an operator left that does
        not (:func:`taskflow.execution.outcomes.end_verdict`)."""
        if outcome == "succeeded":
            outcome = next((v for v in w.skipped.values() if v != "succeeded"), outcome)
        w.outcome = outcome

    def complete(self, w: _Work, node: StateNode, outcome: str) -> None:
        w.skipped.pop(node.path, None)
        for tr in node.transitions:
            if isinstance(tr, DoneTransition) and tr.handles(outcome):
                leaf, resumed = self.destination(w, tr.target, tr.resume, tr.domain_depth)
                self.go(w, leaf, DONE, resume=resumed, keep=tr.domain_depth)
                return
        self.end(w, outcome)

    def preempt(self, w: _Work, target: StateNode) -> None:
        """An operator's pre-emption to ``target`` (:mod:`taskflow.execution.preemption`): every active ``foreach``
        or parallel state it leaves for good records what its rule gives now."""
        leaf, resumed = self.destination(w, target, True, 0)
        staying = {a.path for entered in leaf.entry_leaves() for a in self.anc[entered.path]}
        rule_states: dict[str, StateNode] = {}
        for p in w.leaves:
            for a in self.anc[p]:
                if a.loop is not None or a.parallel:
                    rule_states.setdefault(a.path, a)
        for node in sorted(rule_states.values(), key=lambda n: n.depth):
            if node.path in staying:
                continue
            if node.loop is not None:
                succeeded = w.loops[self.loop_index[node.path]][1]
                verdict, _ = loop_verdict(node.loop, succeeded, len(self.params[node.loop.items]))
            else:
                verdict, _ = parallel_verdict(node, w.regions.get(node.path, {}))
            w.skipped[node.path] = verdict
        self.go(w, leaf, OPERATOR, resume=resumed, keep=0)

    # -- what can happen next ---------------------------------------------------------------------------------
    def events_possible(self, c: Config) -> tuple[set[str], set[str]]:
        """The events that can arrive in ``c``: (the world's, the mission's and the active tasks', the end events
        of the actions its active states run)."""
        return self._events_of(c.leaves)

    def _events_of(self, leaves: tuple[str, ...]) -> tuple[set[str], set[str]]:
        out = set(self.always_events)
        ends: set[str] = set()
        for leaf in leaves:
            node = self.states[leaf]
            if node.task_cls is not None and not node.final:
                out.update(node.task_cls.events)
            for a in self.anc[node.path]:
                if a.action is not None:
                    ends.update(self.action_events.get(a.action[0], ()))
        return out, ends

    def clock(self, c: Config, state: str, first: bool) -> int:
        i = self.clock_index.get((state, first))
        if i is None:
            return -1
        v = c.clocks[i]
        if first and v < 0:  # never entered since forgotten: the engine reads the last entry's clock
            return self.clock(c, state, False)
        return v

    def candidates(self, leaves: tuple[str, ...]) -> list[_Candidate]:
        """The transitions that may fire while ``leaves`` are active, innermost first and each once, with what
        decides whether one is enabled (memoized: it depends on the leaves only)."""
        out = self._candidates.get(leaves)
        if out is not None:
            return out
        out = []
        seen: set[int] = set()
        events: tuple[set[str], set[str]] | None = None
        for leaf in leaves:
            for tr in self.tables.get(leaf, ()):
                if tr.index in seen:
                    continue
                seen.add(tr.index)
                if isinstance(tr, TimeoutTransition):
                    out.append(_Candidate(tr, TIMEOUT, False, self._clock_slots(tr.since.path, tr.since_first),
                                          -(-_ms(tr.after) // self.qms)))
                elif isinstance(tr, GuardTransition):
                    need = int(math.floor(_ms(tr.dwell) / self.qms + 1e-9)) if tr.dwell > 0.0 else 0
                    if need > 0:
                        out.append(_Candidate(tr, GUARD, False, self._clock_slots(tr.source.path, False), need))
                    else:
                        out.append(_Candidate(tr, GUARD, False))
                elif isinstance(tr, EventTransition):
                    if events is None:
                        events = self._events_of(leaves)
                    if tr.event in events[1]:
                        out.append(_Candidate(tr, EVENT, True))
                    elif tr.event in events[0]:
                        out.append(_Candidate(tr, EVENT, False))
        self._candidates[leaves] = out
        return out

    def _clock_slots(self, state: str, first: bool) -> tuple[int, int]:
        """Where :meth:`clock` reads ``(state, first)``: the clock's index (-1: none) and, for a first-entry clock,
        the entry clock it falls back on while stopped."""
        i = self.clock_index.get((state, first), -1)
        return i, (self.clock_index.get((state, False), -1) if first and i >= 0 else -1)

    def enabled(self, c: Config) -> tuple[list[tuple[Transition, str, bool]], bool]:
        """The transitions that may fire now, with their cause and whether an action's end fires it, and whether a
        timer is due (no tick then)."""
        out: list[tuple[Transition, str, bool]] = []
        due = False
        clocks = c.clocks
        for cand in self.candidates(c.leaves):
            if cand.need < 0:
                out.append((cand.tr, cand.cause, cand.action_end))
                due = due or cand.cause == TIMEOUT
                continue
            i, fallback = cand.slots
            v = clocks[i] if i >= 0 else -1
            if v < 0 and fallback >= 0:  # a first-entry clock never started since forgotten: the entry clock's
                v = clocks[fallback]
            if v >= cand.need:
                out.append((cand.tr, cand.cause, cand.action_end))
                due = due or cand.cause == TIMEOUT
        return out, due

    def fire_from(self, c: Config, tr: Transition, cause: str,
                  memo: dict[int, _Firing] | None = None) -> tuple[Config, tuple[tuple[str, str], ...]]:
        """The configuration after ``tr`` fires in ``c`` (before :meth:`fired`'s grace), and the records it writes.

        What a firing does to everything but the clocks depends on that part alone, and what it does to a clock
        is one of: leave it, stop it (-1), restart it (0), start it unless it runs (first entry) — so it is
        computed once per clock-free part and transition, by firing with every clock running (a value no clock
        reaches: what stays is left or started, what is -1 stopped, what is 0 restarted), and applied to each
        configuration's clocks."""
        if memo is None:
            memo = self.firings_of(c)
        f = memo.get(tr.index)
        if f is None:
            w = self.thaw(replace(c, clocks=(_PROBE,) * len(self.clocks)))
            self.fire(w, tr, cause)
            effect = tuple((k, _STOP if v < 0 else _RESTART if v == 0 else _START) for k, v in enumerate(w.clocks)
                           if v != _PROBE or k in w.started)
            f = memo[tr.index] = _Firing(self.freeze(w), effect, tuple(w.records))
        clocks = list(c.clocks)
        for k, e in f.effect:
            if e == _RESTART or (e == _START and clocks[k] < 0):
                clocks[k] = 0
            elif e == _STOP:
                clocks[k] = -1
        n = f.config  # Config(...) directly: dataclasses.replace costs more than the firing's memo lookup
        return (Config(n.leaves, tuple(clocks), n.history, n.loops, n.regions, n.outcome, c.mission_ticks, n.skipped,
                       c.grace), f.records)

    def firings_of(self, c: Config) -> dict[int, _Firing]:
        """The memo of :meth:`fire_from` for the clock-free part of ``c``."""
        return self._firings.setdefault((c.leaves, c.history, c.loops, c.regions, c.outcome, c.skipped), {})

    def fired(self, c: Config) -> Config:
        """The configuration after a firing.  A timer due in it fires at the engine's next control period, not in
        the one that fired (one firing per region and period): when that period lies past the next tick, the tick
        comes first — a timer already due when its state is entered (``since: first_entry``, ``since: STATE``,
        ``after: 0 s``), or one a firing of the same period went before.  So one tick may pass (``grace``)."""
        if c.outcome is None and not c.grace and self.enabled(c)[1]:
            return replace(c, grace=True)
        return c

    def successors(self, c: Config) -> list[tuple[Step, Config]]:
        if c.outcome is not None:
            return []
        out: list[tuple[Step, Config]] = []
        enabled, due = self.enabled(c)
        memo = self.firings_of(c) if enabled else None
        for tr, cause, action_end in enabled:
            nc, records = self.fire_from(c, tr, cause, memo)
            event = tr.event if isinstance(tr, EventTransition) else None
            out.append((Step(cause, -1, tr.index, tr.label, event, records, action_end), self.fired(nc)))
        if self.operator:
            for path in self.m.outside_regions:
                w = self.thaw(c)
                self.preempt(w, self.states[path])
                out.append((Step(OPERATOR, -1, None, f"preempt --to {path}", None, tuple(w.records)),
                            self.fired(self.freeze(w))))
            w = self.thaw(c)
            w.outcome = "aborted"
            out.append((Step(OPERATOR, -1, None, "abort"), self.freeze(w)))
        if self.max_ticks is not None and c.mission_ticks >= self.max_ticks:
            w = self.thaw(c)
            w.outcome = "timeout"
            out.append((Step(MAX_TIME, -1, None, f"max_time {self.max_ticks * self.q:g} s"), self.freeze(w)))
        elif not due or c.grace:
            clocks = tuple(v if v < 0 else min(v + 1, clk.cap) for v, clk in zip(c.clocks, self.clocks, strict=True))
            ticks = c.mission_ticks if self.max_ticks is None else min(c.mission_ticks + 1, self.max_ticks)
            out.append((self._tick_step, Config(c.leaves, clocks, c.history, c.loops, c.regions, c.outcome, ticks,
                                                c.skipped, False)))
        return out


@dataclass(frozen=True)
class _Candidate:
    """A transition that may fire from a set of active leaves: it is enabled once clock ``slots`` (index, the
    entry clock a stopped first-entry clock falls back on; -1: none) has run ``need`` ticks (a stopped clock never
    has; ``need`` -1: always enabled)."""

    tr: Transition
    cause: str
    action_end: bool
    slots: tuple[int, int] = (-1, -1)
    need: int = -1


@dataclass(frozen=True)
class _Firing:
    """A firing's effect on a clock-free part (:meth:`_Explorer.fire_from`): the configuration it gives (its clocks
    those of the probe), what it does to each clock it changes, the records it writes."""

    config: Config
    effect: tuple[tuple[int, int], ...]
    records: tuple[tuple[str, str], ...]


_PROBE = 1 << 30  # a running clock's value no model reaches (caps are the mission's timeouts in ticks)
_STOP, _RESTART, _START = 1, 2, 3  # what a firing does to a clock: -1; 0; 0 unless it runs


@dataclass
class _Work:
    leaves: list[str]
    clocks: list[int]
    history: dict[str, str]
    loops: list[list[int]]
    regions: dict[str, dict[str, str]]
    outcome: str | None
    mission_ticks: int
    records: list[tuple[str, str]] = field(default_factory=list)
    entered: list[str] = field(default_factory=list)  # the states the step entered, in order
    started: set[int] = field(default_factory=set)  # the first-entry clocks the step started unless running
    skipped: dict[str, str] = field(default_factory=dict)  # rule state → the verdict an operator left it with
    grace: bool = False


def entered_by(model: Model, source: int, step: Step) -> list[str]:
    """The states ``step`` enters when taken from configuration ``source`` (the start's: ``source`` -1)."""
    ex = _Explorer(model.mission, model.max_time, model.operator)
    if source < 0:
        w = _Work([], [-1] * len(ex.clocks), {}, [[0, 0, 1] for _ in ex.loop_states], {}, None, 0)
        root = model.mission.root
        ex.go(w, root.children[str(root.initial)].entry_point(), START_CAUSE, resume=False, keep=0)
        return w.entered
    w = ex.thaw(model.configs[source])
    if step.cause == OPERATOR and step.label.startswith("preempt --to "):
        ex.preempt(w, model.mission.states[step.label[len("preempt --to "):]])
        return w.entered
    if step.transition is None:
        return []
    ex.fire(w, model.mission.transitions[step.transition], step.cause)
    return w.entered


def build_model(mission: CompiledMission, max_time: float | None = None, *, operator: bool = False,
                budget: int = DEFAULT_BUDGET) -> Model:
    """Explore every configuration the machine of ``mission`` can reach (module docstring: what is kept and
    what is abstracted).  ``max_time``: the run ends with ``timeout`` after it (seconds).  ``operator``: an
    operator may pre-empt the run to any state outside the regions, or abort it, at any moment
    (``taskflow ctl preempt``; holds are not modelled: they only stop the clocks).  Raises
    :class:`StateBudgetExceeded` past ``budget`` configurations."""
    ex = _Explorer(mission, max_time, operator)
    c0, start_records = ex.initial()
    model = Model(mission, ex.q, ex.clocks, ex.loop_states, start_records=start_records, max_time=max_time,
                  operator=operator)
    index: dict[Config, int] = {c0: 0}
    model.configs.append(c0)
    model.steps.append([])
    queue = deque([0])
    while queue:
        s = queue.popleft()
        steps: list[Step] = []
        for step, nc in ex.successors(model.configs[s]):
            j = index.get(nc)
            if j is None:
                if len(model.configs) >= budget:
                    raise StateBudgetExceeded(f"{mission.file}: the model has more than {budget} configurations "
                                              f"(time step {ex.q:g} s)")
                j = index[nc] = len(model.configs)
                model.configs.append(nc)
                model.steps.append([])
                queue.append(j)
            steps.append(Step(step.cause, j, step.transition, step.label, step.event, step.records, step.action_end))
        model.steps[s] = steps
    return model
