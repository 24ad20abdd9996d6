"""Camera model and detection-dropout model shared by both ViKi-HyCo perception modes.

Camera model (both modes, so a geometric box and a rendered box of the same scene agree):

* pinhole, ``fx = fy = H / (2 tan(fovy / 2))`` (``CameraMount.focal_px``), principal point
  ``(W / 2, H / 2 - 1)`` — where PyBullet's TinyRenderer puts it (measured: a box centred on the optical
  axis covers pixel rows 84..94 at 320x180, i.e. centre row 89; SIMULATOR_NOTES.md);
* OpenCV pixel convention: pixel centres at integer coordinates; a pixel is covered when its centre is
  inside the silhouette (TinyRenderer's rasterisation rule, checked against the segmentation mask), so a
  box covering columns ``a..b`` has edges ``a - 0.5`` and ``b + 0.5``;
* depth is the camera-axis coordinate ``Z`` (what a depth camera and the linearised OpenGL depth buffer
  give), limited to ``depth_max`` (the paper's RealSense: 5 m), 0 beyond.

Dropout (a detector that misses frames, ViKi-HyCo section III-B): a two-state Markov chain per frame
(Gilbert–Elliott) whose stationary miss fraction is ``miss`` and whose misses come in bursts of
geometric length with mean ``burst`` frames (``burst = 1``: independent misses).  A detector is
deterministic: when the camera has not moved since the previous frame (less than ``static_m`` of
translation and ``static_rad`` of rotation) the image is the same and so is the outcome, except with
probability ``static_flip`` per frame (sensor noise; ``viki_ground`` uses 1 %, i.e. a still miss lasts
~6.7 s on average at 15 Hz).  That is what stalls the paper's VS-only baseline (Fig. 12): the robot stops
on a missed detection, the image stops changing, the detection does not come back.  (With
``static_flip = 0`` a hybrid run that happens to stop exactly at its kinematic target during a miss
would wait forever too; the noise term lets it resume.)  The
first frame of a camera stream is never dropped (the paper starts its experiments from a detection,
section III-E).  Dropout applies only to frames in which the object is visible at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.camera import tinyrenderer_intrinsics
from taskflow_robots.racecar import CameraMount

from taskflow.spatial import rotation_angle


@dataclass(frozen=True)
class CameraModel:
    """One camera: name, mount on the robot, image size, intrinsics and depth range."""

    name: str
    mount: CameraMount
    width: int
    height: int
    depth_max: float

    @property
    def intrinsics(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cu, cv)`` with TinyRenderer's principal point ``(W/2, H/2 - 1)``."""
        return tinyrenderer_intrinsics(self.width, self.height, self.mount.fov)

    def T_robot_camera(self) -> NDArray[np.float64]:
        """Robot ← optical frame (4x4)."""
        return self.mount.T_body_camera()

    def pose(self, T_world_robot: NDArray[np.float64]) -> NDArray[np.float64]:
        """World ← optical frame for a robot pose ``T_world_robot`` (4x4)."""
        return T_world_robot @ self.T_robot_camera()

    def project(self, T_world_camera: NDArray[np.float64], P_w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixels ``(N, 2)`` and camera depths ``(N,)`` of world points ``(N, 3)``."""
        R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
        Pc = (np.asarray(P_w, dtype=float) - t) @ R  # R^T (P - t), row-wise
        fx, fy, cu, cv = self.intrinsics
        z = Pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.column_stack([fx * Pc[:, 0] / z + cu, fy * Pc[:, 1] / z + cv])
        return uv, z

    def rays(self, T_world_camera: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World origin and (N, 3) directions of pixel rays, scaled so the camera-Z component is 1.

        With that scaling the ray parameter of a hit *is* the camera depth ``Z``.
        """
        fx, fy, cu, cv = self.intrinsics
        dc = np.column_stack([(np.asarray(u, float) - cu) / fx, (np.asarray(v, float) - cv) / fy,
                              np.ones(np.size(u))])
        return T_world_camera[:3, 3].copy(), dc @ T_world_camera[:3, :3].T


def quantise_box(u0: float, v0: float, u2: float, v2: float) -> tuple[float, float, float, float]:
    """Continuous silhouette extents → the box of the pixels whose centres they cover (edges at .5).

    A silhouette thinner than a pixel between two centres still covers the nearest pixel.
    """
    a, b = math.ceil(u0), math.floor(u2)
    c, d = math.ceil(v0), math.floor(v2)
    if a > b:
        a = b = round(0.5 * (u0 + u2))
    if c > d:
        c = d = round(0.5 * (v0 + v2))
    return (a - 0.5, c - 0.5, b + 0.5, d + 0.5)


def pixel_box(bbox: tuple[float, float, float, float]) -> tuple[int, int, int, int]:
    """Edge box (``a - 0.5 .. b + 0.5``) → inclusive pixel-index box ``(a, c, b, d)`` for eq. 16–17."""
    u0, v0, u2, v2 = bbox
    return (int(round(u0 + 0.5)), int(round(v0 + 0.5)), int(round(u2 - 0.5)), int(round(v2 - 0.5)))


class DropoutModel:
    """Seeded per-frame detection misses (module docstring): Gilbert–Elliott chain + static repeat."""

    def __init__(self, rng: np.random.Generator, miss: float, burst: float, static_m: float,
                 static_rad: float, static_flip: float) -> None:
        if not 0.0 <= miss < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {miss}")
        if not burst >= 1.0:
            raise ValueError(f"dropout_burst (mean burst length, frames) must be >= 1, got {burst}")
        self.rng = rng
        self.miss = miss
        self.p_recover = 1.0 / burst  # bad → good
        self.p_fail = min(1.0, miss / (burst * (1.0 - miss))) if miss > 0.0 else 0.0  # good → bad
        self.static_m, self.static_rad, self.static_flip = static_m, static_rad, static_flip
        self.missing = False
        self._last_pose: NDArray[np.float64] | None = None

    def reset(self) -> None:
        """New camera stream: start detected, forget the last camera pose."""
        self.missing = False
        self._last_pose = None

    def frame(self, T_world_camera: NDArray[np.float64]) -> bool:
        """Advance one frame taken from camera pose ``T_world_camera``; True if this frame's detection is dropped."""
        if self.miss <= 0.0:
            return False
        u = float(self.rng.random())  # one draw per frame whatever the branch: the stream stays aligned
        last, self._last_pose = self._last_pose, T_world_camera.copy()
        if last is None:  # a stream's first frame is a detection (the experiment starts from one)
            self.missing = False
            return False
        if self._static(last, T_world_camera):
            if u < self.static_flip:
                self.missing = not self.missing
            return self.missing
        if self.missing:
            self.missing = u >= self.p_recover
        else:
            self.missing = u < self.p_fail
        return self.missing

    def _static(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
        if self.static_m <= 0.0:
            return False
        dt = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
        ang = rotation_angle(a[:3, :3].T @ b[:3, :3])
        return dt < self.static_m and ang < self.static_rad
