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
from taskflow_robots.racecar import CAMERA_PITCH, GROUND_SENSORS, CameraMount, LidarMount

from taskflow.api import ObsSpec, Robot, StrictModel, array, scalar
from taskflow.registry import register_robot


class HuskyParams(StrictModel):
    """Geometry (m), limits (m/s, rad/s, m/s², rad/s²) and motor torque (N m per wheel)."""

    # the body is the Husky URDF (its geometry is read from the URDF): these are the controller's belief
    wheel_radius: float = Field(default=0.17775, ge=0.05, le=0.5, description="m: the controller's belief of the "
                                "URDF's 0.178 m wheels, within about x1/3 to x3: the wheel speeds it commands are off by that factor")
    track: float = Field(default=0.5708, ge=0.2, le=1.5, description="distance between left and right wheel centres "
                         "(m): the controller's belief of the URDF's 0.571 m, within about x1/3 to x3")
    wheelbase: float = Field(default=0.512, ge=0.2, le=1.5, description="m: the controller's belief of the URDF's "
                             "0.512 m, within about x1/3 to x3")
    track_multiplier: float = Field(default=1.875, ge=1.0, le=4.0, description="skid-steer effective track / track: "
                                    "1 (no skid) to 4 (the skid-steer models' largest fitted value for four-wheel robots)")
    v_max: float = Field(default=1.0, gt=0.0, le=1.0, description="speed limit (m/s): at most 1.0, the Husky's top "
                         "speed (Clearpath datasheet)")
    w_max: float = Field(default=2.0, gt=0.0, le=4.0, description="yaw-rate limit (rad/s): at most 4, what the wheels "
                         "at 1 m/s can turn the skid-steer track (2 x 1 m/s / (0.571 m x 1.875) = 1.9 rad/s) with margin")
    a_max: float = Field(default=1.5, gt=0.0, le=5.0, description="forward acceleration limit (m/s^2): at most 5, "
                         "half the floor's grip mu g on the friction-1 floor")
    alpha_max: float = Field(default=4.0, gt=0.0, le=20.0, description="yaw acceleration limit (rad/s^2): at most 20, "
                             "the grip limit over the skid-steer half-track")
    wheel_torque: float = Field(default=60.0, gt=0.0, le=500.0, description="N m per wheel: at most 500 (the Husky's "
                                "motors give ~60 N m per wheel after their gearbox; more only spins the wheels)")
    # RGB-D cameras on a mast 0.55 m high pitched 30 deg down, at the front and rear bumpers (data only:
    # worlds that render sensors, e.g. viki_ground, read them), and a LiDAR above the centre.
    front_camera: CameraMount = Field(default=CameraMount(xyz=(0.58, 0.0, 0.55), rpy=(0.0, CAMERA_PITCH, 0.0)),
                                      description="the forward RGB-D camera")
    rear_camera: CameraMount = Field(default=CameraMount(xyz=(-0.40, 0.0, 0.55), rpy=(0.0, CAMERA_PITCH, math.pi)),
                                     description="the backward RGB-D camera")
    lidar: LidarMount = Field(default=LidarMount(xyz=(0.0, 0.0, 1.10)), description="the LiDAR above the centre")


@register_robot("husky")
class Husky(Robot):
    """Skid-steer robot commanded with forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s)."""

    Params: ClassVar[type[HuskyParams]] = HuskyParams
    command_interface: ClassVar[str] = "unicycle"
    command_keys: ClassVar[dict[str, int]] = {"v": 1, "w": 1}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {"v": (("v", "m/s"),), "w": (("w", "rad/s"),)}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.pose": array(3), "state.v": scalar(), "state.w": scalar()}
    sensors: ClassVar[dict[str, str]] = GROUND_SENSORS

    params: HuskyParams

