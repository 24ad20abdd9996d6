"""Goals shared by several control laws: the planar target, the go-to metrics measured against it, and
:class:`PlanarGoto`, the base of the tasks that drive a ground robot to such a target."""

from __future__ import annotations

import math
from typing import ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, field_validator
from taskflow_tasks.core.keys import POSE, SPEED

from taskflow.api import DISTANCE, WRAPPED_ANGLE, Marker, StrictModel, Task, TaskContext
from taskflow.api import SPEED as SPEED_UNIT
from taskflow.specs import Requires

#: the metrics of a go-to law: the distance (m) from the controlled point to the target, the heading
#: error (rad) and the measured forward speed (m/s), as ``car_goto``, ``unicycle_goto`` and ``viki_rotate``
#: report them
GOTO_METRICS: dict[str, str] = {"pos_error": DISTANCE, "heading_error": WRAPPED_ANGLE, "speed": SPEED_UNIT}


class PlanarTarget(StrictModel):
    """A goal in the odometry frame: ``[x, y]`` or ``[x, y, yaw]`` (m, m, rad)."""

    target: list[float]

    @field_validator("target")
    @classmethod
    def _shape(cls, target: list[float]) -> list[float]:
        if len(target) not in (2, 3) or not all(math.isfinite(v) for v in target):
            raise ValueError(f"target must be [x, y] or [x, y, yaw] with finite values, got {target}")
        return target

    def target_xy(self) -> NDArray[np.float64]:
        """The target's ``(x, y)`` (m) as an array."""
        return np.asarray(self.target[:2], dtype=np.float64)

    def target_yaw(self) -> float | None:
        """The target's yaw (rad), ``None`` for an ``[x, y]`` target."""
        return float(self.target[2]) if len(self.target) == 3 else None

    def marker(self) -> Marker:
        """The target as a goal marker (with its yaw when it has one)."""
        t = self.target
        return Marker.point("goal", "target", t[0], t[1], yaw=t[2] if len(t) == 3 else None)


GoalT = TypeVar("GoalT", bound=PlanarTarget)
RobotT = TypeVar("RobotT", bound=BaseModel)


class PlanarGoto(Task[GoalT, RobotT]):
    """Base of the go-to tasks (``car_goto``, ``unicycle_goto``): a :class:`PlanarTarget` in the odometry
    frame (``self.target_xy``, ``self.target_yaw``), the odometry pose and speed as the observation it
    reads (:data:`~taskflow_tasks.core.keys.POSE`, :data:`~taskflow_tasks.core.keys.SPEED`) and the
    :data:`GOTO_METRICS`.  Not registered: a subclass gives the law (``step``), its gains and robot."""

    metrics: ClassVar[dict[str, str]] = {**GOTO_METRICS}
    requires: ClassVar[Requires] = (POSE, SPEED)

    def __init__(self, ctx: TaskContext[GoalT, RobotT]) -> None:
        super().__init__(ctx)
        self.target_xy, self.target_yaw = ctx.params.target_xy(), ctx.params.target_yaw()
