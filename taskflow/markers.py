"""What a figure or a viewer draws of a mission besides the robot's path: typed scene markers.

A world says what its parameters put in the scene (:meth:`taskflow.api.World.scene`: obstacles, the
object, keyframes, walls, the start pose); a task says what its parameters aim at and which point of
the robot its guards measure (:meth:`taskflow.api.Task.scene`: a goal, the control point ``d`` ahead of
the rear axle).  :mod:`taskflow.readers.scene` collects both for a mission; :mod:`taskflow.readers.plots` and
:mod:`taskflow.readers.telemetry` draw them without knowing any mission.

Every coordinate is in the world frame of the robot's ground-truth pose (m, rad), the frame of the
poses a world declares in :attr:`taskflow.api.World.poses`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

ROLES = ("goal", "waypoint", "keyframe", "obstacle", "object", "start", "boundary")
"""What a marker is; figures style each role one way (a goal a cross, an obstacle a filled polygon …)."""


@dataclass(frozen=True)
class Marker:
    """One thing to draw: a point (one entry in ``points``), a polyline, or a closed polygon (``closed``).

    ``role`` is one of :data:`ROLES`; ``label`` names it in legends and viewers (``"waypoint 2"``);
    ``yaw`` is the heading of a pose marker (a keyframe, the start) in rad, None for a plain point;
    ``radius`` (m) draws a point as a circle of that size (a cylinder obstacle)."""

    role: str
    label: str
    points: tuple[tuple[float, float], ...]
    closed: bool = False
    yaw: float | None = None
    radius: float | None = None

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"marker role {self.role!r} — valid: {', '.join(ROLES)}")
        if not self.points:
            raise ValueError(f"marker {self.label!r} has no points")

    @classmethod
    def point(cls, role: str, label: str, x: float, y: float, yaw: float | None = None,
              radius: float | None = None) -> Marker:
        return cls(role, label, ((float(x), float(y)),), yaw=None if yaw is None else float(yaw),
                   radius=None if radius is None else float(radius))

    @classmethod
    def box(cls, role: str, label: str, x: float, y: float, width: float, depth: float, yaw: float = 0.0) -> Marker:
        """A ``width`` (along x before ``yaw``) x ``depth`` rectangle centred on ``(x, y)``, turned by ``yaw``."""
        c, s = math.cos(yaw), math.sin(yaw)
        corners = [(-width / 2, -depth / 2), (width / 2, -depth / 2), (width / 2, depth / 2), (-width / 2, depth / 2)]
        return cls(role, label, tuple((x + c * a - s * b, y + s * a + c * b) for a, b in corners), closed=True)


@dataclass(frozen=True)
class ControlPoint:
    """The point of the robot a task's guards measure, as an offset from the pose the world reports
    (:attr:`taskflow.api.World.poses`' first entry): ``offset`` = (ahead, left) in the robot's frame, m.
    ``label`` says what it is (``"control point d = 0.325 m ahead of the rear axle"``)."""

    offset: tuple[float, float]
    label: str

    def of(self, x: Any, y: Any, yaw: Any) -> tuple[Any, Any]:
        """The point in the world for the robot pose ``(x, y, yaw)`` (floats, or arrays of poses)."""
        a, b = self.offset
        c, s = np.cos(yaw), np.sin(yaw)
        return x + a * c - b * s, y + a * s + b * c


@dataclass(frozen=True)
class TaskScene:
    """What one task, with its parameters, adds to the scene: markers and the control point (None: the
    robot's reported pose itself is what its guards measure, or the task measures no position)."""

    markers: tuple[Marker, ...] = ()
    control_point: ControlPoint | None = None
