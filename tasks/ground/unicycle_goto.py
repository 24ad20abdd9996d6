"""``unicycle_goto``: drive a unicycle-commanded robot (``v``, ``w``) to a point.

The law (:func:`unicycle_point_law`) is Cartesian regulation of the unicycle in polar coordinates,
Siciliano, Sciavicco, Villani & Oriolo, *Robotics: Modelling, Planning and Control* (Springer 2009),
§11.6.2 ("Cartesian regulation": ``v = k_rho rho cos(alpha)``, ``w`` proportional to the bearing
error), with the ``k_rho sin(alpha) cos(alpha)`` feed-forward of Aicardi, Casalino, Bicchi & Balestrino,
"Closed loop steering of unicycle-like vehicles via Lyapunov techniques", IEEE Robotics & Automation
Magazine 2(1), 1995, that cancels the bearing drift caused by ``v``::

    rho   = |p* - p|,   alpha = wrap(atan2(y* - y, x* - x) - theta)
    v     = k_rho rho cos(alpha)
    w     = k_alpha alpha + k_rho sin(alpha) cos(alpha)

With the unicycle kinematics ``rho' = -v cos(alpha)``, ``alpha' = v sin(alpha) / rho - w`` this gives
the closed loop ``alpha' = -k_alpha alpha`` (exponential decay of the bearing error) and
``rho' = -k_rho rho cos(alpha)^2 <= 0``.  ``cos(alpha) < 0`` (target behind) drives backwards while the
robot turns.  Signs: ``theta``, ``alpha`` and ``w`` positive counter-clockwise (z up).  The final
heading is not controlled.

The task saturates ``(v, w)`` to the robot's ``v_max`` / ``w_max`` by one common factor (so the path's
curvature ``w / v`` is kept).  Metrics (from odometry, never ground truth): ``pos_error`` (m) = rho,
``heading_error`` (rad) = alpha (or, with a target yaw, ``wrap(yaw* - theta)``, reported only),
``speed`` (m/s) = ``|v|`` measured.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field
from taskflow_tasks.core.keys import POSE, SPEED
from taskflow_tasks.core.targets import PlanarGoto, PlanarTarget

from taskflow.api import (
    Observation,
    StepResult,
    StrictModel,
    TaskContext,
    TaskScene,
)
from taskflow.registry import register_task
from taskflow.spatial import wrap_angle


def unicycle_point_law(pose: NDArray[np.float64], target: NDArray[np.float64], k_rho: float,
                       k_alpha: float) -> tuple[float, float, float, float]:
    """``(v, w, rho, alpha)`` of the law in the module docstring for ``pose = [x, y, theta]`` and
    ``target = [x*, y*]`` (m, rad).  At the target (``rho = 0``) the bearing is undefined: ``(0, 0, 0, 0)``."""
    dx, dy = float(target[0] - pose[0]), float(target[1] - pose[1])
    rho = math.hypot(dx, dy)
    if rho == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    alpha = wrap_angle(math.atan2(dy, dx) - float(pose[2]))
    c, s = math.cos(alpha), math.sin(alpha)
    return k_rho * rho * c, k_alpha * alpha + k_rho * s * c, rho, alpha


def saturate(v: float, w: float, v_max: float, w_max: float) -> tuple[float, float]:
    """``(v, w)`` scaled by one factor so that ``|v| <= v_max`` and ``|w| <= w_max``."""
    scale = max(1.0, abs(v) / v_max, abs(w) / w_max)
    return v / scale, w / scale


class UnicycleLimits(StrictModel):
    """The robot parameters the law reads: its forward-speed and yaw-rate limits."""

    v_max: float
    w_max: float


class UnicycleGains(StrictModel):
    """``k_rho`` (1/s) and ``k_alpha`` (1/s) of the law; ``alpha`` decays as ``exp(-k_alpha t)``."""

    k_rho: float = Field(default=0.5, gt=0.0)
    k_alpha: float = Field(default=1.5, gt=0.0)


class UnicycleGotoParams(PlanarTarget):
    """Target ``[x, y]`` or ``[x, y, yaw]`` (m, m, rad) in the odometry frame (yaw is reported only)."""


@register_task("unicycle_goto")
class UnicycleGoto(PlanarGoto[UnicycleGotoParams, UnicycleLimits]):
    """Point regulation of a unicycle (Siciliano et al. 2009 §11.6.2; Aicardi et al. 1995)."""

    Params: ClassVar[type[UnicycleGotoParams]] = UnicycleGotoParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"gains": UnicycleGains}
    command_interface: ClassVar[str] = "unicycle"
    robot_params: ClassVar[type[BaseModel]] = UnicycleLimits

    def __init__(self, ctx: TaskContext[UnicycleGotoParams, UnicycleLimits]) -> None:
        super().__init__(ctx)
        gains, rp = ctx.profile("gains", UnicycleGains), ctx.robot_params
        self.v_max, self.w_max = float(rp.v_max), float(rp.w_max)
        self.k_rho, self.k_alpha = gains.k_rho, gains.k_alpha

    @classmethod
    def scene(cls, params: BaseModel, profiles: Mapping[str, BaseModel], robot_params: BaseModel | None) -> TaskScene:
        """The target; ``pos_error`` is measured at the robot's reported pose itself."""
        return TaskScene((cast(UnicycleGotoParams, params).marker(),))

    def step(self, obs: Observation) -> StepResult:
        pose = np.asarray(POSE(obs), dtype=np.float64)
        v, w, rho, alpha = unicycle_point_law(pose, self.target_xy, self.k_rho, self.k_alpha)
        v, w = saturate(v, w, self.v_max, self.w_max)
        heading = wrap_angle(self.target_yaw - float(pose[2])) if self.target_yaw is not None else alpha
        return StepResult(command={"v": np.array([v]), "w": np.array([w])},
                          metrics={"pos_error": rho, "heading_error": heading, "speed": abs(float(SPEED(obs)))})
