"""The quadcopter of the visual-path-following paper (Toro-Arcila et al.), as a velocity-controlled body.

The paper commands ``nu = [vx, vy, vz, wz]`` (body frame) to the Bebop 2's on-board velocity
controller and models the flat outputs ``[x, y, z, yaw]`` as single integrators (eq. 1).  Here the
on-board controller tracks the command with a first-order lag of time constant ``tau`` (a robot
parameter; ``tau = 0`` is the paper's ideal integrator); ``sim/`` moves the body kinematically.

Body frame: x forward, y left, z up (FLU); yaw about z.  Looks and collision shapes are the ``iris``
quadrotor of example-robot-data, scaled by ``scale`` (default 0.75: 0.39 m x 0.52 m rotor tips, about
a Bebop 2 with its hull).  A forward monocular camera (OpenCV optical frame) sits at ``eT_c``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator
from taskflow_robots.camera import tinyrenderer_K

from taskflow.api import ObsSpec, Robot, StrictModel, array
from taskflow.registry import register_robot
from taskflow.spatial import R_FLU_OPTICAL, rotation_y, rotation_z, transform


class QuadCamera(StrictModel):
    """Forward camera: resolution, vertical field of view (rad), frame rate and its mount ``eT_c``.

    ``xyz`` is ``et_c`` (m, body frame); ``pitch`` tilts the optical axis down (rad, 0 = horizontal).
    Intrinsics follow PyBullet's TinyRenderer: ``fx = fy = H / (2 tan(fovy/2))``, principal point
    ``(W/2, H/2 - 1)`` (SIMULATOR_NOTES.md).  The paper's Bebop 2 streams 856x480; 320x240 is the
    default here for speed (rendering ~20–35 ms per frame).
    """

    width: int = Field(default=320, gt=15, le=4096, description="px: 16 (feature points need pixels) to 4096 "
                       "(TinyRenderer's largest image)")
    height: int = Field(default=240, gt=15, le=4096, description="px, as width")
    fovy: float = Field(default=math.radians(60.0), gt=0.05, lt=math.pi - 0.05,
                        description="vertical field of view (rad): a pinhole camera has 0 < fov < pi (at pi the "
                        "focal length is 0); kept 0.05 rad from both ends")
    rate_hz: float = Field(default=25.0, ge=1.0, le=120.0, description="frame rate (Hz): 1-120; the Bebop 2 streams "
                           "30 fps; below 1 Hz the 25 Hz visual-servo law repeats one view for 25 ticks")
    xyz: tuple[float, float, float] = Field(default=(0.17, 0.0, -0.03), description="camera origin in the body frame "
                                            "(m): each within ±1 m (on the drone)")
    pitch: float = Field(default=0.0, ge=-math.pi / 2, le=math.pi / 2, description="rad: from straight down to straight up")
    near: float = Field(default=0.03, gt=0.0, le=1.0, description="near clip plane (m): > 0, at most 1 m")
    far: float = Field(default=30.0, gt=0.0, le=1000.0, description="far clip plane (m): beyond near, at most 1 km")

    @model_validator(mode="after")
    def _range(self) -> QuadCamera:
        if not self.near < self.far:
            raise ValueError(f"camera near ({self.near}) must be < far ({self.far})")
        if max(abs(x) for x in self.xyz) > 1.0:
            raise ValueError(f"the camera sits on the drone: each xyz within ±1 m, got {list(self.xyz)}")
        return self

    def K(self) -> NDArray[np.float64]:
        """3x3 intrinsic matrix in pixels."""
        return tinyrenderer_K(self.width, self.height, self.fovy)

    def R_body_camera(self) -> NDArray[np.float64]:
        """``eR_c``: rotation body ← optical frame (the optical axis pitched down by ``pitch``)."""
        return rotation_y(self.pitch) @ R_FLU_OPTICAL

    def t_body_camera(self) -> NDArray[np.float64]:
        """``et_c``: camera origin in the body frame (m)."""
        return np.asarray(self.xyz, dtype=np.float64)

    def T_body_camera(self) -> NDArray[np.float64]:
        """``eT_c`` as a 4x4 transform: body ← optical frame."""
        return transform(self.R_body_camera(), self.t_body_camera())

    def pose_in_world(self, pose: tuple[float, float, float, float] | list[float]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(R_world_camera, t_world_camera)`` of this camera on a body at ``pose = (x, y, z, yaw)``
        (the quadcopter flies level: its body frame is turned by ``yaw`` about the world z only)."""
        x, y, z, yaw = pose
        R_world_body = rotation_z(yaw)
        return R_world_body @ self.R_body_camera(), np.array([x, y, z]) + R_world_body @ self.t_body_camera()


class QuadcopterParams(StrictModel):
    """Velocity-loop lag, limits, look and camera of the quadcopter."""

    tau: float = Field(default=0.15, ge=0.0, le=5.0, description="first-order lag of the velocity loop (s): at "
                       "most 5 s (a drone that slow cannot follow a visual-servo command at all)")
    v_max: float = Field(default=1.0, ge=0.05, le=5.0, description="|vx|, |vy|, |vz| limit (m/s): 0.05-5 (indoors; "
                         "the Bebop 2 flies up to 16 m/s outdoors); below 0.05 m/s the saturation, not the visual-servo "
                         "law, sets every command and a 1 m leg of the path takes over 20 s")
    wz_max: float = Field(default=math.radians(100.0), ge=0.05, le=3.5, description="|wz| limit (rad/s): 0.05 to "
                          "3.5 (the Bebop 2's 200 deg/s top yaw rate)")
    scale: float = Field(default=0.75, gt=0.05, le=3.0, description="scale of the iris mesh and shapes")
    camera: QuadCamera = Field(default=QuadCamera(), description="the forward camera")


@register_robot("quadcopter")
class Quadcopter(Robot):
    """Quadcopter commanded with ``nu = [vx, vy, vz, wz]`` (m/s, rad/s) in its body frame."""

    Params: ClassVar[type[QuadcopterParams]] = QuadcopterParams
    command_interface: ClassVar[str] = "body_velocity"
    command_keys: ClassVar[dict[str, int]] = {"nu": 4}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {
        "nu": (("v_x", "m/s"), ("v_y", "m/s"), ("v_z", "m/s"), ("w_z", "rad/s"))}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.nu": array(4)}
    sensors: ClassVar[dict[str, str]] = {"camera": "rgb_camera"}

    params: QuadcopterParams

    def saturate(self, nu: NDArray[np.float64]) -> NDArray[np.float64]:
        """Clip a command to the velocity limits (each axis separately)."""
        p = self.params
        lim = np.array([p.v_max, p.v_max, p.v_max, p.wz_max])
        return np.clip(np.asarray(nu, dtype=np.float64).reshape(4), -lim, lim)

    def T_body_camera(self) -> NDArray[np.float64]:
        """``eT_c`` (4x4): body ← camera optical frame.  Eq. (5)'s 6x6 twist map camera → body is
        ``taskflow.spatial.twist_adjoint(robot.T_body_camera())``."""
        return self.params.camera.T_body_camera()
