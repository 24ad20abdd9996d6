"""Runs a compiled machine tick by tick on the engine (`transitions`' HierarchicalMachine, `engine.py`).

The engine holds the active configuration and the per-state run-time data (entry clocks, history,
foreach position); the executor adds what happens in a tick: the task step, the blend, and the guards,
evaluated in per-leaf tables (outermost state first, then in the order written).  The engine is asked
to change state only when one fires; it runs the exit and entry callbacks, which build tasks and
start world actions.  Time is whatever the caller passes in: the simulation clock.

Semantics in brief (docs/missions.md has the long form):

* a transition on a composite state is checked while any of its sub-states is active; outer
  transitions are checked before inner ones, so `target_lost` on a parent pre-empts its children;
* entering a composite enters its ``initial`` chain, or, with ``history: true`` and ``resume`` (the
  default), the leaf that was active when it was last left (deep history, foreach index included) —
  resolved after the transition's exits, so re-entering an active history state resumes where it is;
* reaching a final sub-state finishes its parent: a ``foreach`` parent moves to the next item (or
  stops on a failed/aborted iteration unless ``on_failure: continue``); otherwise the parent's
  matching ``done`` transition fires.  A final state directly under the root ends the run;
* ``blend: T`` on a transition mixes the last outgoing command into the incoming one with
  ``h(τ) = ½(1 − cos(π τ / T))`` for ``τ < T`` (inside a parallel region, only the parts that region
  owns, alongside a sibling region's blend);
* a state with ``regions`` runs them in parallel: one active leaf per region, each with its task; a
  tick steps every task, takes from each region's command only the parts it ``owns`` (the robot's stop
  command for the parts nobody drives) and checks every active leaf's table, each shared transition
  once and at most one transition per region.  A region reaching a final state finishes; the parallel
  state finishes by its ``outcome_map``, at once with the outcome of a region that did not succeed
  (pre-empting the others), or ``succeeded`` when every region has;
* time under operator hold does not count: ``after`` timeouts and ``for`` dwell read the *operating
  clock*, sim time less :attr:`Executor.held_s` (entry clocks stay sim times, as the records give them);
* an operator pre-emption that leaves a ``foreach`` or parallel state before its own success rule
  decided it records what that rule gives at that moment; a run that then reaches a ``succeeded`` final
  ends with the first such verdict that is not ``succeeded`` (:meth:`Executor.preempt`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

from taskflow.api import Command, Observation, Robot, Task, TaskContext, World
from taskflow.execution.data import DataAccess
from taskflow.execution.engine import START, MissionMachine, MissionState, leaf_paths
from taskflow.execution.records import (
    CAUSES,
    DONE,
    EVENT,
    GUARD,
    NEXT_ITEM,
    OPERATOR,
    START_CAUSE,
    TIMEOUT,
    ItemCount,
    IterationRecord,
    TransitionRecord,
)
from taskflow.mission.contracts import build_robot_params
from taskflow.mission.model import (
    CompiledMission,
    DoneTransition,
    EventTransition,
    GuardTransition,
    StateNode,
    TimeoutTransition,
    Transition,
    UnknownRef,
    data_refs,
    has_refs,
    resolve_refs,
)
from taskflow.shaping import activation

__all__ = ["CAUSES", "START", "Executor", "ItemCount", "IterationRecord", "TaskFactory", "TransitionRecord",
           "blend_weight"]


blend_weight = activation
"""The papers' activation ``h(t)`` (quadcopter paper eq. 20), used by ``blend:``."""


TaskFactory = Callable[[type[Task], TaskContext], Task | None]


def parallel_outcome(parallel: StateNode, finished: dict[str, str]) -> str | None:
    """How the parallel state finishes given the outcomes of the regions that have (region name → outcome):
    the first ``outcome_map`` rule whose regions all finished so, else a region's outcome other than
    ``succeeded``, else ``succeeded`` once every region has finished; None while it goes on."""
    result = next((out for out, need in parallel.outcome_map if all(finished.get(r) == o for r, o in need.items())),
                  None)
    if result is None:
        result = next((o for o in finished.values() if o != "succeeded"), None)
    if result is None and len(finished) == len(parallel.children):
        result = "succeeded"
    return result


