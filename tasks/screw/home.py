"""``arm_home``: the screw mission's error handling — the platform stops and the arm retracts to the
robot's ``q_home`` in joint space (no camera needed, so it works when the target is lost)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, Field
from taskflow_tasks.core.impedance import AdmittanceState
from taskflow_tasks.screw.data import ADMITTANCE, Q_NOM, Q_REF, Q, control_period

from taskflow.api import MemoryKey, Metric, Observation, StepResult, StrictModel, Task, TaskContext
from taskflow.registry import register_task
from taskflow.specs import Requires


class HomeParams(StrictModel):
    """Joint-space move to the robot's ``q_home`` at ``speed`` (rad/s)."""

    speed: float = Field(default=0.5, gt=0.0, le=2.0)


class HomePose(StrictModel):
    """The robot parameter the homing law reads: the arm's home configuration (rad)."""

    q_home: tuple[float, ...]


@register_task("arm_home")
class ArmHome(Task[HomeParams, HomePose]):
    """Error handling: the platform stops and the arm retracts to ``q_home`` in joint space (no
    camera needed, so it works when the target is lost).  ``joint_error`` (rad) is the largest joint
    distance to home."""

    Params: ClassVar[type[BaseModel]] = HomeParams
    metrics: ClassVar[dict[str, str]] = {"joint_error": Metric("rad", low=0.0, reason="the largest |joint angle error|")}
    command_interface: ClassVar[str] = "base_arm"
    robot_params: ClassVar[type[BaseModel]] = HomePose
    requires: ClassVar[Requires] = (Q, Q_REF)
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (Q_NOM, ADMITTANCE)

    def __init__(self, ctx: TaskContext[HomeParams, HomePose]) -> None:
        super().__init__(ctx)
        self.dt = control_period(ctx, self.name or type(self).__name__)
        self.home = np.array(ctx.robot_params.q_home)
        self.speed = float(ctx.params.speed)
        self.mem = ctx.memory

    def step(self, obs: Observation) -> StepResult:
        m = self.mem
        dt = self.dt
        q_ref = np.asarray(Q_REF(obs), dtype=np.float64)
        q_nom = Q_NOM.get(m)
        q_nom = q_ref.copy() if q_nom is None else q_nom
        d = self.home - q_nom
        peak = float(np.max(np.abs(d)))
        step = self.speed * dt
        q_nom = self.home.copy() if peak <= step else q_nom + d * (step / peak)
        Q_NOM.set(m, q_nom)
        ADMITTANCE.set(m, AdmittanceState())
        q = np.asarray(Q(obs), dtype=np.float64)
        return StepResult({"base_twist": np.zeros(3), "arm_dq": q_nom - q_ref},
                          {"joint_error": float(np.max(np.abs(self.home - q)))})
