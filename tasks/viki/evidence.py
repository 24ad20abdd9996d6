"""What a ViKi-HyCo detection is worth as evidence: border-cut boxes, how far the view has moved since it.

Pure functions (numbers in, numbers out) used by :mod:`taskflow_tasks.viki.hyco`:

* :func:`box_cut_by_border` — a box that touches the image border (or comes within ``margin_px`` of it)
  is the visible part of an object the image cuts: its centre, width and eq. 18's position estimate are
  all biased toward the image's inside (a can half out of view looks half as wide and sits at the edge).
  Such a box neither drives the visual servo nor re-anchors the kinematic target;
* :func:`view_shift` — how far (m) a point fixed in the robot frame (the goal position of the object) has
  moved in the odometry frame between two poses: the change of the camera's view of the goal since a
  detection.  While it is below a few millimetres the image is the same (``viki_ground``'s still-camera
  model), so the last detection still describes the scene;
* :func:`goal_offset` — the object's position (odometry) seen from a pose, minus the desired position in
  the robot frame (m): the metric form of the visual servo's goal, for the settle rule.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from taskflow.spatial import planar_apply, planar_apply_inverse

__all__ = ["box_cut_by_border", "view_shift", "view_shifts", "goal_offset"]


def box_cut_by_border(bbox: ArrayLike, width: int, height: int, margin_px: float) -> bool:
    """True if the box ``(u0, v0, u2, v2)`` (edges, OpenCV convention: the image spans ``-0.5 .. W - 0.5``)
    lies within ``margin_px`` of any border of a ``width`` x ``height`` image (touching it: margin 0)."""
    if width <= 0 or height <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if not margin_px >= 0.0:
        raise ValueError(f"margin_px must be >= 0, got {margin_px}")
    u0, v0, u2, v2 = (float(x) for x in np.asarray(bbox, dtype=float).reshape(4))
    lo_u, lo_v, hi_u, hi_v = -0.5 + margin_px, -0.5 + margin_px, width - 0.5 - margin_px, height - 0.5 - margin_px
    eps = 1e-9
    return u0 <= lo_u + eps or v0 <= lo_v + eps or u2 >= hi_u - eps or v2 >= hi_v - eps


def view_shifts(poses_then: ArrayLike, pose_now: ArrayLike, point: ArrayLike) -> NDArray[np.float64]:
    """Distance (m) in odometry between where the robot-frame ``point`` was at each of ``poses_then``
    (``(N, 3)`` rows ``(x, y, theta)``) and where it is at ``pose_now``: translation plus rotation times the
    point's lever arm (one per row; the settle rule checks every stored detection each tick)."""
    g = np.asarray(point, dtype=float).reshape(2)
    T_odom_then = np.asarray(poses_then, dtype=float).reshape(-1, 3)
    d = planar_apply(np.asarray(pose_now, dtype=float).reshape(1, 3), g) - planar_apply(T_odom_then, g)
    shifts: NDArray[np.float64] = np.hypot(d[:, 0], d[:, 1])
    return shifts


def view_shift(pose_then: ArrayLike, pose_now: ArrayLike, point: ArrayLike) -> float:
    """:func:`view_shifts` for one pose ``(x, y, theta)`` then."""
    return float(view_shifts(pose_then, pose_now, point)[0])


def goal_offset(pose: ArrayLike, object_xy: ArrayLike, desired: ArrayLike) -> NDArray[np.float64]:
    """Object (odometry ``object_xy``) in the robot frame of ``pose`` minus ``desired`` (robot frame), m."""
    offset: NDArray[np.float64] = planar_apply_inverse(pose, object_xy) - np.asarray(desired, dtype=float).reshape(2)
    return offset
