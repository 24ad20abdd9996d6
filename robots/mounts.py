"""Sensor mounts of the ground robots (racecar, Husky): where a camera or a LiDAR sits on the robot and
what it sees, as data — ``sim/`` renders them.

A mount is the pose ``T_body_mount`` of the sensor's body frame (x along the view, y left, z up) in the
robot body frame, from a translation ``xyz`` and URDF ``rpy``; a camera's optical frame (OpenCV) is
``T_body_camera`` (:meth:`CameraMount.T_body_camera`, the one name of a camera mount on every robot).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator, model_validator
from taskflow_robots.camera import focal_px

from taskflow.api import StrictModel
from taskflow.spatial import R_body_optical, rotation_from_rpy, transform

Vec3 = tuple[float, float, float]


class Mount(StrictModel):
    """Robot → sensor body frame: translation ``xyz`` (m) and URDF ``rpy`` (rad).

    The sensor body frame is x forward (along the view), y left, z up, so ``rpy = (0, a, 0)`` pitches the
    sensor down by ``a`` and ``yaw = pi`` looks backward.
    """

    xyz: Vec3 = Field(description="m, in the robot frame: each within ±3 m (a sensor carried by the robot)")
    rpy: Vec3 = Field(default=(0.0, 0.0, 0.0), description="URDF roll, pitch, yaw (rad): each within one turn either way")

    @model_validator(mode="after")
    def _on_the_robot(self) -> Mount:
        if not all(math.isfinite(x) and abs(x) <= 3.0 for x in self.xyz) or \
                not all(math.isfinite(a) and abs(a) <= 2.0 * math.pi for a in self.rpy):
            raise ValueError(f"a sensor mount has each xyz within ±3 m and each rpy angle within ±2 pi rad, "
                             f"got xyz {list(self.xyz)}, rpy {list(self.rpy)}")
        return self

    def R_body_mount(self) -> NDArray[np.float64]:
        """``R_body_mount``: rotation robot body ← sensor body frame."""
        return rotation_from_rpy(*self.rpy)

    def T_body_mount(self) -> NDArray[np.float64]:
        """``T_body_mount``: 4x4 pose of the sensor body frame in the robot body frame."""
        return transform(self.R_body_mount(), self.xyz)


class CameraMount(Mount):
    """An RGB-D camera: mount, image size, vertical field of view (rad), rate and depth range.

    The paper's cameras run 1280x720 at 15 fps; the default here is 640x360 (same aspect ratio) since
    TinyRenderer costs ~0.2 s per 1280x720 frame (SIMULATOR_NOTES.md).
    """

    width: int = Field(default=640, ge=16, le=4096, description="px: at least 16 (a box detector needs pixels "
                       "across the object), at most 4096 (TinyRenderer's largest image)")
    height: int = Field(default=360, ge=16, le=4096, description="px, as width")
    fov: float = Field(default=0.7330, ge=0.05, le=math.pi - 0.05,  # vertical, 42 deg (RealSense D435 colour)
                       description="vertical field of view (rad): a pinhole camera has 0 < fov < pi (at pi the focal "
                       "length is 0); kept 0.05 rad from both ends")
    rate_hz: float = Field(default=15.0, ge=1.0, le=90.0, description="frame rate (Hz): 1-90, what RGB-D cameras "
                           "deliver (the RealSense D435i: 6 to 90 fps); below 1 Hz the 20 Hz control laws act on one "
                           "frame for 20 ticks and the car covers v_max x 1 s between two detections")
    near: float = Field(default=0.05, gt=0.0, le=1.0, description="near clip plane (m): > 0, at most 1 m (nearer objects vanish)")
    far: float = Field(default=20.0, gt=0.0, le=1000.0, description="far clip plane (m): beyond near, at most 1 km "
                       "(the depth buffer's resolution is spread over far / near)")

    @model_validator(mode="after")
    def _clip_planes(self) -> CameraMount:
        if not self.near < self.far:
            raise ValueError(f"the far clip plane ({self.far} m) must lie beyond the near one ({self.near} m)")
        return self

    def T_body_camera(self) -> NDArray[np.float64]:
        """``T_body_camera``: 4x4 pose of the camera optical frame (x right, y down, z along the view,
        OpenCV) in the robot body frame — the camera mount's one name on every robot.

        This is the ``(^r R_c, ^r t_c)`` of the paper's eqs. (22)–(23).
        """
        roll, pitch, yaw = self.rpy
        return transform(R_body_optical(yaw=yaw, pitch=pitch, roll=roll), self.xyz)

    def focal_px(self) -> float:
        """Focal length in pixels, ``fx = fy = H / (2 tan(fovy / 2))``."""
        return focal_px(self.height, self.fov)


class LidarMount(Mount):
    """A multi-layer LiDAR: ``layers`` elevation rings evenly spread over ``v_fov = (low, high)`` rad.

    Default: VLP-16 (16 layers, ±15 deg) at the paper's 1.10 m height, whose ground blind-spot radius is
    ``1.10 / tan(15 deg) = 4.105 m`` — the paper's ``R = 4.1052 m`` (eq. 13).  Azimuths cover ``h_fov``
    (rad) centred on the sensor's x axis in ``azimuths`` steps: only the part the front camera sees is
    used by eq. (11), so the default spans a little more than the camera's horizontal field of view.
    """

    layers: int = Field(default=16, ge=1, le=128, description="elevation rings: 1-128 (spinning LiDARs have 16 to 128)")
    v_fov: tuple[float, float] = Field(default=(-math.radians(15.0), math.radians(15.0)),
                                       description="(low, high) elevation of the outer rings (rad): low < high, "
                                       "both within [-pi/2, pi/2] (straight down to straight up)")
    h_fov: float = Field(default=1.4, gt=0.0, le=2.0 * math.pi, description="azimuth span (rad): at most a full turn")
    azimuths: int = Field(default=128, ge=1, le=4096, description="azimuth steps: 1-4096 (a ray per step and ring "
                          "is cast every scan)")
    rate_hz: float = Field(default=10.0, ge=1.0, le=50.0, description="scan rate (Hz): 1-50, what spinning LiDARs "
                           "do (the VLP-16: 5-20 Hz)")
    min_range: float = Field(default=0.1, ge=0.0, le=300.0, description="m: nearer returns are dropped; below max_range")
    max_range: float = Field(default=30.0, gt=0.0, le=300.0, description="m: at most 300 (the longest-range LiDARs)")

    @field_validator("v_fov")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not -math.pi / 2 <= v[0] < v[1] <= math.pi / 2:
            raise ValueError(f"v_fov must be (low, high) with -pi/2 <= low < high <= pi/2 rad, got {v}")
        return v

    @model_validator(mode="after")
    def _ranges(self) -> LidarMount:
        if not self.min_range < self.max_range:
            raise ValueError(f"min_range ({self.min_range} m) must be below max_range ({self.max_range} m)")
        return self
