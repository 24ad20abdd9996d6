"""The ground-truth score of a ``quad_room`` run: collisions and clearances, the flown path's length and
its deviation from the taught path, and the final errors against the last taught pose (the summary).

Everything here reads the world's true state (the drone's pose, the taught poses, the scene's contact
queries); nothing of it reaches an observation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.quadcopter import QuadCamera
from taskflow_sim.quad.landmarks import project, visible_landmarks
from taskflow_sim.quad.scene import Column

Array = NDArray[np.float64]
Pose = tuple[float, float, float, float]

__all__ = ["RoomScore", "ground_truth_epsilon"]


class RoomScore:
    """Collisions, clearances, path length and path deviation over a run (restart on reset)."""

    def __init__(self, start: Sequence[float], taught: Sequence[Pose]) -> None:
        self.taught = list(taught)
        self.taught_path = np.array([start[:2]] + [p[:2] for p in taught], dtype=np.float64)
        self.taught_path_3d = np.array([start[:3]] + [p[:3] for p in taught], dtype=np.float64)
        self.restart()

    def restart(self) -> None:
        self.in_contact = False
        self.collisions = 0
        self.min_obstacle_clearance = math.inf
        self.min_wall_clearance = math.inf
        self.clearance = (math.inf, math.inf)
        self.path_length = 0.0
        self._dev_sum, self._dev_n, self.max_path_deviation = 0.0, 0, 0.0
        self._dev3_sum, self.max_path_deviation_3d = 0.0, 0.0

    def contacts(self, obstacle: float, wall: float) -> bool:
        """Record this step's clearances (m); whether a contact starts now (a ``collision`` event)."""
        self.clearance = (obstacle, wall)
        self.min_obstacle_clearance = min(self.min_obstacle_clearance, obstacle)
        self.min_wall_clearance = min(self.min_wall_clearance, wall)
        contact = min(obstacle, wall) <= 0.0
        started = contact and not self.in_contact
        if started:
            self.collisions += 1
        self.in_contact = contact
        return started

    def moved(self, start_xyz: Sequence[float], pose: Array) -> None:
        """The drone went from ``start_xyz`` to ``pose`` in one ``advance``: path length and deviation."""
        x, y, z, _ = pose
        self.path_length += math.dist(start_xyz, (x, y, z))
        if not self.taught:
            return
        d = self.path_deviation(pose[:2])
        self.max_path_deviation = max(self.max_path_deviation, d)
        self._dev_sum += d
        self._dev_n += 1
        d3 = self.path_deviation_3d(pose[:3])
        self.max_path_deviation_3d = max(self.max_path_deviation_3d, d3)
        self._dev3_sum += d3

    def path_deviation(self, xy: Sequence[float] | Array) -> float:
        """Horizontal distance (m) from ``xy`` to the taught path polyline (start → keyframe 0 → …)."""
        return _polyline_distance(self.taught_path, xy)

    def path_deviation_3d(self, xyz: Sequence[float] | Array) -> float:
        """Distance (m) in 3-D from ``xyz`` to the taught path polyline through the taught positions
        (start → keyframe 0 → …, heights included): a climb flown below its apex shows here, not in the
        horizontal :meth:`path_deviation`."""
        return _polyline_distance(self.taught_path_3d, xyz)

    def summary(self, pose: Array, has_obstacles: bool, final_epsilon: float | None) -> dict[str, Any]:
        """Collisions and clearances over the run; final errors against the last taught pose."""
        x, y, z, yaw = (float(v) for v in pose)
        out: dict[str, Any] = {
            "collisions": self.collisions,
            "min_clearance_m": float(min(self.min_obstacle_clearance, self.min_wall_clearance)),
            "min_obstacle_clearance_m": float(self.min_obstacle_clearance) if has_obstacles else None,
            "min_wall_clearance_m": float(self.min_wall_clearance),
            "path_length_m": self.path_length,
            "gt_x_m": x, "gt_y_m": y, "gt_z_m": z, "gt_yaw_rad": yaw,
        }
        if self.taught:
            last = self.taught[-1]
            out["final_position_error_m"] = float(math.dist((x, y, z), last[:3]))
            out["final_yaw_error_deg"] = math.degrees(abs(math.remainder(yaw - last[3], 2.0 * math.pi)))
            out["final_epsilon_px"] = final_epsilon
            out["path_deviation_max_m"] = self.max_path_deviation
            out["path_deviation_mean_m"] = self._dev_sum / self._dev_n if self._dev_n else 0.0
            out["path_deviation_3d_max_m"] = self.max_path_deviation_3d
            out["path_deviation_3d_mean_m"] = self._dev3_sum / self._dev_n if self._dev_n else 0.0
        return out


def _polyline_distance(poly: Array, point: Sequence[float] | Array) -> float:
    """Distance (m) from ``point`` to the polyline ``poly`` (rows: vertices, 2-D or 3-D)."""
    q = np.asarray(point, dtype=np.float64)
    if len(poly) < 2:
        return float(np.linalg.norm(q - poly[0]))
    a, ab = poly[:-1], np.diff(poly, axis=0)
    s = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + s[:, None] * ab - q, axis=1)))


def ground_truth_epsilon(cam: QuadCamera, kf_pose: Pose, pose: Sequence[float], landmarks: Array | None = None,
                         columns: Sequence[Column] = (), depth: Array | None = None, grid: int = 16) -> float:
    """Ground-truth ``ε`` (eq. 7, px) between the view at ``pose`` and the keyframe taught at ``kf_pose``.

    With ``landmarks`` (geometric mode): the landmarks the keyframe sees, projected exactly into both
    views.  Otherwise a grid of keyframe pixels is back-projected with the keyframe's ``depth`` buffer and
    projected into the current camera; the mean displacement of those in front of the camera (NaN
    without a depth buffer, or with nothing in front)."""
    K = cam.K()
    if landmarks is not None:
        Rk, tk = cam.pose_in_world(kf_pose)
        ids, uv_k = visible_landmarks(landmarks, columns, Rk, tk, K, (cam.width, cam.height))
        R, t = cam.pose_in_world(list(pose))
        z, uv = project(landmarks[ids], R, t, K)
        front = z > 0.05
        return float(np.mean(np.linalg.norm(uv[front] - uv_k[front], axis=1))) if np.any(front) else math.nan
    if depth is None:
        return math.nan
    us = np.linspace(0.05, 0.95, grid) * cam.width
    vs = np.linspace(0.05, 0.95, grid) * cam.height
    uu, vv = np.meshgrid(us, vs)
    uv = np.column_stack((uu.ravel(), vv.ravel()))
    Z = depth[np.clip(uv[:, 1].astype(int), 0, cam.height - 1), np.clip(uv[:, 0].astype(int), 0, cam.width - 1)]
    ok = 0.99 * cam.far > Z
    uv, Z = uv[ok], Z[ok]
    Xc = np.column_stack(((uv[:, 0] - K[0, 2]) / K[0, 0] * Z, (uv[:, 1] - K[1, 2]) / K[1, 1] * Z, Z))
    Rk, tk = cam.pose_in_world(kf_pose)
    Xw = Xc @ Rk.T + tk
    R, t = cam.pose_in_world(list(pose))
    Xn = (Xw - t) @ R
    front = Xn[:, 2] > 0.05
    if not np.any(front):
        return math.nan
    proj = Xn[front, :2] / Xn[front, 2:3] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    return float(np.mean(np.linalg.norm(proj - uv[front], axis=1)))
