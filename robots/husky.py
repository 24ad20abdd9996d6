"""The Husky: a four-wheel skid-steer ground robot (Clearpath Husky A200), commanded as a unicycle.

Geometry is PyBullet's ``husky/husky.urdf`` (wheel radius 0.17775 m, wheel separation 0.5708 m,
wheelbase 0.512 m).  The robot frame is ``base_footprint``: the centre of the four wheels on the ground,
x forward, y left, z up — the point a skid-steer vehicle turns about.  Limits follow the A200's data
sheet (1.0 m/s top speed); the yaw-rate and acceleration limits are this model's choice.

A skid-steer vehicle turns by dragging its wheels sideways, so the yaw rate it gets from a wheel-speed
difference is lower than a differential drive's: ``track_multiplier`` widens the track used to split
``(v, w)`` into wheel speeds (ROS ``diff_drive_controller``'s ``wheel_separation_multiplier``; 1.875 in
Clearpath's configuration).  It is part of the description because the body and the odometry model
share it.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from taskflow.api import ObsSpec, Robot, StrictModel, array, scalar
from taskflow.registry import register_robot
from taskflow_robots.racecar import CameraMount, LidarMount

_PITCH = math.radians(30.0)


class HuskyParams(StrictModel):
    """Geometry (m), limits (m/s, rad/s, m/s², rad/s²) and motor torque (N m per wheel)."""

    wheel_radius: float = Field(default=0.17775, gt=0.0)
    track: float = Field(default=0.5708, gt=0.0, description="distance between left and right wheel centres")
    wheelbase: float = Field(default=0.512, gt=0.0)
    track_multiplier: float = Field(default=1.875, ge=1.0, description="skid-steer effective track / track")
    v_max: float = Field(default=1.0, gt=0.0)
    w_max: float = Field(default=2.0, gt=0.0)
    a_max: float = Field(default=1.5, gt=0.0, description="forward acceleration limit")
    alpha_max: float = Field(default=4.0, gt=0.0, description="yaw acceleration limit")
    wheel_torque: float = Field(default=60.0, gt=0.0)
    # RGB-D cameras on a mast 0.55 m high pitched 30 deg down, at the front and rear bumpers (data only:
    # worlds that render sensors, e.g. viki_ground, read them), and a LiDAR above the centre.
    front_camera: CameraMount = CameraMount(xyz=(0.58, 0.0, 0.55), rpy=(0.0, _PITCH, 0.0))
    rear_camera: CameraMount = CameraMount(xyz=(-0.40, 0.0, 0.55), rpy=(0.0, _PITCH, math.pi))
    lidar: LidarMount = LidarMount(xyz=(0.0, 0.0, 1.10))


@register_robot("husky")
class Husky(Robot):
    """Skid-steer robot commanded with forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s)."""

    Params: ClassVar[type[HuskyParams]] = HuskyParams
    command_interface: ClassVar[str] = "unicycle"
    command_keys: ClassVar[dict[str, int]] = {"v": 1, "w": 1}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {"v": (("v", "m/s"),), "w": (("w", "rad/s"),)}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.pose": array(3), "state.v": scalar(), "state.w": scalar()}
    sensors: ClassVar[dict[str, str]] = {"front_camera": "rgbd_camera", "rear_camera": "rgbd_camera", "lidar": "lidar"}

    params: HuskyParams

