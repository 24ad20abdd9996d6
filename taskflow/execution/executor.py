"""The tick: one control period of a run — step the active tasks, blend their commands, check the guards.

:class:`Executor` runs a compiled machine tick by tick on top of its semantics (:mod:`taskflow.execution.
statechart`: what firing a transition does; :mod:`taskflow.execution.preemption`: an operator's pre-emption).
A tick (:meth:`Executor.tick`, called by the runtime with the world's observation) steps the active leaf's
task, blends the command (:mod:`taskflow.execution.blends`) and checks the transitions that apply, in
per-leaf tables built once: the leaf's own and its ancestors', outermost first, then in the order written,
so ``target_lost`` on a parent pre-empts its children.  Each entry is a
:class:`~taskflow.execution.triggers.Trigger` that says whether it fires; the first that does fires and the
rest of its table is not checked.

With parallel regions, a tick steps every region's task, takes from each region's command only the parts it
``owns`` (the robot's stop command for the parts nobody drives) and checks every active leaf's table, each
shared transition once and at most one transition per region.
"""

from __future__ import annotations

from collections.abc import Callable, Collection

from taskflow.api import Command, Observation, Robot, World
from taskflow.execution.blends import Blends
from taskflow.execution.contexts import TaskFactory
from taskflow.execution.engine import START
from taskflow.execution.preemption import Preemptible
from taskflow.execution.records import CAUSES, ItemCount, IterationRecord, TransitionRecord
from taskflow.execution.triggers import Trigger
from taskflow.mission.model import CompiledMission, DoneTransition, StateNode, Transition

__all__ = ["CAUSES", "START", "Executor", "ItemCount", "IterationRecord", "TaskFactory", "TransitionRecord"]

Table = list[Trigger]
"""The transitions that apply while a leaf is active, in the order they are checked."""


class Executor(Preemptible):
    """One run of a machine: feed it observations, it returns commands and fires transitions."""

    def __init__(self, mission: CompiledMission, world: World, robot: Robot, *,
                 task_factory: TaskFactory | None = None,
                 on_transition: Callable[[TransitionRecord], None] | None = None) -> None:
        super().__init__(mission, world, robot, task_factory=task_factory, on_transition=on_transition)
        self.step_timings: dict[str, float] = {}  # wall-clock seconds of the last task step's parts (never guarded on)
        self.step_sensors: tuple[str, ...] | None = None  # the sensors the last task step asked the world to run
        self.last_command: Command = robot.stop_command()
        self._stop = robot.stop_command()
        self.blends = Blends()
        # per leaf: the transitions that apply while it is active (its own and its ancestors', outermost first)
        self._tables: dict[str, Table] = {
            leaf.path: [self.triggers[t.index] for a in leaf.ancestors() for t in a.transitions
                        if not isinstance(t, DoneTransition)]
            for leaf in mission.states.values() if leaf.is_leaf
        }
        # per leaf inside a parallel region: the command parts its task drives
        self._parts: dict[str, tuple[str, ...]] = {
            n.path: region.owns for n in mission.states.values()
            if n.is_leaf and (region := n.region) is not None and region.owns is not None}

    # -- one tick ---------------------------------------------------------------------------------------
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
        if self.blends.active:
            command = self.blends.apply(command, t)
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
        if self.blends.active:
            command = self.blends.apply(command, t)
        self.last_command = command
        if self.outcome is None:
            self._check_regions(t, metrics, events)
        return command, metrics, events

    # -- the statechart's hooks -------------------------------------------------------------------------
    def _firing(self, tr: Transition, region: StateNode | None) -> None:
        if tr.blend > 0.0:
            self.blends.start(self.t, tr.blend, self.last_command, region)

    def _preempting(self) -> None:
        self.blends.clear()

    # -- the guards -------------------------------------------------------------------------------------
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

    def _check_table(self, t: float, table: Table, metrics: dict[str, float], events: Collection[str],
                     seen: set[int] | None) -> Transition | None:
        held_s = self.held_s
        if seen is None:  # one active leaf: every transition of its table
            for i, trigger in enumerate(table):
                if trigger.ready(t, held_s, metrics, events):
                    return self._fire_from(table, i, metrics)
            return None
        for i, trigger in enumerate(table):
            if trigger.index in seen:
                continue
            seen.add(trigger.index)
            if trigger.ready(t, held_s, metrics, events):
                return self._fire_from(table, i, metrics)
        return None

    def _fire_from(self, table: Table, i: int, metrics: dict[str, float]) -> Transition:
        """Fire ``table[i]``; the triggers after it, not evaluated this tick, still see this tick's metrics
        (a break in a dwell guard's condition must not go unnoticed if its state stays active)."""
        for later in table[i + 1:]:
            later.missed(metrics)
        trigger = table[i]
        self.fire(trigger, metrics)
        return trigger.transition
