"""``mobile_iiwa``: an omnidirectional platform carrying a KUKA LBR iiwa with a screwdriver, and an
eye-to-hand camera fixed on the platform — the robot of the screw-fastening paper (section 8).

Pure description (no simulator): parameters, limits, command layout, the run-time URDF shared by
PyBullet and Pinocchio (:mod:`taskflow_robots.iiwa_urdf`) and the Pinocchio kinematics the tasks use.

Frames: ``b`` platform base (centre of the footprint on the ground, x forward, y left, z up),
``a`` arm base (``H_ba`` = ``arm_mount``), ``c`` camera optical frame (``H_bc`` = ``camera.mount``;
x right, y down, z along the view), ``e`` screwdriver tip (``tool_tip``; z along the tool).

Commands (``command_keys``):

* ``base_twist`` = ``(v_x, v_y, ω_z)`` in the base frame (m/s, rad/s), saturated to ``v_max``/``w_max``;
* ``arm_dq`` = joint position increments (rad) added to the arm's joint reference this tick — the
  world ramps the reference over the tick and servoes the joints to it (the iiwa's 250 Hz position
  interface).  All zeros holds the arm where its reference is, which is what :meth:`stop_command`
  sends: the platform stops and the arm holds.
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import ConfigDict, Field, field_validator, model_validator

from taskflow_robots.iiwa_urdf import IiwaKinematics, UrdfSpec, build_urdf_text, kinematics_for
from taskflow.api import ObsSpec, Robot, StrictModel, array
from taskflow.registry import register_robot
from taskflow_robots.camera import focal_px, tinyrenderer_K
from taskflow.spatial import rpy_from_rotation, transform_from_xyz_rpy

Vec3 = tuple[float, float, float]


def _finite3(name: str, v: object) -> Vec3:
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ValueError(f"{name} needs 3 numbers, got {v!r}")
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
            raise ValueError(f"{name} values must be finite numbers, got {x!r}")
        out.append(float(x))
    return (out[0], out[1], out[2])


class Pose(StrictModel):
    """A rigid pose: ``xyz`` (m) and URDF ``rpy`` (rad).

    In YAML: ``{xyz: [x, y, z], rpy: [r, p, y]}``, ``{xyz: [...], rpy_deg: [...]}`` or the list
    ``[x, y, z, roll, pitch, yaw]`` (m, rad).
    """

    xyz: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="before")
    @classmethod
    def _forms(cls, v: Any) -> Any:
        if isinstance(v, Pose):
            return v
        if isinstance(v, (list, tuple)):
            if len(v) != 6:
                raise ValueError(f"a pose list needs 6 numbers [x, y, z, roll, pitch, yaw], got {len(v)}")
            return {"xyz": list(v[:3]), "rpy": list(v[3:])}
        if isinstance(v, dict):
            if "rpy_deg" in v:
                if "rpy" in v:
                    raise ValueError("give either rpy (rad) or rpy_deg, not both")
                d = dict(v)
                rd = _finite3("rpy_deg", d.pop("rpy_deg"))
                d["rpy"] = [math.radians(a) for a in rd]
                return d
            return v
        raise ValueError(f"a pose is {{xyz: [..], rpy: [..]}}, {{xyz, rpy_deg}} or [x, y, z, r, p, y]; got {type(v).__name__}")

    @field_validator("xyz", "rpy", mode="before")
    @classmethod
    def _three(cls, v: object, info) -> Vec3:  # type: ignore[no-untyped-def]
        return _finite3(info.field_name, v)

    def matrix(self) -> NDArray[np.float64]:
        """``T_parent_frame`` of this pose (4x4)."""
        return transform_from_xyz_rpy(self.xyz, self.rpy)

    @classmethod
    def from_matrix(cls, H: NDArray[np.float64]) -> "Pose":
        return cls(xyz=tuple(float(x) for x in H[:3, 3]), rpy=rpy_from_rotation(H[:3, :3]))  # type: ignore[arg-type]


class CameraParams(StrictModel):
    """The eye-to-hand camera: mount ``H_bc`` (optical frame), image size, vertical FOV (rad), rate.

    Default: 640x480 at 40 Hz (the paper's marker rate), a narrow 32° vertical field of view so the
    10 cm marker spans ~120 px at 0.65 m; mounted on a mast at the platform's front-left corner,
    looking 48° down at the part's marker 0.67 m away.
    """

    model_config = ConfigDict(allow_inf_nan=False)  # every number finite

    mount: Pose = Pose(xyz=(0.45, 0.40, 1.35), rpy=(-2.41075, 0.0, -2.24554))
    width: int = Field(default=640, gt=0)
    height: int = Field(default=480, gt=0)
    fov: float = Field(default=math.radians(32.0), gt=0.0, lt=math.pi)
    rate_hz: float = Field(default=40.0, gt=0.0)
    near: float = Field(default=0.05, gt=0.0)
    far: float = Field(default=5.0, gt=0.0)

    @model_validator(mode="after")
    def _clip(self) -> "CameraParams":
        if self.far <= self.near:
            raise ValueError(f"the far clip plane ({self.far} m) must lie beyond the near one ({self.near} m)")
        return self

    def focal_px(self) -> float:
        """``fx = fy = H / (2 tan(fovy / 2))`` (the FOV is vertical)."""
        return focal_px(self.height, self.fov)

    def K(self) -> NDArray[np.float64]:
        """TinyRenderer's intrinsics (principal point ``(W/2, H/2 − 1)``, SIMULATOR_NOTES.md)."""
        return tinyrenderer_K(self.width, self.height, self.fov)


class ToolParams(StrictModel):
    """The screwdriver: geometry (m, kg), activation time (s) and coupling tolerances.

    Coupling succeeds when, throughout activation, the bit's axis is within ``tol_t`` of the bolt's
    axis (lateral), its tip within ``tol_axial`` of the head, and its axis within ``tol_r`` (rad) of the
    bolt's; while fastening, the bit slips off when the lateral error exceeds ``slip_t``.
    """

    model_config = ConfigDict(allow_inf_nan=False)  # every number finite

    length: float = Field(default=0.15, gt=0.0)
    radius: float = Field(default=0.025, gt=0.0)
    bit_radius: float = Field(default=0.004, gt=0.0)
    bit_length: float = Field(default=0.03, gt=0.0)
    mass: float = Field(default=0.6, gt=0.0)
    activation_s: float = Field(default=1.0, gt=0.0)
    tol_t: float = Field(default=0.003, gt=0.0)
    tol_axial: float = Field(default=0.003, gt=0.0)
    tol_r: float = Field(default=math.radians(3.0), gt=0.0, lt=0.5 * math.pi)
    slip_t: float = Field(default=0.005, gt=0.0)

    @model_validator(mode="after")
    def _bit(self) -> "ToolParams":
        if self.bit_length >= self.length:
            raise ValueError(f"bit_length ({self.bit_length}) must be shorter than the tool ({self.length})")
        if self.slip_t < self.tol_t:
            raise ValueError(f"slip_t ({self.slip_t}) must be at least the coupling tolerance tol_t ({self.tol_t}): "
                             "a bit coupled within tol_t would otherwise count as slipped off at once")
        return self


_Q_HOME = (0.0, -0.35, 0.0, -1.74, 0.0, 1.75, 0.0)  # tool tip at b (0.55, 0, 1.10), pointing down


class MobileIiwaParams(StrictModel):
    """Platform limits, arm mount ``H_ba``, camera ``H_bc``, tool, home configuration and DLS damping."""

    model_config = ConfigDict(allow_inf_nan=False)  # every number finite

    v_max: float = Field(default=1.0, gt=0.0, le=1.0, description="platform speed limit (m/s), paper: 1.0")
    w_max: float = Field(default=1.0, gt=0.0, description="platform yaw-rate limit (rad/s)")
    accel_max: float = Field(default=1.0, gt=0.0, description="platform acceleration limit (m/s²)")
    brake_decel: float = Field(default=2.0, gt=0.0, description="platform deceleration of a safe stop (m/s²): "
                               "rest within v_max / brake_decel s")
    platform_size: Vec3 = (1.0, 0.7, 0.55)
    arm_mount: Pose = Pose(xyz=(0.30, 0.0, 0.55))
    camera: CameraParams = CameraParams()
    tool: ToolParams = ToolParams()
    q_home: tuple[float, ...] = _Q_HOME
    qd_max: float = Field(default=1.5, gt=0.0, description="joint speed limit of the arm command (rad/s)")
    dls_damping: float = Field(default=0.02, ge=0.0, description="λ of the damped least-squares J⁺")

    @field_validator("platform_size")
    @classmethod
    def _size(cls, v: Vec3) -> Vec3:
        if not all(x > 0.0 for x in v):
            raise ValueError(f"platform_size needs 3 lengths > 0 (m), got {v}")
        return v

    @field_validator("q_home")
    @classmethod
    def _q7(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if len(v) != 7 or not all(math.isfinite(x) for x in v):
            raise ValueError(f"q_home needs 7 finite joint angles (rad), got {len(v)}")
        return v

    def urdf_spec(self) -> UrdfSpec:
        t = self.tool
        return UrdfSpec(arm_xyz=self.arm_mount.xyz, arm_rpy=self.arm_mount.rpy, camera_xyz=self.camera.mount.xyz,
                        camera_rpy=self.camera.mount.rpy, platform_size=self.platform_size, tool_length=t.length,
                        tool_radius=t.radius, bit_radius=t.bit_radius, bit_length=t.bit_length, tool_mass=t.mass)

    def H_ba(self) -> NDArray[np.float64]:
        return self.arm_mount.matrix()

    def H_bc(self) -> NDArray[np.float64]:
        return self.camera.mount.matrix()


@register_robot("mobile_iiwa")
class MobileIiwa(Robot):
    """Holonomic platform (``base_twist``) + 7-DoF arm (``arm_dq``) + screwdriver + platform camera."""

    Params: ClassVar[type[MobileIiwaParams]] = MobileIiwaParams
    command_interface: ClassVar[str] = "base_arm"
    command_keys: ClassVar[dict[str, int]] = {"base_twist": 3, "arm_dq": 7}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {
        "base_twist": (("v_x", "m/s"), ("v_y", "m/s"), ("w_z", "rad/s")),
        "arm_dq": tuple((f"dq_{j}", "rad") for j in range(1, 8))}
    observations: ClassVar[dict[str, ObsSpec]] = {"state.q": array(7), "state.qd": array(7), "state.q_ref": array(7),
                                                  "state.base_twist": array(3), "state.odom": array(3)}
    sensors: ClassVar[dict[str, str]] = {"camera": "rgb_camera"}

    params: MobileIiwaParams

    @cached_property
    def urdf_text(self) -> str:
        """The run-time URDF (absolute mesh paths, tool and camera frames); the sim writes it to a file."""
        return build_urdf_text(self.params.urdf_spec())

    @property
    def kinematics(self) -> IiwaKinematics:
        """Pinocchio kinematics of the same URDF (shared per distinct URDF text)."""
        return kinematics_for(self.urdf_text)
