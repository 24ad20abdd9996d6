"""The statechart semantics: what it means for the machine to take a step — fire a transition, enter and
leave states, resume history, finish a composite, a ``foreach`` item, a region, the run — and what an
operator's pre-emption leaves undecided (:mod:`taskflow.execution.preemption` does the pre-emption).  The tick
(:mod:`taskflow.execution.executor`) decides *when* a transition fires; this module says what firing it does.

The engine (:mod:`taskflow.execution.engine`, `transitions`' HierarchicalMachine) holds the active
configuration and the per-state run-time data (entry clocks, history, foreach position) and runs the exit
and entry callbacks, which build tasks and start world actions.  Time is whatever the caller passes in:
the simulation clock.  In brief (docs/missions.md has the long form):

* entering a composite enters its ``initial`` chain, or, with ``history: true`` and ``resume`` (the
  default), the leaf that was active when it was last left (deep history, foreach index included) —
  resolved after the transition's exits, so re-entering an active history state resumes where it is;
* a transition exits and re-enters every state below its domain (UML external semantics: a transition
  into its own source or an ancestor re-enters it);
* reaching a final sub-state finishes its parent: a ``foreach`` parent runs the item again when its
  ``retry`` covers that final state and attempts remain, else moves to the next item (or stops on a
  failed/aborted iteration unless ``on_failure: continue``); otherwise the parent's matching ``done``
  transition fires.  A final state directly under the root ends the run;
* a region reaching a final state finishes; its parallel state finishes by its rule
  (:func:`~taskflow.execution.outcomes.parallel_outcome`);
* time under operator hold does not count: ``after`` timeouts and ``for`` dwell read the *operating clock*,
  sim time less :attr:`Statechart.held_s` (entry clocks stay sim times, as the records give them);
* an operator pre-emption that leaves a ``foreach`` or parallel state before its own success rule decided
  it records what that rule gives at that moment; a run that then reaches a ``succeeded`` final ends with
  the first such verdict that is not ``succeeded`` (:func:`~taskflow.execution.outcomes.end_verdict`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from taskflow.api import Robot, World
from taskflow.execution.contexts import AnyTask, Contexts, TaskFactory
from taskflow.execution.engine import START, MissionMachine, MissionState, leaf_paths
from taskflow.execution.outcomes import Preemption, SkippedRule, end_verdict, loop_verdict, parallel_outcome
from taskflow.execution.records import DONE, NEXT_ITEM, RETRY, START_CAUSE, ItemCount, IterationRecord, TransitionRecord
from taskflow.execution.triggers import Trigger, arm
from taskflow.mission.model import CompiledMission, DoneTransition, StateNode, Transition, resolve_refs

__all__ = ["Statechart"]


class Statechart:
    """One run of a compiled machine's semantics on the engine: its configuration, its tasks and its record."""

    def __init__(self, mission: CompiledMission, world: World, robot: Robot, *,
                 task_factory: TaskFactory | None = None,
                 on_transition: Callable[[TransitionRecord], None] | None = None) -> None:
        self.mission, self.world, self.robot = mission, world, robot
        self.params = mission.spec.parameters
        self.task_factory: TaskFactory = task_factory or (lambda cls, ctx: cls(ctx))
        self.on_transition = on_transition
        self.memory: dict[str, Any] = mission.data.initial_values()  # the run's mission data, by key name
        self.cache: dict[str, Any] = {}  # the run's memo of derived values (TaskContext.cache), not mission data
        self.t = 0.0
        self.task: AnyTask | None = None  # the task of the leaf entered last (the only one without parallel regions)
        self.tasks: dict[str, AnyTask] = {}  # active leaf → its task
        self._region_outcomes: dict[str, dict[str, str]] = {}  # parallel state → region → outcome it finished with
        self.held_s = 0.0  # sim seconds spent under operator hold so far (not counted by `after` and `for`)
        self.preemptions: list[Preemption] = []  # operator pre-emptions, in order
        self.skipped_rules: dict[str, SkippedRule] = {}  # composite path → the rule a pre-emption left undecided
        self.iterations: list[IterationRecord] = []
        self.loop_failures: list[str] = []  # loops that finished failed by their success rule, for the reason
        self.item_counts: dict[str, ItemCount] = {}  # foreach path → items attempted / succeeded over the whole run
        self.path: list[str] = []  # leaves visited, in order
        self.time_in_state: dict[str, float] = {}
        self.transitions_fired: list[TransitionRecord] = []
        self.outcome: str | None = None
        self.reason: str = ""
        self._running_actions: set[str] = set()
        self._resuming = False
        self._since: dict[str, float] = {}  # active leaf → sim time it was entered
        self.engine = MissionMachine(mission, self._enter, self._exit)
        self._states: dict[str, MissionState] = self.engine.by_path
        self._contexts = Contexts(mission, robot, self.memory, self.cache)
        # every transition but `done` armed for this run (taskflow.execution.triggers), by index; and per
        # state, those it declares (entering it starts their run-time state afresh)
        self.triggers: dict[int, Trigger] = {
            t.index: arm(t, self.memory, lambda n: self._states[n.path])
            for n in mission.states.values() for t in n.transitions if not isinstance(t, DoneTransition)}
        self._declared: dict[str, list[Trigger]] = {
            n.path: [self.triggers[t.index] for t in n.transitions if t.index in self.triggers]
            for n in mission.states.values()}
        self._scoped: set[str] = {n.path for n in mission.states.values() if any(a.loop for a in n.ancestors())}
        self._below: dict[str, list[MissionState]] = {
            n.path: [self._states[d.path] for d in n.walk() if d is not n] for n in mission.states.values() if n.children}

    # -- the configuration ------------------------------------------------------------------------------
    @property
    def leaf(self) -> StateNode | None:
        """The active leaf: the engine's state (None before the run starts; the first region's leaf while
        parallel regions are active — :attr:`leaves` has them all)."""
        st = self._states.get(self.engine.active)
        return st.node if st is not None else None

    @property
    def leaves(self) -> list[StateNode]:
        """Every active leaf: one, or one per active parallel region (in the order declared)."""
        return [n for p in self.engine.active_leaves() if p in self._states and (n := self._states[p].node) is not None]

    @property
    def state(self) -> str:
        """The active leaf's path; with parallel regions active, every region's leaf joined by ``|``."""
        path = self.engine.mission_model.state
        if type(path) is str:
            return "" if path == START else path
        return "|".join(leaf_paths(path))

    @property
    def history(self) -> dict[str, str]:
        """Composite with history → the leaf it was last left in (read from the engine's states)."""
        return {p: st.last_leaf for p, st in self._states.items() if st.last_leaf is not None}

    @property
    def iteration(self) -> dict[str, int]:
        """Foreach composite → index of its current item (read from the engine's states)."""
        return {p: st.item for p, st in self._states.items() if st.node is not None and st.node.loop}

    def items(self, node: StateNode) -> dict[str, Any]:
        """Current foreach items in scope at ``node``."""
        out: dict[str, Any] = {}
        if node.path not in self._scoped:
            return out
        for a in node.ancestors():
            if a.loop:
                lst = self.params[a.loop.items]
                out[a.loop.item] = lst[min(self._states[a.path].item, len(lst) - 1)]
        return out

    def entered_at(self, node: StateNode) -> float:
        """Sim time of ``node``'s last entry."""
        return self._states[node.path].entered_at

    def operating_since(self, node: StateNode, t: float, first: bool = False) -> float:
        """Seconds of operating time (sim time not under operator hold) from ``node``'s last entry — or,
        with ``first``, its first entry since its enclosing state was entered afresh — to sim time ``t``:
        what its ``after`` timeouts compare."""
        return self._states[node.path].operating_time(t, self.held_s, first)

    def hold_for(self, seconds: float) -> None:
        """The world went on for ``seconds`` of sim time under operator hold (the runtime's held ticks)."""
        self.held_s += seconds

    def start(self, t: float) -> None:
        self.t = t
        first = self.mission.root.children[str(self.mission.root.initial)]
        self._go(first.entry_point(), START_CAUSE, resume=False, keep=0)

    def close(self, t: float) -> None:
        """Account the time of the leaf still active at the end."""
        self.t = t
        for path, since in self._since.items():
            self.time_in_state[path] = self.time_in_state.get(path, 0.0) + (t - since)
            self._since[path] = t
        for name in list(self._running_actions):
            self.world.cancel_action(name)
        self._running_actions.clear()

    # -- entering and leaving (engine callbacks) ---------------------------------------------------------
    def _enter(self, node: StateNode) -> None:
        t = self.t
        st = self._states[node.path]
        st.entered_at = t
        st.held_at_entry = self.held_s
        if st.first_entered is None:
            st.first_entered = t
            st.held_at_first = self.held_s
        for trigger in self._declared[node.path]:
            trigger.reset()
        if not self._resuming and node.children:
            self._forget_first_entries(node)
        if node.loop and not self._resuming:
            st.item, st.item_started, st.items_succeeded, st.attempt, st.retried = 0, t, 0, 1, []
        if node.parallel:
            self._region_outcomes.pop(node.path, None)
        if (node.loop or node.parallel) and not self._resuming:
            self.skipped_rules.pop(node.path, None)  # a fresh run of it: its own rule decides again
        if node.action is not None:
            name, params = node.action
            self.world.start_action(name, resolve_refs(params, self.params, self.items(node)))
            self._running_actions.add(name)
        if node.is_leaf:
            self._since[node.path] = t
            self.path.append(node.path)
            self.task = None
            if node.task_cls is not None and not node.final:
                ctx = self._contexts.context(node, node.task_cls, t, self.items(node))
                self.task = self.task_factory(node.task_cls, ctx)
                if self.task is not None:
                    self.tasks[node.path] = self.task

    def _exit(self, node: StateNode) -> None:
        # exits run before the engine's state changes: its state is still the leaf being left
        if node.is_leaf:
            task = self.tasks.pop(node.path, None)
            if task is not None:
                task.on_exit(self.t)
                if task is self.task:
                    self.task = None
            since = self._since.pop(node.path, self.t)
            self.time_in_state[node.path] = self.time_in_state.get(node.path, 0.0) + (self.t - since)
        if node.action is not None and node.action[0] in self._running_actions:
            self.world.cancel_action(node.action[0])
            self._running_actions.discard(node.action[0])
        if node.history:
            self._states[node.path].last_leaf = self._resume_point(node)

    def _active_under(self, node: StateNode) -> str:
        """The first active leaf inside ``node`` (the engine's state has not changed yet during exits)."""
        prefix = node.path + "."
        return next(p for p in self.engine.active_leaves() if p.startswith(prefix) or p == node.path)

    def _resume_point(self, node: StateNode) -> str:
        """Where history re-enters ``node``: the active leaf inside it, or the outermost parallel state on the
        way there (its regions then start again at their initial states)."""
        leaf = self.mission.states[self._active_under(node)]
        for a in leaf.ancestors():
            if a.parallel and a.depth > node.depth:
                return a.path
        return leaf.path

    def _forget_first_entries(self, node: StateNode) -> None:
        """A fresh entry of ``node`` (or its next foreach item) starts its sub-states' `first_entry` clocks anew."""
        for st in self._below[node.path]:
            st.first_entered = None

    def _destination(self, target: StateNode, resume: bool, keep: int) -> tuple[StateNode, bool]:
        """The leaf (or parallel state) a transition into ``target`` that keeps ``keep`` levels active enters,
        and whether it resumes ``target``'s history.  UML order: the transition exits first, then resolves
        history — so when ``target`` is active and is exited (a self-transition, a transition to an
        enclosing state, an operator's pre-empt into the active state), it resumes where this exit leaves
        it, not where an earlier exit did."""
        if target.children and target.history and resume:
            if keep < target.depth and self._is_active(target):
                point = self.mission.states[self._resume_point(target)]
                if point.final:  # ``target`` has just finished (a `done` into it): it starts afresh
                    return target.entry_point(), False
                return point, True
            last = self._states[target.path].last_leaf
            if last is not None:
                return self.mission.states[last], True
        return target.entry_point(), False

    def _is_active(self, node: StateNode) -> bool:
        """Whether an active leaf lies inside ``node``."""
        prefix = node.path + "."
        return any(p.startswith(prefix) for p in self.engine.active_leaves())

    # -- firing ------------------------------------------------------------------------------------------
    def _go(self, leaf: StateNode, cause: str, resume: bool, keep: int, source: str | None = None, **why: Any) -> None:
        """Make ``leaf`` active (a leaf, or a parallel state: all its regions' initial leaves), exiting and
        re-entering every state below the first ``keep`` levels of its path.  ``source``: the leaf the record
        names as left (default: the whole active configuration)."""
        source = source or self.state or START
        self._resuming = resume
        try:
            self.engine.go(leaf.path, keep)
        finally:
            self._resuming = False
        rec = TransitionRecord(self.t, source, leaf.path, cause, resumed=resume, **why)
        self.transitions_fired.append(rec)
        if self.on_transition is not None:
            self.on_transition(rec)
        if leaf.final:
            self._finished(leaf)

    def fire(self, trigger: Trigger, metrics: dict[str, float] | None = None) -> None:
        """Fire ``trigger``'s transition (declared on an active state); ``metrics`` are the tick's, for the record."""
        tr = trigger.transition
        leaf, resumed = self._destination(tr.target, tr.resume, tr.domain_depth)
        region = tr.domain.region
        self._firing(tr, region)
        source = self._active_under(tr.source) if region is not None else None
        self._go(leaf, trigger.cause, resume=resumed, keep=tr.domain_depth, source=source, **trigger.why(metrics))

    def _firing(self, tr: Transition, region: StateNode | None) -> None:
        """``tr`` is about to fire in ``region`` (None: outside any): the tick's hook (it starts a blend)."""

    # -- finishing ---------------------------------------------------------------------------------------
    def _finished(self, leaf: StateNode) -> None:
        """A final state was entered: finish its parent (foreach step, done transition or the run)."""
        parent = leaf.parent
        outcome = leaf.final or "succeeded"
        if parent is not None and parent.owns is not None:
            self._region_finished(parent, outcome)
            return
        if parent is None or parent.parent is None:
            desc = self.mission.description_of(leaf)
            why = f"reached final state {leaf.path!r}" + (f" ({desc})" if desc else "")
            if outcome != "succeeded" and self.loop_failures:
                why += "; " + "; ".join(self.loop_failures)
            self._end(outcome, self.reason or why)
            return
        if parent.loop:
            loop = parent.loop
            st = self._states[parent.path]
            lst = self.params[loop.items]
            i = st.item
            count = self.item_counts.setdefault(parent.path, ItemCount(loop.required, loop.rule, retry=loop.retries))
            count.attempts += 1
            if outcome != "succeeded" and loop.retries_after(leaf, st.attempt):
                # the item runs again from the sub-machine's initial state, entered afresh as for a new
                # item (first-entry clocks, histories, nested loops); its index and the loop's counts stay
                st.attempt += 1
                st.retried.append(leaf.name)
                self._forget_first_entries(parent)
                self._go(parent.entry_point(), RETRY, resume=False, keep=parent.depth, source=leaf.path,
                         state=parent.path, outcome=outcome, item=i, attempt=st.attempt)
                return
            self.iterations.append(IterationRecord(
                parent.path, i, lst[i], outcome, st.item_started, self.t, self.world.ground_truth(),
                attempts=st.attempt if loop.retries else None, retried=tuple(st.retried)))
            count.attempted += 1
            count.retried += st.attempt > 1
            count.recovered += st.attempt > 1 and outcome == "succeeded"
            st.attempt, st.retried = 1, []
            if outcome == "succeeded":
                count.succeeded += 1
                st.items_succeeded += 1
            if outcome == "succeeded" or loop.on_failure == "continue":
                if i + 1 < len(lst):
                    st.item, st.item_started = i + 1, self.t
                    self._forget_first_entries(parent)
                    # a new item enters the sub-machine afresh (no history, nested loops restart); the
                    # loop state itself stays active
                    self._go(parent.entry_point(), NEXT_ITEM, resume=False, keep=parent.depth, state=parent.path,
                             outcome=outcome, item=i + 1)
                    return
                # the last item: the loop's own success rule decides
                outcome, why = loop_verdict(loop, st.items_succeeded, len(lst))
                if outcome == "failed":
                    self.loop_failures.append(f"{parent.path!r} finished failed: {why}")
        self._complete(parent, outcome)

    def _region_finished(self, region: StateNode, outcome: str) -> None:
        """A region reached a final state: its parallel state may finish (:func:`parallel_outcome`)."""
        parallel = region.parent
        assert parallel is not None  # a region is a parallel state's child
        finished = self._region_outcomes.setdefault(parallel.path, {})
        finished[region.name] = outcome
        result = parallel_outcome(parallel, finished)
        if result is not None:
            self._complete(parallel, result)

    def _complete(self, node: StateNode, outcome: str) -> None:
        self.skipped_rules.pop(node.path, None)  # its own rule decided
        for tr in node.transitions:
            if isinstance(tr, DoneTransition) and tr.handles(outcome):
                leaf, resumed = self._destination(tr.target, tr.resume, tr.domain_depth)
                self._go(leaf, DONE, resume=resumed, keep=tr.domain_depth, state=node.path, label=tr.label,
                         index=tr.index, outcome=outcome)
                return
        # nobody handles this outcome: the run ends with it
        self._end(outcome, f"{node.path!r} finished {outcome} and no `done` transition handles it")

    def _end(self, outcome: str, why: str) -> None:
        """The machine ended the run with ``outcome`` (:func:`end_verdict` weighs the skipped rules)."""
        self.outcome, self.reason = end_verdict(outcome, why, self.skipped_rules.values(), self.preemptions)
