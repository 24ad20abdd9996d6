"""Runs a compiled machine tick by tick on `transitions`' HierarchicalMachine.

Guards are evaluated every tick in taskflow's own per-leaf tables (outermost state first, then in
the order written); `transitions` is called only when one fires, to exit and enter states through
its nested-state callbacks.  Time is whatever the caller passes in: the simulation clock.

Semantics in brief (docs/missions.md has the long form):

* a transition on a composite state is checked while any of its sub-states is active; outer
  transitions are checked before inner ones, so `target_lost` on a parent pre-empts its children;
* entering a composite enters its ``initial`` chain, or, with ``history: true`` and ``resume`` (the
  default), the leaf that was active when it was last left (deep history, foreach index included);
* reaching a final sub-state finishes its parent: a ``foreach`` parent moves to the next item (or
  stops on a failed/aborted iteration unless ``on_failure: continue``); otherwise the parent's
  matching ``done`` transition fires.  A final state directly under the root ends the run;
* ``blend: T`` on a transition mixes the last outgoing command into the incoming one with
  ``h(τ) = ½(1 − cos(π τ / T))`` for ``τ < T``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Collection

from transitions.extensions.nesting import HierarchicalMachine, NestedState

from .api import Command, Observation, Robot, Task, TaskContext, World
from .model import (CompiledMission, DoneTransition, EventTransition, GuardTransition, StateNode, TimeoutTransition,
                    Transition, has_refs, resolve_refs)
from .shaping import activation

START = "__start__"


class _DotState(NestedState):
    separator = "."


class _Machine(HierarchicalMachine):
    state_cls = _DotState


blend_weight = activation
"""The papers' activation ``h(t)`` (quadcopter paper eq. 20), used by ``blend:``."""


START_CAUSE, GUARD, TIMEOUT, EVENT, DONE, NEXT_ITEM = "start", "guard", "timeout", "event", "done", "next_item"
CAUSES = (START_CAUSE, GUARD, TIMEOUT, EVENT, DONE, NEXT_ITEM)


