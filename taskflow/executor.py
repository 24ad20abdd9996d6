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
from .shaping import activation
from .loader import CompiledMission, CompiledTransition, StateNode, resolve_refs

START = "__start__"


class _DotState(NestedState):
    separator = "."


class _Machine(HierarchicalMachine):
    state_cls = _DotState


blend_weight = activation
"""The papers' activation ``h(t)`` (quadcopter paper eq. 20), used by ``blend:``."""


@dataclass
class TransitionRecord:
    t: float
    source: str
    target: str
    trigger: str


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
        self._tables: dict[str, list[CompiledTransition]] = {
            leaf.path: [t for a in leaf.ancestors() for t in a.transitions if t.kind != "done"]
            for leaf in mission.states.values() if leaf.is_leaf
        }
        # per-leaf: a validated parameter model when the task's params hold no $reference
        self._static_params: dict[str, Any] = {}
        self._scoped: set[str] = {n.path for n in mission.states.values() if any(a.foreach for a in n.ancestors())}
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
            if a.foreach:
                lst = self.params[a.foreach[0]]
                out[a.foreach[1]] = lst[min(self.iteration.get(a.path, 0), len(lst) - 1)]
        return out

    # -- start -------------------------------------------------------------------------------------
    def start(self, t: float) -> None:
        self.t = t
        first = self.mission.root.children[self.mission.root.initial]  # type: ignore[index]
        self._go(first.initial_leaf(), None, "start", resume=False)

    # -- entering and leaving -----------------------------------------------------------------------------
    def _enter(self, node: StateNode) -> None:
        t = self.t
        self.entered_at[node.path] = t
        self.first_entered.setdefault(node.path, t)
        for tr in node.transitions:
            self.dwell_since.pop(tr.index, None)
        if not self._resuming and node.children:
            self._forget_first_entries(node)
        if node.foreach and not self._resuming:
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
                    if not _has_refs(node.task_params):
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

    def _go(self, leaf: StateNode, tr: CompiledTransition | None, trigger: str, resume: bool,
            domain: StateNode | None = None) -> None:
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
        rec = TransitionRecord(self.t, source, leaf.path, trigger)
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

    def fire(self, tr: CompiledTransition) -> None:
        leaf, resumed = self._destination(tr.target, tr.resume)
        if tr.blend > 0.0:
            self._blend = _Blend(self.t, tr.blend, self.last_command)
        label = f"{tr.source.path}: {tr.label}" + (" (resume)" if resumed else "")
        self._go(leaf, tr, label, resume=resumed, domain=_domain(tr.source, tr.target))

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
        if parent.foreach:
            lst_name, item_name, on_failure = parent.foreach
            lst = self.params[lst_name]
            i = self.iteration.get(parent.path, 0)
            self.iterations.append(IterationRecord(parent.path, i, lst[i], outcome,
                                                   self.iteration_start.get(parent.path, self.t), self.t,
                                                   self.world.ground_truth()))
            count = self.item_counts.setdefault(parent.path, ItemCount(required=parent.require, rule=parent.require_text))
            count.attempted += 1
            if outcome == "succeeded":
                count.succeeded += 1
                self.loop_succeeded[parent.path] = self.loop_succeeded.get(parent.path, 0) + 1
            if outcome == "succeeded" or on_failure == "continue":
                if i + 1 < len(lst):
                    self.iteration[parent.path] = i + 1
                    self.iteration_start[parent.path] = self.t
                    self._forget_first_entries(parent)
                    # a new item enters the sub-machine afresh (no history, nested loops restart)
                    self._go(parent.initial_leaf(), None, f"{parent.path}: next {item_name} ({i + 2}/{len(lst)})",
                             resume=False)
                    return
                # the last item: the loop's own success rule decides
                done = self.loop_succeeded.get(parent.path, 0)
                outcome = "succeeded" if done >= parent.require else "failed"
                if outcome == "failed":
                    self.loop_failures.append(f"{parent.path!r} finished failed: {done} of {len(lst)} items "
                                              f"succeeded, its rule requires {parent.require} ({parent.require_text})")
        self._complete(parent, outcome)

    def _complete(self, node: StateNode, outcome: str) -> None:
        for tr in node.transitions:
            if tr.kind == "done" and (tr.done is True or tr.done == outcome):
                leaf, resumed = self._destination(tr.target, tr.resume)
                self._go(leaf, tr, f"{node.path}: {tr.label} ({outcome})", resume=resumed,
                         domain=_domain(tr.source, tr.target))
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

    def check(self, t: float, metrics: dict[str, float], events: Collection[str]) -> CompiledTransition | None:
        """Evaluate the active leaf's table; fire the first transition that holds."""
        if self.leaf is None or self.outcome is not None:
            return None
        entered = self.entered_at
        table = self._tables[self.leaf.path]
        for i, tr in enumerate(table):
            kind = tr.kind
            if kind == "when":
                if tr.predicate(metrics):  # type: ignore[misc]
                    if tr.dwell > 0.0:
                        since = self.dwell_since.setdefault(tr.index, t)
                        if t - since + 1e-9 < tr.dwell:
                            continue
                    return self._fire_from(table, i, metrics)
                if tr.dwell > 0.0:
                    self.dwell_since.pop(tr.index, None)
            elif kind == "on":
                if tr.event in events and (tr.predicate is None or tr.predicate(metrics)):
                    return self._fire_from(table, i, metrics)
            elif kind == "after":
                since = (self.first_entered if tr.since_first else entered)[tr.since.path]  # type: ignore[union-attr]
                if t - since + 1e-9 >= tr.after:
                    return self._fire_from(table, i, metrics)
        return None

    def _fire_from(self, table: list[CompiledTransition], i: int, metrics: dict[str, float]) -> CompiledTransition:
        """Fire ``table[i]``; dwell timers of the guards not evaluated this tick still see this tick's
        metrics (a break in their condition must not go unnoticed if their state stays active)."""
        for later in table[i + 1:]:
            if later.dwell > 0.0 and later.index in self.dwell_since and not later.predicate(metrics):  # type: ignore[misc]
                del self.dwell_since[later.index]
        self.fire(table[i])
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


def _has_refs(value: Any) -> bool:
    if isinstance(value, str):
        return value.startswith("$")
    if isinstance(value, dict):
        return any(_has_refs(v) for v in value.values())
    if isinstance(value, list):
        return any(_has_refs(v) for v in value)
    return False
