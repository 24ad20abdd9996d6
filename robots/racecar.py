"""The racecar: a car-like (Ackermann) robot standing in for the ViKi-HyCo paper's BLUE robot.

Geometry is PyBullet's ``racecar/racecar.urdf`` (wheelbase 0.325 m, track 0.2 m, wheel radius 0.05 m);
limits are the paper's (``|v| < 0.5 m/s``, ``|psi| < 0.44 rad``, section II-A).  The robot frame is the
rear-axle midpoint on the ground: x forward, y left, z up.

Sensor mounts follow the paper's layout (front RGB-D camera c1 + 16-layer LiDAR, rear RGB-D camera c2)
scaled to this car (:mod:`taskflow_robots.mounts`); they are data only — ``sim/`` renders them.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field
from taskflow_robots.mounts import CameraMount, LidarMount

from taskflow.api import ObsSpec, Robot, StrictModel, array, scalar
from taskflow.registry import register_robot

_PITCH = math.radians(30.0)


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
    front_camera: CameraMount = Field(default=CameraMount(xyz=(0.40, 0.0, 0.55), rpy=(0.0, _PITCH, 0.0)),
                                      description="the forward RGB-D camera c1")
    rear_camera: CameraMount = Field(default=CameraMount(xyz=(-0.10, 0.0, 0.55), rpy=(0.0, _PITCH, math.pi)),
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
    sensors: ClassVar[dict[str, str]] = {"front_camera": "rgbd_camera", "rear_camera": "rgbd_camera", "lidar": "lidar"}

    params: RacecarParams