@dataclass
class TransitionRecord:
    """One change of the active leaf, with what caused it as fields (``transitions.jsonl`` holds them).

    ``cause`` is one of :data:`CAUSES`: ``start``; ``guard`` (a ``when`` held: ``metrics`` has the values
    of its metrics that tick), ``timeout`` (an ``after`` ran out), ``event`` (``event``; with a condition,
    ``metrics`` too), ``done`` (the sub-machine of ``state`` finished with ``outcome``) or ``next_item``
    (the loop ``state`` moved to item ``item`` after an item that ended ``outcome``).  ``state`` and
    ``label`` name the declaring state and the transition as written; ``index`` is the transition's index
    in the mission; ``resumed`` says a history state was resumed where it was left."""

    t: float
    source: str  # the leaf left ("__start__" for the first record)
    target: str  # the leaf entered
    cause: str
    state: str = ""
    label: str = ""
    index: int | None = None
    metrics: dict[str, float] | None = None
    event: str | None = None
    outcome: str | None = None
    item: int | None = None
    resumed: bool = False

    def as_dict(self) -> dict[str, Any]:
        """The JSON object of ``transitions.jsonl``: the fields that apply to this cause."""
        out: dict[str, Any] = {"t": round(self.t, 9), "from": self.source, "to": self.target, "cause": self.cause,
                               "state": self.state, "label": self.label}
        for key in ("index", "metrics", "event", "outcome", "item"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        if self.resumed:
            out["resumed"] = True
        return out


@dataclass
class ItemCount:
    """A foreach loop's items over a whole run: attempted, succeeded, and its success rule."""

    required: int  # per run of the loop
    rule: str  # as written: "all", "3", "75 %"
    attempted: int = 0
    succeeded: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {"attempted": self.attempted, "succeeded": self.succeeded, "failed": self.attempted - self.succeeded,
                "success_rate": self.succeeded / self.attempted if self.attempted else None,
                "required": self.required, "rule": self.rule}


@dataclass
class IterationRecord:
    state: str
    index: int
    item: Any
    outcome: str
    t_start: float
    t_end: float
    ground_truth: dict[str, float]


TaskFactory = Callable[[type[Task], TaskContext], Task | None]


class _Model:
    """The model object `transitions` sets ``state`` on."""

    state: str = START


@dataclass
class _Blend:
    t0: float
    duration: float
    old: Command


class Executor:
    """One run of a machine: feed it observations, it returns commands and fires transitions."""

    def __init__(self, mission: CompiledMission, world: World, robot: Robot, *,
                 task_factory: TaskFactory | None = None,
                 on_transition: Callable[[TransitionRecord], None] | None = None) -> None:
        self.mission, self.world, self.robot = mission, world, robot
        self.params = mission.spec.parameters
        self._dt = 1.0 / mission.spec.rate_hz
        self.task_factory = task_factory or (lambda cls, ctx: cls(ctx))
        self.on_transition = on_transition
        self.memory: dict[str, Any] = {}
        self.t = 0.0
        self.leaf: StateNode | None = None
        self.task: Task | None = None
        self.entered_at: dict[str, float] = {}
        # first entry of each state since its enclosing state was last entered afresh (`since: first_entry`)
        self.first_entered: dict[str, float] = {}
        self.dwell_since: dict[int, float] = {}
        self.iteration: dict[str, int] = {}
        self.iteration_start: dict[str, float] = {}
        self.history: dict[str, str] = {}
        self.iterations: list[IterationRecord] = []
        self.loop_failures: list[str] = []  # loops that finished failed by their success rule, for the reason
        self.loop_succeeded: dict[str, int] = {}  # foreach path → items succeeded in its current run
        self.item_counts: dict[str, ItemCount] = {}  # foreach path → items attempted / succeeded over the whole run
        self.step_timings: dict[str, float] = {}  # wall-clock seconds of the last task step's parts (never guarded on)
        self.path: list[str] = []  # leaves visited, in order
        self.time_in_state: dict[str, float] = {}
        self.transitions_fired: list[TransitionRecord] = []
        self.outcome: str | None = None
        self.reason: str = ""
        self.last_command: Command = robot.stop_command()
        self._stop = robot.stop_command()
        self._blend: _Blend | None = None
        self._running_actions: set[str] = set()
        self._resuming = False
        self._leaf_since = 0.0
        self._tables: dict[str, list[Transition]] = {
            leaf.path: [t for a in leaf.ancestors() for t in a.transitions if not isinstance(t, DoneTransition)]
            for leaf in mission.states.values() if leaf.is_leaf
        }
        # per-leaf: a validated parameter model when the task's params hold no $reference
        self._static_params: dict[str, Any] = {}
        self._scoped: set[str] = {n.path for n in mission.states.values() if any(a.loop for a in n.ancestors())}
        self._below: dict[str, list[str]] = {n.path: [d.path for d in n.walk() if d is not n]
                                             for n in mission.states.values() if n.children}
        self._model = _Model()
        self._machine = _Machine(model=self._model, states=[START, *self._state_dicts(mission.root)], initial=START,
                                 auto_transitions=True, send_event=False)
        for node in mission.states.values():
            st = self._machine.get_state(node.path)
            st.on_enter.append(lambda n=node: self._enter(n))
            st.on_exit.append(lambda n=node: self._exit(n))

    # -- building ------------------------------------------------------------------------------
    def _state_dicts(self, node: StateNode) -> list[dict[str, Any]]:
        out = []
        for child in node.children.values():
            d: dict[str, Any] = {"name": child.name}
            if child.children:
                d["children"] = self._state_dicts(child)
                d["initial"] = child.initial
            out.append(d)
        return out

    # -- state path --------------------------------------------------------------------------------
    @property
    def state(self) -> str:
        return self.leaf.path if self.leaf is not None else ""

    def items(self, node: StateNode) -> dict[str, Any]:
        """Current foreach items in scope at ``node``."""
        out: dict[str, Any] = {}
        if node.path not in self._scoped:
            return out
        for a in node.ancestors():
            if a.loop:
                lst = self.params[a.loop.items]
                out[a.loop.item] = lst[min(self.iteration.get(a.path, 0), len(lst) - 1)]
        return out

    # -- start -------------------------------------------------------------------------------------
    def start(self, t: float) -> None:
        self.t = t
        first = self.mission.root.children[self.mission.root.initial]  # type: ignore[index]
        self._go(first.initial_leaf(), START_CAUSE, resume=False)

    # -- entering and leaving -----------------------------------------------------------------------------
    def _enter(self, node: StateNode) -> None:
        t = self.t
        self.entered_at[node.path] = t
        self.first_entered.setdefault(node.path, t)
        for tr in node.transitions:
            self.dwell_since.pop(tr.index, None)
        if not self._resuming and node.children:
            self._forget_first_entries(node)
        if node.loop and not self._resuming:
            self.iteration[node.path] = 0
            self.iteration_start[node.path] = t
            self.loop_succeeded[node.path] = 0
        if node.action is not None:
            name, params = node.action
            self.world.start_action(name, resolve_refs(params, self.params, self.items(node)))
            self._running_actions.add(name)
        if node.is_leaf:
            self.leaf = node
            self._leaf_since = t
            self.path.append(node.path)
            self.task = None
            if node.task_cls is not None and not node.final:
                items = self.items(node)
                params = self._static_params.get(node.path)
                if params is None:
                    params = node.task_cls.Params.model_validate(resolve_refs(node.task_params, self.params, items))
                    if not has_refs(node.task_params):
                        self._static_params[node.path] = params
                ctx = TaskContext(t=t, params=params, profiles=node.profiles, memory=self.memory,
                                  robot=self.robot, items=items, dt=self._dt)
                self.task = self.task_factory(node.task_cls, ctx)

    def _exit(self, node: StateNode) -> None:
        if node.is_leaf:
            if self.task is not None:
                self.task.on_exit(self.t)
                self.task = None
            self.time_in_state[node.path] = self.time_in_state.get(node.path, 0.0) + (self.t - self._leaf_since)
        if node.action is not None and node.action[0] in self._running_actions:
            self.world.cancel_action(node.action[0])
            self._running_actions.discard(node.action[0])
        if node.history and self.leaf is not None:
            self.history[node.path] = self.leaf.path

    def _forget_first_entries(self, node: StateNode) -> None:
        """A fresh entry of ``node`` (or its next foreach item) starts its sub-states' `first_entry` clocks anew."""
        first = self.first_entered
        for path in self._below[node.path]:
            first.pop(path, None)

    def _destination(self, target: StateNode, resume: bool) -> tuple[StateNode, bool]:
        if target.children and target.history and resume and target.path in self.history:
            return self.mission.states[self.history[target.path]], True
        return target.initial_leaf(), False

    def _go(self, leaf: StateNode, cause: str, resume: bool, domain: StateNode | None = None,
            **why: Any) -> None:
        """Make ``leaf`` active.  States below ``domain`` on both sides are exited and entered (UML
        external semantics: a transition into its own source or an ancestor re-enters it); the
        ``transitions`` machine does the work unless its own least common ancestor would leave a
        state of the domain un-exited, in which case the callbacks run here and the machine's state
        is set to match."""
        source = self.state or START
        self._resuming = resume
        try:
            current = self.leaf
            if domain is not None and current is not None and _is_strict_ancestor(domain, _lca(current, leaf)):
                self._manual_switch(current, leaf, domain)
            else:
                self._model.trigger(f"to_{leaf.path}")  # type: ignore[attr-defined]
        finally:
            self._resuming = False
        rec = TransitionRecord(self.t, source, leaf.path, cause, resumed=resume, **why)
        self.transitions_fired.append(rec)
        if self.on_transition is not None:
            self.on_transition(rec)
        if leaf.final:
            self._finished(leaf)

    def _manual_switch(self, current: StateNode, leaf: StateNode, domain: StateNode) -> None:
        exiting = [n for n in reversed(current.ancestors()) if _is_strict_ancestor(domain, n)]
        entering = [n for n in leaf.ancestors() if _is_strict_ancestor(domain, n)]
        for n in exiting:
            self._exit(n)
        self._machine.set_state(leaf.path, model=self._model)
        for n in entering:
            self._enter(n)

    def fire(self, tr: Transition, metrics: dict[str, float] | None = None) -> None:
        """Fire ``tr`` (declared on an active state); ``metrics`` are the tick's, for the record."""
        leaf, resumed = self._destination(tr.target, tr.resume)
        if tr.blend > 0.0:
            self._blend = _Blend(self.t, tr.blend, self.last_command)
        kind = type(tr)
        why: dict[str, Any] = {"state": tr.source.path, "label": tr.label, "index": tr.index}
        guard = tr.guard if kind is GuardTransition or kind is EventTransition else None  # type: ignore[attr-defined]
        if guard is not None and metrics is not None:
            why["metrics"] = {m: metrics.get(m) for m in sorted(guard.metrics)}
        if kind is EventTransition:
            why["event"] = tr.event  # type: ignore[attr-defined]
        cause = GUARD if kind is GuardTransition else EVENT if kind is EventTransition else TIMEOUT
        self._go(leaf, cause, resume=resumed, domain=_domain(tr.source, tr.target), **why)

    def _finished(self, leaf: StateNode) -> None:
        """A final state was entered: finish its parent (foreach step, done transition or the run)."""
        parent = leaf.parent
        outcome = leaf.final or "succeeded"
        if parent is None or parent.parent is None:
            self.outcome = outcome
            desc = self.mission.description_of(leaf)
            why = f"reached final state {leaf.path!r}" + (f" ({desc})" if desc else "")
            if outcome != "succeeded" and self.loop_failures:
                why += "; " + "; ".join(self.loop_failures)
            self.reason = self.reason or why
            return
        if parent.loop:
            loop = parent.loop
            lst = self.params[loop.items]
            i = self.iteration.get(parent.path, 0)
            self.iterations.append(IterationRecord(parent.path, i, lst[i], outcome,
                                                   self.iteration_start.get(parent.path, self.t), self.t,
                                                   self.world.ground_truth()))
            count = self.item_counts.setdefault(parent.path, ItemCount(required=loop.required, rule=loop.rule))
            count.attempted += 1
            if outcome == "succeeded":
                count.succeeded += 1
                self.loop_succeeded[parent.path] = self.loop_succeeded.get(parent.path, 0) + 1
            if outcome == "succeeded" or loop.on_failure == "continue":
                if i + 1 < len(lst):
                    self.iteration[parent.path] = i + 1
                    self.iteration_start[parent.path] = self.t
                    self._forget_first_entries(parent)
                    # a new item enters the sub-machine afresh (no history, nested loops restart)
                    self._go(parent.initial_leaf(), NEXT_ITEM, resume=False, state=parent.path, outcome=outcome,
                             item=i + 1)
                    return
                # the last item: the loop's own success rule decides
                done = self.loop_succeeded.get(parent.path, 0)
                outcome = "succeeded" if done >= loop.required else "failed"
                if outcome == "failed":
                    self.loop_failures.append(f"{parent.path!r} finished failed: {done} of {len(lst)} items "
                                              f"succeeded, its rule requires {loop.required} ({loop.rule})")
        self._complete(parent, outcome)

    def _complete(self, node: StateNode, outcome: str) -> None:
        for tr in node.transitions:
            if isinstance(tr, DoneTransition) and tr.handles(outcome):
                leaf, resumed = self._destination(tr.target, tr.resume)
                self._go(leaf, DONE, resume=resumed, domain=_domain(tr.source, tr.target), state=node.path,
                         label=tr.label, index=tr.index, outcome=outcome)
                return
        # nobody handles this outcome: the run ends with it
        self.outcome = outcome
        self.reason = f"{node.path!r} finished {outcome} and no `done` transition handles it"

    # -- one tick -------------------------------------------------------------------------------------
    def tick(self, obs: Observation) -> tuple[Command, dict[str, float], Collection[str]]:
        """Step the active task, apply nothing, check guards; returns (command, metrics, events)."""
        t = self.t = obs.t
        events: Collection[str] = obs.events
        task = self.task
        if task is not None:
            res = task.step(obs)
            self.step_timings = res.timings
            command = res.command
            metrics = {**obs.metrics, **res.metrics} if obs.metrics else res.metrics
            if res.events:
                events = (*events, *res.events)
        else:
            command = self._stop
            metrics = obs.metrics
        if self._blend is not None:
            command = self._blended(command, t)
        self.last_command = command
        self.check(t, metrics, events)
        return command, metrics, events

    def _blended(self, command: Command, t: float) -> Command:
        b = self._blend
        assert b is not None
        h = blend_weight(t - b.t0, b.duration)
        if h >= 1.0:
            self._blend = None
            return command
        return {k: h * v + (1.0 - h) * b.old[k] if k in b.old else v for k, v in command.items()}

    def check(self, t: float, metrics: dict[str, float], events: Collection[str]) -> Transition | None:
        """Evaluate the active leaf's table; fire the first transition that holds."""
        if self.leaf is None or self.outcome is not None:
            return None
        entered = self.entered_at
        table = self._tables[self.leaf.path]
        for i, tr in enumerate(table):
            kind = type(tr)
            if kind is GuardTransition:
                if tr.predicate(metrics):  # type: ignore[attr-defined]
                    if tr.dwell > 0.0:  # type: ignore[attr-defined]
                        since = self.dwell_since.setdefault(tr.index, t)
                        if t - since + 1e-9 < tr.dwell:  # type: ignore[attr-defined]
                            continue
                    return self._fire_from(table, i, metrics)
                if tr.dwell > 0.0:  # type: ignore[attr-defined]
                    self.dwell_since.pop(tr.index, None)
            elif kind is EventTransition:
                if tr.event in events and (tr.predicate is None or tr.predicate(metrics)):  # type: ignore[attr-defined]
                    return self._fire_from(table, i, metrics)
            elif kind is TimeoutTransition:
                clocks = self.first_entered if tr.since_first else entered  # type: ignore[attr-defined]
                if t - clocks[tr.since.path] + 1e-9 >= tr.after:  # type: ignore[attr-defined]
                    return self._fire_from(table, i, metrics)
        return None

    def _fire_from(self, table: list[Transition], i: int, metrics: dict[str, float]) -> Transition:
        """Fire ``table[i]``; dwell timers of the guards not evaluated this tick still see this tick's
        metrics (a break in their condition must not go unnoticed if their state stays active)."""
        for later in table[i + 1:]:
            if (type(later) is GuardTransition and later.dwell > 0.0 and later.index in self.dwell_since  # type: ignore[attr-defined]
                    and not later.predicate(metrics)):  # type: ignore[attr-defined]
                del self.dwell_since[later.index]
        self.fire(table[i], metrics)
        return table[i]

    def close(self, t: float) -> None:
        """Account the time of the leaf still active at the end."""
        self.t = t
        if self.leaf is not None:
            self.time_in_state[self.leaf.path] = self.time_in_state.get(self.leaf.path, 0.0) + (t - self._leaf_since)
            self._leaf_since = t
        for name in list(self._running_actions):
            self.world.cancel_action(name)
        self._running_actions.clear()


def _lca(a: StateNode, b: StateNode) -> StateNode:
    """Deepest common ancestor-or-self of two states."""
    pa = a.ancestors()
    pb = b.ancestors()
    common = pa[0]
    for x, y in zip(pa, pb):
        if x is not y:
            break
        common = x
    return common


def _is_strict_ancestor(a: StateNode, b: StateNode) -> bool:
    n = b.parent
    while n is not None:
        if n is a:
            return True
        n = n.parent
    return False


def _domain(source: StateNode, target: StateNode) -> StateNode:
    """The state whose descendants a transition exits and enters: the common ancestor of source and
    target, or its parent when one of them contains the other (so that one is re-entered)."""
    common = _lca(source, target)
    if common is source or common is target:
        return common.parent if common.parent is not None else common
    return common