@dataclass(frozen=True)
class Preemption:
    """One operator pre-emption: sim time ``t``, ``who`` asked, the state path it went ``to`` (None: the run
    was aborted) and the active configuration it left (``source``) — the summary's ``preempted`` list."""

    t: float
    who: str
    to: str | None
    source: str

    def as_dict(self) -> dict[str, Any]:
        return {"t": round(self.t, 9), "who": self.who, "to": self.to, "from": self.source}


@dataclass(frozen=True)
class SkippedRule:
    """A ``foreach`` or parallel state a pre-emption left before its success rule decided it: the outcome
    that rule gives at that moment (``verdict``) and why, in words, naming the pre-emption."""

    verdict: str
    why: str
    by: Preemption


@dataclass
class _Blend:
    """One blend in progress: ``old`` (the command when its transition fired) fades into the new one."""

    t0: float  # sim time the transition fired
    duration: float  # seconds (the transition's ``blend:``)
    old: Command
    parts: tuple[str, ...] | None = None  # the command parts blended (None: all)


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
        self.memory: dict[str, Any] = mission.data.initial_values()  # the run's mission data, by key name
        self.cache: dict[str, Any] = {}  # the run's memo of derived values (TaskContext.cache), not mission data
        self.t = 0.0
        self.task: Task | None = None  # the task of the leaf entered last (the only one without parallel regions)
        self.tasks: dict[str, Task] = {}  # active leaf → its task
        self._region_outcomes: dict[str, dict[str, str]] = {}  # parallel state → region → outcome it finished with
        self.dwell_since: dict[int, float] = {}  # dwell guard's index → operating-clock time its condition began
        self.held_s = 0.0  # sim seconds spent under operator hold so far (not counted by `after` and `for`)
        self.preemptions: list[Preemption] = []  # operator pre-emptions, in order
        self.skipped_rules: dict[str, SkippedRule] = {}  # composite path → the rule a pre-emption left undecided
        self.iterations: list[IterationRecord] = []
        self.loop_failures: list[str] = []  # loops that finished failed by their success rule, for the reason
        self.item_counts: dict[str, ItemCount] = {}  # foreach path → items attempted / succeeded over the whole run
        self.step_timings: dict[str, float] = {}  # wall-clock seconds of the last task step's parts (never guarded on)
        self.step_sensors: tuple[str, ...] | None = None  # the sensors the last task step asked the world to run
        self.path: list[str] = []  # leaves visited, in order
        self.time_in_state: dict[str, float] = {}
        self.transitions_fired: list[TransitionRecord] = []
        self.outcome: str | None = None
        self.reason: str = ""
        self.last_command: Command = robot.stop_command()
        self._stop = robot.stop_command()
        # blends in progress, by the region whose transition started them (None: a transition outside any
        # region, which blends every part); each parallel region blends only the parts it owns
        self._blends: dict[str | None, _Blend] = {}
        self._running_actions: set[str] = set()
        self._resuming = False
        self._since: dict[str, float] = {}  # active leaf → sim time it was entered
        self.engine = MissionMachine(mission, self._enter, self._exit)
        self._states: dict[str, MissionState] = self.engine.by_path
        # per leaf: the transitions that apply while it is active (its own and its ancestors', outermost
        # first), each with the engine state whose clock a timeout reads
        self._tables: dict[str, list[tuple[Transition, MissionState | None]]] = {
            leaf.path: [(t, self._clock_of(t)) for a in leaf.ancestors() for t in a.transitions
                        if not isinstance(t, DoneTransition)]
            for leaf in mission.states.values() if leaf.is_leaf
        }
        # per-leaf: a validated parameter model when the task's params hold no $reference
        self._static_params: dict[str, Any] = {}
        # per task class of the mission: its view of the robot's parameters (Task.robot_params), built once
        self._robot_params: dict[type[Task], Any] = {
            n.task_cls: build_robot_params(n.task_cls, robot) for n in mission.states.values() if n.task_cls}
        # per task class: its checked view of the mission data (Task.reads / Task.writes)
        self._data_access: dict[type[Task], DataAccess] = {
            n.task_cls: DataAccess(self.memory, n.task_cls) for n in mission.states.values() if n.task_cls}
        self._scoped: set[str] = {n.path for n in mission.states.values() if any(a.loop for a in n.ancestors())}
        self._below: dict[str, list[MissionState]] = {
            n.path: [self._states[d.path] for d in n.walk() if d is not n] for n in mission.states.values() if n.children}
        # per leaf inside a parallel region: the command parts its task drives
        self._parts: dict[str, tuple[str, ...]] = {
            n.path: n.region.owns for n in mission.states.values() if n.is_leaf and n.region is not None}  # type: ignore[misc]

    def _clock_of(self, tr: Transition) -> MissionState | None:
        return self._states[tr.since.path] if isinstance(tr, TimeoutTransition) else None

    # -- state path --------------------------------------------------------------------------------
    @property
    def leaf(self) -> StateNode | None:
        """The active leaf: the engine's state (None before the run starts; the first region's leaf while
        parallel regions are active — :attr:`leaves` has them all)."""
        st = self._states.get(self.engine.active)
        return st.node if st is not None else None

    @property
    def leaves(self) -> list[StateNode]:
        """Every active leaf: one, or one per active parallel region (in the order declared)."""
        return [self._states[p].node for p in self.engine.active_leaves() if p in self._states]  # type: ignore[misc]

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

    # -- start -------------------------------------------------------------------------------------
    def start(self, t: float) -> None:
        self.t = t
        first = self.mission.root.children[self.mission.root.initial]  # type: ignore[index]
        self._go(first.entry_point(), START_CAUSE, resume=False, keep=0)

    # -- entering and leaving (engine callbacks) ---------------------------------------------------
    def _enter(self, node: StateNode) -> None:
        t = self.t
        st = self._states[node.path]
        st.entered_at = t
        st.held_at_entry = self.held_s
        if st.first_entered is None:
            st.first_entered = t
            st.held_at_first = self.held_s
        for tr in node.transitions:
            self.dwell_since.pop(tr.index, None)
        if not self._resuming and node.children:
            self._forget_first_entries(node)
        if node.loop and not self._resuming:
            st.item, st.item_started, st.items_succeeded = 0, t, 0
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
                items = self.items(node)
                params = self._static_params.get(node.path)
                if params is None:
                    try:
                        raw = resolve_refs(node.task_params, self.params, items, data=self.memory)
                    except UnknownRef as exc:  # declared written on every path, but the writer did not write it
                        raise RuntimeError(f"state {node.path!r}: parameter ${exc.name} has no value yet (its "
                                           "writer declares it but did not write it)") from None
                    params = node.task_cls.Params.model_validate(raw)
                    if not has_refs(node.task_params):
                        self._static_params[node.path] = params
                ctx = TaskContext(t=t, params=params, profiles=node.profiles, memory=self._data_access[node.task_cls],
                                  robot=self.robot, items=items, dt=self._dt,
                                  robot_params=self._robot_params[node.task_cls], cache=self.cache)
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

    def _go(self, leaf: StateNode, cause: str, resume: bool, keep: int, source: str | None = None, **why: Any) -> None:
        """Make ``leaf`` active (a leaf, or a parallel state: all its regions' initial leaves), exiting and
        re-entering every state below the first ``keep`` levels of its path (UML external semantics: a
        transition into its own source or an ancestor re-enters it).  ``source``: the leaf the record names
        as left (default: the whole active configuration)."""
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

    def fire(self, tr: Transition, metrics: dict[str, float] | None = None) -> None:
        """Fire ``tr`` (declared on an active state); ``metrics`` are the tick's, for the record."""
        leaf, resumed = self._destination(tr.target, tr.resume, tr.domain_depth)
        region = tr.domain.region
        if tr.blend > 0.0:
            self._start_blend(tr.blend, region)
        kind = type(tr)
        why: dict[str, Any] = {"state": tr.source.path, "label": tr.label, "index": tr.index}
        guard = tr.guard if kind is GuardTransition or kind is EventTransition else None  # type: ignore[attr-defined]
        if guard is not None and metrics is not None:
            why["metrics"] = {m: metrics.get(m) for m in sorted(guard.metrics)}
        if kind is EventTransition:
            why["event"] = tr.event  # type: ignore[attr-defined]
        cause = GUARD if kind is GuardTransition else EVENT if kind is EventTransition else TIMEOUT
        source = self._active_under(tr.source) if region is not None else None
        self._go(leaf, cause, resume=resumed, keep=tr.domain_depth, source=source, **why)

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
            self.iterations.append(IterationRecord(parent.path, i, lst[i], outcome, st.item_started, self.t,
                                                   self.world.ground_truth()))
            count = self.item_counts.setdefault(parent.path, ItemCount(required=loop.required, rule=loop.rule))
            count.attempted += 1
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
                outcome = "succeeded" if st.items_succeeded >= loop.required else "failed"
                if outcome == "failed":
                    self.loop_failures.append(f"{parent.path!r} finished failed: {st.items_succeeded} of {len(lst)} "
                                              f"items succeeded, its rule requires {loop.required} ({loop.rule})")
        self._complete(parent, outcome)

    def _region_finished(self, region: StateNode, outcome: str) -> None:
        """A region reached a final state: its parallel state finishes by the first ``outcome_map`` rule whose
        regions have all finished so, else at once with a region's outcome other than ``succeeded``, else
        ``succeeded`` once every region has finished (SMACH's Concurrence, with the statechart rule)."""
        parallel = region.parent
        assert parallel is not None
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
        """The machine ended the run with ``outcome``: a ``succeeded`` one stands only if no rule a
        pre-emption skipped gives otherwise; the reason names every pre-emption."""
        bad = None
        if outcome == "succeeded":
            bad = next((s for s in self.skipped_rules.values() if s.verdict != "succeeded"), None)
            if bad is not None:
                outcome, why = bad.verdict, f"{why}, but the mission's success rule does not hold: {bad.why}"
        for p in self.preemptions:
            if p.to is not None and (bad is None or p is not bad.by):
                why += f"; pre-empted by {p.who} (operator) to {p.to!r} at t = {p.t:g} s"
        self.outcome, self.reason = outcome, why

    # -- one tick -------------------------------------------------------------------------------------
    def tick(self, obs: Observation) -> tuple[Command, dict[str, float], Collection[str]]:
        """Step the active task, apply nothing, check guards; returns (command, metrics, events)."""
        t = self.t = obs.t
        state = self.engine.mission_model.state
        if type(state) is not str:
            return self._tick_regions(obs)
        events: Collection[str] = obs.events
        task = self.task
        if task is not None:
            res = task.step(obs)
            self.step_timings = res.timings
            self.step_sensors = res.sensors
            command = res.command
            metrics = {**obs.metrics, **res.metrics} if obs.metrics else res.metrics
            if res.events:
                events = (*events, *res.events)
        else:
            command = self._stop
            metrics = obs.metrics
            self.step_sensors = None
        if self._blends:
            command = self._blended(command, t)
        self.last_command = command
        if self.outcome is None:
            table = self._tables.get(state)
            if table is not None:
                self._check_table(t, table, metrics, events, None)
        return command, metrics, events

    def _tick_regions(self, obs: Observation) -> tuple[Command, dict[str, float], Collection[str]]:
        """:meth:`tick` with parallel regions active: every region's task steps; each drives its parts."""
        t = obs.t
        command = dict(self._stop)
        metrics = dict(obs.metrics)
        events = list(obs.events)
        timings: dict[str, float] = {}
        sensors: set[str] = set()
        named = False
        for path in self.engine.active_leaves():
            task = self.tasks.get(path)
            if task is None:
                continue
            res = task.step(obs)
            parts = self._parts.get(path)
            for k in (parts if parts is not None else res.command):
                if k in res.command:
                    command[k] = res.command[k]
            metrics.update(res.metrics)
            events.extend(res.events)
            timings.update(res.timings)
            if res.sensors is not None:
                named = True
                sensors.update(res.sensors)
        self.step_timings = timings
        self.step_sensors = tuple(sorted(sensors)) if named else None
        if self._blends:
            command = self._blended(command, t)
        self.last_command = command
        if self.outcome is None:
            self._check_regions(t, metrics, events)
        return command, metrics, events

    def _start_blend(self, duration: float, region: StateNode | None) -> None:
        """A transition with ``blend:`` fired in ``region`` (None: outside any): fade the last command into the
        new one over ``duration``.  It replaces the blends it covers — every one for a transition outside any
        region (it starts from the command they shaped), its own region's and those nested in it otherwise —
        and leaves a sibling region's blend running on the parts that region owns."""
        if region is None:
            self._blends.clear()
        else:
            inner = region.path + "."
            for key in [k for k in self._blends if k is not None and (k == region.path or k.startswith(inner))]:
                del self._blends[key]
        self._blends[None if region is None else region.path] = _Blend(
            self.t, duration, self.last_command, region.owns if region is not None else None)

    def _blended(self, command: Command, t: float) -> Command:
        """``command`` with every blend in progress applied (in the order they started); a finished one is dropped."""
        for key, b in list(self._blends.items()):
            h = blend_weight(t - b.t0, b.duration)
            if h >= 1.0:
                del self._blends[key]
                continue
            command = {k: h * v + (1.0 - h) * b.old[k] if k in b.old and (b.parts is None or k in b.parts) else v
                       for k, v in command.items()}
        return command

    def check(self, t: float, metrics: dict[str, float], events: Collection[str]) -> Transition | None:
        """Evaluate the active leaf's table (every active leaf's, with parallel regions); fire the first
        transition that holds."""
        if self.outcome is not None:
            return None
        state = self.engine.mission_model.state
        if type(state) is not str:
            return self._check_regions(t, metrics, events)
        table = self._tables.get(state)
        if table is None:
            return None
        return self._check_table(t, table, metrics, events, None)

    def _check_regions(self, t: float, metrics: dict[str, float], events: Collection[str]) -> Transition | None:
        """Every active leaf's table, each transition once (those of the states the regions share are in
        every table), at most one firing per leaf; a leaf a firing has left is not checked."""
        seen: set[int] = set()
        fired = None
        leaves = self.engine.active_leaves()
        active = leaves  # re-read only after a firing changed the configuration
        for path in leaves:
            if self.outcome is not None:
                break
            if path not in active:
                continue
            table = self._tables.get(path)
            if table is not None:
                tr = self._check_table(t, table, metrics, events, seen)
                if tr is not None:
                    fired = tr
                    active = self.engine.active_leaves()
        return fired

    def _check_table(self, t: float, table: list[tuple[Transition, MissionState | None]], metrics: dict[str, float],
                     events: Collection[str], seen: set[int] | None) -> Transition | None:
        for i, (tr, clock) in enumerate(table):
            if seen is not None:
                if tr.index in seen:
                    continue
                seen.add(tr.index)
            kind = type(tr)
            if kind is GuardTransition:
                if tr.predicate(metrics, self.memory):  # type: ignore[attr-defined]
                    if tr.dwell > 0.0:  # type: ignore[attr-defined]
                        op = t - self.held_s  # the operating clock: time under hold does not count
                        since = self.dwell_since.setdefault(tr.index, op)
                        if op - since + 1e-9 < tr.dwell:  # type: ignore[attr-defined]
                            continue
                    return self._fire_from(table, i, metrics)
                if tr.dwell > 0.0:  # type: ignore[attr-defined]
                    self.dwell_since.pop(tr.index, None)
            elif kind is EventTransition:
                if tr.event in events and (tr.predicate is None or tr.predicate(metrics, self.memory)):  # type: ignore[attr-defined]
                    return self._fire_from(table, i, metrics)
            elif kind is TimeoutTransition:
                if clock.operating_time(t, self.held_s, tr.since_first) + 1e-9 >= tr.after:  # type: ignore[attr-defined,union-attr]
                    return self._fire_from(table, i, metrics)
        return None

    def _fire_from(self, table: list[tuple[Transition, MissionState | None]], i: int,
                   metrics: dict[str, float]) -> Transition:
        """Fire ``table[i]``; dwell timers of the guards not evaluated this tick still see this tick's
        metrics (a break in their condition must not go unnoticed if their state stays active)."""
        for later, _ in table[i + 1:]:
            if (type(later) is GuardTransition and later.dwell > 0.0 and later.index in self.dwell_since  # type: ignore[attr-defined]
                    and not later.predicate(metrics, self.memory)):  # type: ignore[attr-defined]
                del self.dwell_since[later.index]
        tr = table[i][0]
        self.fire(tr, metrics)
        return tr

    def close(self, t: float) -> None:
        """Account the time of the leaf still active at the end."""
        self.t = t
        for path, since in self._since.items():
            self.time_in_state[path] = self.time_in_state.get(path, 0.0) + (t - since)
            self._since[path] = t
        for name in list(self._running_actions):
            self.world.cancel_action(name)
        self._running_actions.clear()

    # -- operator (taskflow/operate/control.py) -----------------------------------------------------------------
    def preempt(self, target: str | None, who: str, t: float) -> None:
        """Operator pre-emption at sim time ``t``: leave every active state (their exits cancel running world
        actions) for the state path ``target`` — its initial leaf, or its history — recorded with cause
        ``operator``; or, with ``target=None``, end the run ``aborted`` (the runtime then stops the robot).

        Every active ``foreach`` or parallel state the pre-emption leaves for good (not the target nor on the
        way into it) has its success rule evaluated now (:meth:`_rule_verdict`); until that state is entered
        afresh or finishes by its own rule, a ``succeeded`` end of the run yields to the first verdict that is
        not (:meth:`_end`)."""
        self.t = t
        by = Preemption(t, who, target, self.state)
        self.preemptions.append(by)
        if target is None:
            self.outcome, self.reason = "aborted", f"pre-empted by {who} (operator)"
            return
        leaf, resumed = self._destination(self.mission.states[target], True, 0)
        staying = {a.path for entered in leaf.entry_leaves() for a in entered.ancestors()}
        for node in self._rule_states():
            if node.path not in staying:
                verdict, why = self._rule_verdict(node)
                self.skipped_rules[node.path] = SkippedRule(
                    verdict, f"{node.path!r} had not finished when {who} (operator) pre-empted the run to {target!r} "
                    f"at t = {t:g} s: {why}", by)
        self._blends.clear()
        self._go(leaf, OPERATOR, resume=resumed, keep=0, label=f"preempt --to {target}", who=who)

    def _rule_states(self) -> list[StateNode]:
        """The active ``foreach`` and parallel states (each once, outermost first)."""
        seen: dict[str, StateNode] = {}
        for leaf in self.leaves:
            for a in leaf.ancestors():
                if a.loop or a.parallel:
                    seen.setdefault(a.path, a)
        return sorted(seen.values(), key=lambda n: n.depth)

    def _rule_verdict(self, node: StateNode) -> tuple[str, str]:
        """What the success rule of the active ``foreach`` or parallel ``node`` gives now, and why: a loop
        ``succeeded`` if its items so far meet ``require``, else ``failed`` (as when its last item ends);
        a parallel state by its ``outcome_map`` with the unfinished regions counted ``aborted`` (how a
        region pre-empted mid-way ends), else the first region outcome that is not ``succeeded``."""
        if node.loop is not None:
            loop, st = node.loop, self._states[node.path]
            n = len(self.params[loop.items])
            ok = st.items_succeeded >= loop.required
            return ("succeeded" if ok else "failed",
                    f"{st.items_succeeded} of {n} items succeeded, its rule requires {loop.required} ({loop.rule})")
        finished = self._region_outcomes.get(node.path, {})
        result = parallel_outcome(node, {r: finished.get(r, "aborted") for r in node.children})
        assert result is not None  # every region has an outcome
        running = [r for r in node.children if r not in finished]
        return result, f"regions {', '.join(map(repr, running))} had not finished (counted aborted): {result}"

    def preempt_problem(self, target: str) -> str | None:
        """Why a pre-emption to ``target`` cannot be taken now, or None: a leaf it would enter reads, on
        entry, mission data this run has not written (its task's ``reads``, its ``$data`` parameters)."""
        leaf, _ = self._destination(self.mission.states[target], True, 0)
        data = self.mission.data
        for entered in leaf.entry_leaves():
            if entered.final or entered.task_cls is None:
                continue
            needed = [k.name for k in entered.task_cls.reads]
            needed += [name for name, _ in data_refs(entered.task_params) if name in data.keys]
            for key in needed:
                if key not in self.memory:
                    writers = [n.path for n in self.mission.leaves() if not n.final and n.task_cls is not None
                               and any(k.name == key for k in n.task_cls.writes)]
                    via = f" (entered as {entered.path!r})" if entered is not self.mission.states[target] else ""
                    return (f"preempt: {target!r}{via} reads mission data {key!r} on entry, which this run has "
                            f"not written yet — it is written by {', '.join(map(repr, writers)) or 'no state'}: "
                            "pre-empt to one of those first")
        return None
