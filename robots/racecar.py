"""The racecar: a car-like (Ackermann) robot standing in for the ViKi-HyCo paper's BLUE robot.

Geometry is PyBullet's ``racecar/racecar.urdf`` (wheelbase 0.325 m, track 0.2 m, wheel radius 0.05 m);
limits are the paper's (``|v| < 0.5 m/s``, ``|psi| < 0.44 rad``, section II-A).  The robot frame is the
rear-axle midpoint on the ground: x forward, y left, z up.

Sensor mounts follow the paper's layout (front RGB-D camera c1 + 16-layer LiDAR, rear RGB-D camera c2)
scaled to this car; they are data only — ``sim/`` renders them.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator

from taskflow.api import ObsSpec, Robot, StrictModel, array, scalar
from taskflow.registry import register_robot
from taskflow_robots.camera import focal_px
from taskflow.spatial import R_body_optical, rotation_from_rpy, transform

Vec3 = tuple[float, float, float]


class Mount(StrictModel):
    """Robot → sensor body frame: translation ``xyz`` (m) and URDF ``rpy`` (rad).

    The sensor body frame is x forward (along the view), y left, z up, so ``rpy = (0, a, 0)`` pitches the
    sensor down by ``a`` and ``yaw = pi`` looks backward.
    """

    xyz: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)

    def R_robot_mount(self) -> NDArray[np.float64]:
        """Rotation robot ← sensor body frame."""
        return rotation_from_rpy(*self.rpy)

    def T_robot_mount(self) -> NDArray[np.float64]:
        """4x4 homogeneous transform robot ← sensor body frame."""
        return transform(self.R_robot_mount(), self.xyz)


class CameraMount(Mount):
    """An RGB-D camera: mount, image size, vertical field of view (rad), rate and depth range.

    The paper's cameras run 1280x720 at 15 fps; the default here is 640x360 (same aspect ratio) since
    TinyRenderer costs ~0.2 s per 1280x720 frame (SIMULATOR_NOTES.md).
    """

    width: int = Field(default=640, gt=0)
    height: int = Field(default=360, gt=0)
    fov: float = Field(default=0.7330, gt=0.0, lt=math.pi)  # vertical, 42 deg (RealSense D435 colour)
    rate_hz: float = Field(default=15.0, gt=0.0)
    near: float = Field(default=0.05, gt=0.0)
    far: float = Field(default=20.0, gt=0.0)

    def T_robot_camera(self) -> NDArray[np.float64]:
        """4x4 transform robot ← camera optical frame (x right, y down, z along the view, OpenCV).

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

    layers: int = Field(default=16, gt=0)
    v_fov: tuple[float, float] = (-math.radians(15.0), math.radians(15.0))
    h_fov: float = Field(default=1.4, gt=0.0, le=2.0 * math.pi)
    azimuths: int = Field(default=128, gt=0)
    rate_hz: float = Field(default=10.0, gt=0.0)
    min_range: float = Field(default=0.1, ge=0.0)
    max_range: float = Field(default=30.0, gt=0.0)

    @field_validator("v_fov")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"v_fov must be (low, high) with low < high, got {v}")
        return v


_PITCH = math.radians(30.0)


class RacecarParams(StrictModel):
    """Geometry (m), limits (m/s, rad) and sensor mounts of the racecar."""

    wheelbase: float = Field(default=0.325, gt=0.0)
    track: float = Field(default=0.2, gt=0.0)
    wheel_radius: float = Field(default=0.05, gt=0.0)
    v_max: float = Field(default=0.5, gt=0.0)
    psi_max: float = Field(default=0.44, gt=0.0, lt=math.pi / 2)
    # Cameras 0.55 m high pitched 30 deg down: the optical axis meets the ground ~0.95 m away and the
    # image spans ~0.45–3.5 m of ground ahead (behind for the rear camera).
    front_camera: CameraMount = CameraMount(xyz=(0.40, 0.0, 0.55), rpy=(0.0, _PITCH, 0.0))
    rear_camera: CameraMount = CameraMount(xyz=(-0.10, 0.0, 0.55), rpy=(0.0, _PITCH, math.pi))
    lidar: LidarMount = LidarMount(xyz=(0.20, 0.0, 1.10))


@register_robot("racecar")
class Racecar(Robot):
    """Car-like robot commanded with forward speed ``v`` (m/s) and bicycle steering angle ``steer`` (rad)."""

    Params: ClassVar[type[RacecarParams]] = RacecarParams
    command_interface: ClassVar[str] = "ackermann"
    command_keys: ClassVar[dict[str, int]] = {"v": 1, "steer": 1}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {"v": (("v", "m/s"),), "steer": (("steer", "rad"),)}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.pose": array(3), "state.v": scalar(), "state.steer": scalar()}
    sensors: ClassVar[dict[str, str]] = {"front_camera": "rgbd_camera", "rear_camera": "rgbd_camera", "lidar": "lidar"}

    params: RacecarParams

