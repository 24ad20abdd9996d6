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
from pydantic import Field, field_validator, model_validator
from taskflow_robots.camera import focal_px

from taskflow.api import ObsSpec, Robot, StrictModel, array, scalar
from taskflow.registry import register_robot
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


#: the pitch (rad, down) of the ground robots' RGB-D cameras (racecar, husky)
CAMERA_PITCH = math.radians(30.0)
#: the sensor kinds of a ground robot's mounts: RGB-D cameras front and rear, a LiDAR (racecar, husky)
GROUND_SENSORS: dict[str, str] = {"front_camera": "rgbd_camera", "rear_camera": "rgbd_camera", "lidar": "lidar"}


class RacecarParams(StrictModel):
    """Geometry (m), limits (m/s, rad) and sensor mounts of the racecar."""

    # the body is PyBullet's racecar URDF (the worlds read its geometry from the URDF): these are the
    # controller's belief about it, so they stay near the body's own numbers
    wheelbase: float = Field(default=0.325, ge=0.1, le=1.0, description="m: the controller's belief of the body's "
                             "0.325 m, within about x1/3 to x3 of it; the steering it computes, psi = atan(L w / v), "
                             "is off by that factor")
    track: float = Field(default=0.2, ge=0.05, le=0.6, description="m: the controller's belief of the body's 0.2 m "
                         "(the body's own track drives its wheels), within about x1/4 to x3")
    wheel_radius: float = Field(default=0.05, ge=0.01, le=0.2, description="m: the controller's belief of the body's "
                                "0.05 m wheels, within x1/5 to x4")
    v_max: float = Field(default=0.5, gt=0.0, le=2.5, description="speed limit (m/s; paper: 0.5): at most 2.5 m/s, "
                         "where a full-lock turn's lateral acceleration v^2 tan(psi_max) / wheelbase (1.45 /m at "
                         "0.44 rad) reaches the floor's grip mu g = 9.8 m/s^2: faster, the tyres slide, which the "
                         "no-slip bicycle model of the laws and the odometry does not describe")
    psi_max: float = Field(default=0.44, gt=0.0, lt=math.pi / 2, description="steering limit (rad; paper: 0.44): "
                           "below pi/2 (a wheel turned across the car)")
    # Cameras 0.55 m high pitched 30 deg down: the optical axis meets the ground ~0.95 m away and the
    # image spans ~0.45–3.5 m of ground ahead (behind for the rear camera).
    front_camera: CameraMount = Field(default=CameraMount(xyz=(0.40, 0.0, 0.55), rpy=(0.0, CAMERA_PITCH, 0.0)),
                                      description="the forward RGB-D camera c1")
    rear_camera: CameraMount = Field(default=CameraMount(xyz=(-0.10, 0.0, 0.55), rpy=(0.0, CAMERA_PITCH, math.pi)),
                                     description="the backward RGB-D camera c2")
    lidar: LidarMount = Field(default=LidarMount(xyz=(0.20, 0.0, 1.10)), description="the 16-layer LiDAR")


@register_robot("racecar")
class Racecar(Robot):
    """Car-like robot commanded with forward speed ``v`` (m/s) and bicycle steering angle ``steer`` (rad)."""

    Params: ClassVar[type[RacecarParams]] = RacecarParams
    command_interface: ClassVar[str] = "ackermann"
    command_keys: ClassVar[dict[str, int]] = {"v": 1, "steer": 1}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {"v": (("v", "m/s"),), "steer": (("steer", "rad"),)}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.pose": array(3), "state.v": scalar(), "state.steer": scalar()}
    sensors: ClassVar[dict[str, str]] = GROUND_SENSORS

    params: RacecarParams

