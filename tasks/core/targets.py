"""Goals shared by several control laws: the planar target and the go-to metrics measured against it."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from pydantic import field_validator

from taskflow.api import DISTANCE, SPEED, WRAPPED_ANGLE, Marker, StrictModel

#: the metrics of a go-to law: the distance (m) from the controlled point to the target, the heading
#: error (rad) and the measured forward speed (m/s), as ``car_goto``, ``unicycle_goto`` and ``viki_rotate``
#: report them
GOTO_METRICS: dict[str, str] = {"pos_error": DISTANCE, "heading_error": WRAPPED_ANGLE, "speed": SPEED}


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
