"""Task parameter models shared by several control laws."""

from __future__ import annotations

import math

from pydantic import field_validator

from taskflow.api import Marker, StrictModel


class PlanarTarget(StrictModel):
    """A goal in the odometry frame: ``[x, y]`` or ``[x, y, yaw]`` (m, m, rad)."""

    target: list[float]

    @field_validator("target")
    @classmethod
    def _shape(cls, target: list[float]) -> list[float]:
        if len(target) not in (2, 3) or not all(math.isfinite(v) for v in target):
            raise ValueError(f"target must be [x, y] or [x, y, yaw] with finite values, got {target}")
        return target

    def marker(self) -> Marker:
        """The target as a goal marker (with its yaw when it has one)."""
        t = self.target
        return Marker.point("goal", "target", t[0], t[1], yaw=t[2] if len(t) == 3 else None)
