"""What a ViKi-HyCo detection is worth as evidence: border-cut boxes, how far the view has moved since it.

Pure functions (numbers in, numbers out) used by :mod:`taskflow_tasks.viki.hyco`:

* :func:`box_cut_by_border` — a box that touches the image border (or comes within ``margin_px`` of it)
  is the visible part of an object the image cuts: its centre, width and eq. 18's position estimate are
  all biased toward the image's inside (a can half out of view looks half as wide and sits at the edge).
  Such a box neither drives the visual servo nor re-anchors the kinematic target;
* :func:`cut_box_near_point` — where the object of a box cut by the left or right border is, from the
  part that shows: eq. 18 with eq. 17's depth puts it 0.35-0.42 m too far (issue 25: the shrunk box of a
  sliver is mostly floor beyond the object), so the position comes from the floor instead: the ray
  through the box's bottom edge in its inner (uncut) column meets the ground in front of the object's
  base — a point no farther than the object, the conservative estimate a keep-out needs;
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

__all__ = ["box_cut_by_border", "cut_box_near_point", "view_shift", "view_shifts", "goal_offset"]


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


def cut_box_near_point(bbox: ArrayLike, width: int, height: int, margin_px: float, intrinsics: ArrayLike,
                       T_body_camera: ArrayLike) -> NDArray[np.float64] | None:
    """Robot-frame ``(x, y)`` (m) of the floor point seen at the bottom of a cut box's inner column.

    The box ``(u0, v0, u2, v2)`` is cut by the left border (``u0`` within ``margin_px`` of it: the inner
    column is ``u2``), by the right one (inner column ``u0``) or only by the top (the centre column).  The
    ray of pixel ``(u_in, v2)`` (eq. 18's back-projection, ``d_c = ((u - c_u) / f_x, (v - c_v) / f_y, 1)``
    rotated into the robot frame) meets the floor ``z = 0`` at the returned point.  A convex object
    standing on the floor hides the floor above its bottom edge in every column, so that point lies on
    the camera's side of the object's base, no farther than it (within its width).  ``None`` when the
    box gives no such bound: cut by the bottom border (the object's base is below the image), by both
    side borders, or a ray that does not reach the floor.
    """
    if width <= 0 or height <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    u0, v0, u2, v2 = (float(x) for x in np.asarray(bbox, dtype=float).reshape(4))
    eps = 1e-9
    left, right = u0 <= -0.5 + margin_px + eps, u2 >= width - 0.5 - margin_px - eps
    if v2 >= height - 0.5 - margin_px - eps or (left and right):
        return None
    u_in = u2 if left else u0 if right else 0.5 * (u0 + u2)
    fx, fy, cu, cv = (float(x) for x in np.asarray(intrinsics, dtype=float).reshape(4))
    T = np.asarray(T_body_camera, dtype=float).reshape(4, 4)
    d = T[:3, :3] @ np.array([(u_in - cu) / fx, (v2 - cv) / fy, 1.0])
    o = T[:3, 3]
    if not d[2] < -1e-9 or not o[2] > 0.0:
        return None
    t = -o[2] / d[2]
    return np.asarray(o[:2] + t * d[:2], dtype=float)


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
