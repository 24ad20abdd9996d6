"""``car_goto``: drive the car's control point to a target with the ViKi-HyCo kinematic controller.

Eq. (4) ``V = J_b^-1 (k1 tanh(h_d - h))`` servoes the **control point** ``h`` — the point ``d`` ahead of
the rear-axle midpoint along the heading (eq. 1; with ``d = wheelbase`` it is the front-axle midpoint)
— to the target; eq. (5) turns the twist into a steering angle (:func:`taskflow_tasks.ground.car_kinematics.car_command`).
A car cannot servo its rear axle to an arbitrary point, but the point ``d`` ahead is controllable, so
that is the point a mission's target refers to and the point ``pos_error`` is measured at.

Metrics (from the observation's odometry, never ground truth):

* ``pos_error`` (m): distance from the control point to the target ``(x, y)``;
* ``heading_error`` (rad): with a target yaw, ``wrap(target_yaw - yaw)`` (reported only — eq. 4 does
  not control the final heading); without one, the bearing of the target seen from the control point
  relative to the heading (0 once the point is on the target);
* ``speed`` (m/s): magnitude of the measured forward speed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar, cast

import numpy as np
from pydantic import BaseModel, Field, field_validator
from taskflow_tasks.core.gains import positive_gains
from taskflow_tasks.core.keys import POSE, SPEED
from taskflow_tasks.core.targets import PlanarGoto, PlanarTarget
from taskflow_tasks.ground.car_kinematics import car_command, control_point, kinematic_control, wrap_angle

from taskflow.api import (
    ControlPoint,
    Observation,
    StepResult,
    StrictModel,
    TaskContext,
    TaskScene,
)
from taskflow.registry import register_task


class CarGains(StrictModel):
    """Gains of eq. (4): ``k1 = (k_x, k_y)`` (1/s·m/s, paper: forward (2, 1), backward (1, 2)) and the
    control-point distance ``d`` (m; ``None`` = the robot's wheelbase, as in the paper)."""

    k1: tuple[float, float] = (2.0, 1.0)
    d: float | None = Field(default=None, gt=0.0)

    @field_validator("k1")
    @classmethod
    def _positive(cls, k1: tuple[float, float]) -> tuple[float, float]:
        positive_gains("k1", k1)
        return k1


class CarGeometry(StrictModel):
    """The robot parameters the car laws read (any robot whose parameters have them, with these types)."""

    wheelbase: float
    v_max: float
    psi_max: float


def car_control_point(gains: BaseModel | None, geometry: CarGeometry) -> ControlPoint:
    """The point ``d`` ahead of the rear-axle midpoint that the car laws servo (``d`` from the gains, or
    the wheelbase)."""
    d = gains.d if isinstance(gains, CarGains) and gains.d is not None else geometry.wheelbase
    return ControlPoint((float(d), 0.0), f"control point d = {d:g} m ahead of the rear axle")


class CarGotoParams(PlanarTarget):
    """Target of the control point: ``[x, y]`` or ``[x, y, yaw]`` (m, m, rad) in the odometry frame."""


@register_task("car_goto")
class CarGoto(PlanarGoto[CarGotoParams, CarGeometry]):
    """Kinematic controller of the ViKi-HyCo paper (eqs. 1–5) toward a fixed point."""

    Params: ClassVar[type[CarGotoParams]] = CarGotoParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"gains": CarGains}
    command_interface: ClassVar[str] = "ackermann"
    robot_params: ClassVar[type[BaseModel]] = CarGeometry

    def __init__(self, ctx: TaskContext[CarGotoParams, CarGeometry]) -> None:
        super().__init__(ctx)
        rp = ctx.robot_params
        gains = ctx.profile("gains", CarGains)
        self.wheelbase = rp.wheelbase
        self.v_max = rp.v_max
        self.psi_max = rp.psi_max
        self.k1 = np.asarray(gains.k1, dtype=np.float64)
        self.d = float(gains.d) if gains.d is not None else self.wheelbase
        self.direction = 0.0  # sign of the last non-zero speed command (see car_command)

    @classmethod
    def scene(cls, params: BaseModel, profiles: Mapping[str, BaseModel], robot_params: BaseModel | None) -> TaskScene:
        """The target, and the control point ``d`` ahead of the rear axle where ``pos_error`` is measured."""
        return TaskScene((cast(CarGotoParams, params).marker(),),
                         car_control_point(profiles.get("gains"), cast(CarGeometry, robot_params)))

    def step(self, obs: Observation) -> StepResult:
        pose = np.asarray(POSE(obs), dtype=np.float64)
        v, w = kinematic_control(pose, self.target_xy, self.k1, self.d)
        v_cmd, psi = car_command(v, w, self.wheelbase, self.v_max, self.psi_max, self.direction)
        if v_cmd != 0.0:
            self.direction = math.copysign(1.0, v_cmd)
        err = self.target_xy - control_point(pose, self.d)
        dist = float(np.hypot(err[0], err[1]))
        if self.target_yaw is not None:
            heading = wrap_angle(self.target_yaw - float(pose[2]))
        elif dist > 1e-9:
            heading = wrap_angle(math.atan2(err[1], err[0]) - float(pose[2]))
        else:
            heading = 0.0
        return StepResult(
            command={"v": np.array([v_cmd]), "steer": np.array([psi])},
            metrics={"pos_error": dist, "heading_error": heading, "speed": abs(float(SPEED(obs)))},
        )
