"""Small registered robot/world/task used by the framework's own tests (no simulator).

``toy_point`` is a 1-D point moved by a velocity command (``toy_pair`` the same with a second command
part ``w``, for two regions that each own one); ``toy_line`` integrates it exactly and
emits ``target_lost`` / ``target_found`` at scheduled times; ``toy_goto`` is a P controller (it records
its targets and robot view in mission data); ``toy_mark`` holds still and writes where it is
(``toy.mark``, mission data), ``toy_return`` reads that mark and drives back to it.
They exist so the machine tests exercise real task and world code paths without PyBullet.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from taskflow.api import (
    MemoryKey,
    Observation,
    Robot,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
    World,
    instance,
    scalar,
    sequence,
)
from taskflow.registry import ROBOTS, TASKS, WORLDS


class ToyRobotParams(StrictModel):
    v_max: float = Field(1.0, gt=0)


class ToyPoint(Robot):
    Params = ToyRobotParams
    command_keys = {"v": 1}


class ToyPair(Robot):
    """``toy_point`` with a second command part ``w`` (``toy_line`` ignores it): two parallel regions can
    each own one part."""

    Params = ToyRobotParams
    command_keys = {"v": 1, "w": 1}


class ToyWheelParams(StrictModel):
    radius: float = 0.1


class ToyWheel(Robot):
    """A robot ``toy_goto`` cannot drive: its parameters have no ``v_max``."""

    Params = ToyWheelParams
    command_keys = {"v": 1}


class ToyWorldParams(StrictModel):
    start: float = 0.0
    lose_at: list[float] = []
    find_at: list[float] = []
    tool_time: float = 0.5
    tool_ok: bool = True
    noise: float = 0.0


class ToyLine(World):
    Params = ToyWorldParams
    events = ("target_lost", "target_found")
    metrics = {"visible": ""}
    ground_truth_keys = ("x",)
    actions = {"tool": ("tool_done", "tool_failed")}
    physics_hz = 100.0

    def reset(self) -> None:
        p = self.params
        self.x = p.start
        self.v = 0.0
        self.k = 0
        self.rng = np.random.default_rng(self.seed)
        self.action: tuple[float, str] | None = None
        self.visible = True
        self.pending: list[str] = []

    @property
    def t(self) -> float:
        return self.k / self.physics_hz

    def observe(self) -> Observation:
        ev = self.pending
        self.pending = []
        if self.action is not None and self.t >= self.action[0] - 1e-9:
            ev.append(self.action[1])
            self.action = None
        x = self.x + (self.rng.normal(0, self.params.noise) if self.params.noise else 0.0)
        return Observation(self.t, state={"x": x}, events=tuple(ev), metrics={"visible": float(self.visible)})

    def apply(self, command: Mapping[str, np.ndarray]) -> None:
        self.v = float(np.clip(command["v"][0], -self.robot.params.v_max, self.robot.params.v_max))

    def advance(self, dt: float) -> None:
        for _ in range(round(dt * self.physics_hz)):
            self.k += 1
            self.x += self.v / self.physics_hz
            for tl in self.params.lose_at:
                if abs(self.t - tl) < 0.5 / self.physics_hz:
                    self.visible = False
                    self.pending.append("target_lost")
            for tf in self.params.find_at:
                if abs(self.t - tf) < 0.5 / self.physics_hz:
                    self.visible = True
                    self.pending.append("target_found")

    def ground_truth(self) -> dict[str, float]:
        return {"x": self.x}

    def summary_metrics(self) -> dict[str, Any]:
        return {"final_x": self.x}

    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        ok = params.get("ok", self.params.tool_ok)
        self.action = (self.t + self.params.tool_time, "tool_done" if ok else "tool_failed")

    def cancel_action(self, name: str) -> None:
        self.action = None



class GainsModel(StrictModel):
    kp: float = Field(gt=0)


class GotoParams(StrictModel):
    target: float


class ToyLimits(StrictModel):
    v_max: float


ENTRIES: MemoryKey[list[float]] = MemoryKey("toy.entries", sequence(), doc="every toy_goto target, in entry order")
ROBOT_VIEW: MemoryKey[ToyLimits] = MemoryKey("toy.robot_params", instance(ToyLimits), output=False,
                                             doc="the last toy_goto's view of the robot parameters")
MARK: MemoryKey[float] = MemoryKey("toy.mark", scalar(), unit="m", doc="where toy_mark stood")


class ToyGoto(Task[GotoParams, ToyLimits]):
    Params = GotoParams
    slots = {"gains": GainsModel}
    robot_params = ToyLimits
    metrics = {"pos_error": "m", "feature_error": "px", "yaw_error": "rad"}
    events = ("arrived",)
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (ENTRIES, ROBOT_VIEW)

    def __init__(self, ctx: TaskContext[GotoParams, ToyLimits]) -> None:
        super().__init__(ctx)
        self.kp = ctx.profile("gains", GainsModel).kp
        self.target = ctx.params.target
        ENTRIES.setdefault(ctx.memory, []).append(self.target)
        ROBOT_VIEW.set(ctx.memory, ctx.robot_params)

    def step(self, obs: Observation) -> StepResult:
        e = self.target - obs.state["x"]
        return StepResult({"v": np.array([self.kp * e])},
                          {"pos_error": abs(e), "feature_error": 100 * abs(e), "yaw_error": 0.0})


class WatchParams(StrictModel):
    pass


class ToyWatch(Task[WatchParams, None]):
    """A monitor: publishes ``x_abs`` (|x|, m) and commands full reverse, which a region that owns no
    command part must never let reach the robot."""

    Params = WatchParams
    metrics = {"x_abs": "m"}

    def step(self, obs: Observation) -> StepResult:
        return StepResult({"v": np.array([-9.0])}, {"x_abs": abs(float(obs.state["x"]))})


class ToyMark(Task):
    """Holds still and writes its position as ``toy.mark`` on every step."""

    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (MARK,)

    def step(self, obs: Observation) -> StepResult:
        MARK.set(self.ctx.memory, float(obs.state["x"]))
        return StepResult({"v": np.zeros(1)})


class ToyReturn(Task[Any, ToyLimits]):
    """A P controller back to ``toy.mark`` (which must be written before its state: ``reads``)."""

    slots = {"gains": GainsModel}
    robot_params = ToyLimits
    metrics = {"pos_error": "m"}
    reads: ClassVar[tuple[MemoryKey[Any], ...]] = (MARK,)

    def __init__(self, ctx: TaskContext[Any, ToyLimits]) -> None:
        super().__init__(ctx)
        self.kp = ctx.profile("gains", GainsModel).kp
        self.target = MARK(ctx.memory)

    def step(self, obs: Observation) -> StepResult:
        e = self.target - obs.state["x"]
        return StepResult({"v": np.array([self.kp * e])}, {"pos_error": abs(e)})


# A mission of the toys for pre-emptions into a state that reads mission data (tests/execution/
# test_operator_semantics.py, tests/operate/test_control*.py): start at 0.3 → away to x = 1.0 → mark writes
# toy.mark → back (toy_return reads it) → done.
MARKED = """
mission: marked
robot: toy_point
world: {name: toy_line, params: {start: 0.3}}
rate_hz: 20
max_time: 20 s
machine:
  initial: away
  states:
    away:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: {kp: 2.0}}
      transitions: [{to: mark, when: "pos_error < 1 cm"}]
    mark:
      task: toy_mark
      transitions: [{to: back, after: 0.2 s}]
    back:
      task: toy_return
      bind: {gains: {kp: 2.0}}
      transitions: [{to: done, when: "pos_error < 1 cm"}]
    done: {final: succeeded}
"""


def register() -> None:
    for reg, name, cls in ((ROBOTS, "toy_point", ToyPoint), (ROBOTS, "toy_wheel", ToyWheel),
                           (ROBOTS, "toy_pair", ToyPair), (WORLDS, "toy_line", ToyLine),
                           (TASKS, "toy_goto", ToyGoto), (TASKS, "toy_watch", ToyWatch), (TASKS, "toy_mark", ToyMark),
                           (TASKS, "toy_return", ToyReturn)):
        if name not in reg._items:
            reg.add(name, cls)
