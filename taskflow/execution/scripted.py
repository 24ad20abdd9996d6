"""The scripted backend: a mission's machine, exactly as loaded and validated, with its world and tasks replaced by a
:class:`Script` — metric values as functions of simulated time and of the active state, events at given times,
asynchronous actions that finish after a delay.  :func:`drive` runs it; nothing is rendered or simulated.

:mod:`taskflow.testing` (the pytest plugin) re-exports it for mission tests; ``taskflow verify`` drives a
counterexample through it.  It needs no test dependency, so a normal install has it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from taskflow.api import Observation, Robot, StepResult, Task, TaskContext, World
from taskflow.execution.runtime import run_mission
from taskflow.execution.summary import RunResult
from taskflow.mission.model import CompiledMission

__all__ = ["MetricFn", "Script", "ScriptState", "ScriptedWorld", "drive"]


@dataclass
class ScriptState:
    """What a script's metric function sees each tick."""

    t: float
    state: str  # active leaf path
    time_in_state: float
    items: Mapping[str, Any]
    memory: dict[str, Any]  # the run's mission data, by key name


MetricFn = Callable[[ScriptState], Mapping[str, float]]


@dataclass
class Script:
    """A scripted stand-in for a world and its tasks.

    ``metrics(state)`` returns metric values each tick; ``events`` is a list of ``(time, name)``;
    ``actions`` maps an action name to ``(delay_s, event)`` (or a function of the action's params
    returning that pair) emitted after the action starts.
    """

    metrics: MetricFn = lambda s: {}
    events: Sequence[tuple[float, str]] = ()
    actions: Mapping[str, tuple[float, str] | Callable[[Mapping[str, Any]], tuple[float, str]]] = field(default_factory=dict)


class _NoParams(BaseModel):
    """A scripted world's parameters: none."""


class ScriptedWorld(World):
    """A :class:`World` whose observations come from a :class:`Script` (no simulator)."""

    name = "scripted"

    def __init__(self, robot: Robot, script: Script, mission: CompiledMission) -> None:
        super().__init__(robot, _NoParams(), 0)
        self.script = script
        self.mission = mission
        self.t = 0.0
        self._tick = 0
        self._dt = 1.0 / float(mission.spec.rate_hz)
        self._events = sorted(script.events)
        self._next_event = 0
        self._pending: list[tuple[float, str]] = []
        self.started: list[tuple[float, str, dict[str, Any]]] = []
        self.cancelled: list[tuple[float, str]] = []
        self.applied: list[dict[str, np.ndarray]] = []
        self.executor: Any = None

    def observe(self) -> Observation:
        t = self.t
        events: list[str] = []
        while self._next_event < len(self._events) and self._events[self._next_event][0] <= t + 1e-9:
            events.append(self._events[self._next_event][1])
            self._next_event += 1
        due = [e for e in self._pending if e[0] <= t + 1e-9]
        for e in due:
            self._pending.remove(e)
            events.append(e[1])
        metrics: dict[str, float] = {}
        ex = self.executor
        if ex is not None and ex.leaf is not None:
            st = ScriptState(t, ex.state, t - ex.entered_at(ex.leaf), ex.items(ex.leaf), ex.memory)
            metrics = {k: float(v) for k, v in self.script.metrics(st).items()}
        return Observation(t=t, events=tuple(events), metrics=metrics)

    def apply(self, command: dict[str, np.ndarray]) -> None:
        self.applied.append(command)

    def advance(self, dt: float) -> None:
        self._tick += 1
        self.t = self._tick * self._dt

    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        spec = self.script.actions.get(name)
        if spec is None:
            raise KeyError(f"the script has no action {name!r}")
        delay, event = spec(params) if callable(spec) else spec
        self.started.append((self.t, name, dict(params)))
        self._pending.append((self.t + delay, event))

    def cancel_action(self, name: str) -> None:
        self.cancelled.append((self.t, name))
        self._pending.clear()


class _IdleTask(Task[Any, Any]):
    """Stands in for every task under a script: holds the robot still, publishes nothing."""

    def __init__(self, ctx: TaskContext[Any, Any]) -> None:
        super().__init__(ctx)
        self._stop = ctx.robot.stop_command()

    def step(self, obs: Observation) -> StepResult:
        return StepResult(self._stop)


def drive(mission: CompiledMission, script: Script, *, max_time: float | None = None,
          out_dir: str | Path | None = None,
          on_world: Callable[[ScriptedWorld], None] | None = None, control: Any = None,
          operator: Sequence[Any] | None = None) -> RunResult:
    """Run the mission's machine against ``script`` (tasks replaced; nothing rendered or simulated).

    ``on_world`` receives the :class:`ScriptedWorld` (its ``started``, ``cancelled`` and
    ``applied`` lists record what the machine asked of the hardware); ``control`` and ``operator``
    are :func:`~taskflow.execution.runtime.run_mission`'s (operator endpoint and script, :mod:`taskflow.execution.control`)."""
    robot = mission.build_robot()
    world = ScriptedWorld(robot, script, mission)
    if on_world is not None:
        on_world(world)

    def factory(cls: type[Task[Any, Any]], ctx: TaskContext[Any, Any]) -> Task[Any, Any]:
        return _IdleTask(ctx)

    def attach(executor: Any) -> None:
        world.executor = executor

    return run_mission(mission, world=world, task_factory=factory, max_time=max_time, on_start=attach,
                       out_dir=out_dir, record=out_dir is not None, control=control, operator=operator)
