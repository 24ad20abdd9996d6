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
from taskflow_robots.camera import focal_px, tinyrenderer_K
from taskflow_robots.iiwa_urdf import IiwaKinematics, UrdfSpec, build_urdf_text, kinematics_for

from taskflow.api import ObsSpec, Robot, StrictModel, array
from taskflow.registry import register_robot
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

    xyz: Vec3 = Field(description="m, in the parent frame: each within ±3 m (a part of the robot, on or beside "
                      "its 1 m platform)")
    rpy: Vec3 = Field(default=(0.0, 0.0, 0.0), description="URDF roll, pitch, yaw (rad): each within one turn either way")

    @model_validator(mode="after")
    def _on_the_robot(self) -> Pose:
        if max(abs(x) for x in self.xyz) > 3.0 or max(abs(a) for a in self.rpy) > 2.0 * math.pi:
            raise ValueError(f"a pose on the robot has each xyz within ±3 m and each rpy angle within ±2 pi rad, "
                             f"got xyz {list(self.xyz)}, rpy {list(self.rpy)}")
        return self

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
    def from_matrix(cls, H: NDArray[np.float64]) -> Pose:
        return cls(xyz=tuple(float(x) for x in H[:3, 3]), rpy=rpy_from_rotation(H[:3, :3]))  # type: ignore[arg-type]


class CameraParams(StrictModel):
    """The eye-to-hand camera: mount ``H_bc`` (optical frame), image size, vertical FOV (rad), rate.

    Default: 640x480 at 40 Hz (the paper's marker rate), a narrow 32° vertical field of view so the
    10 cm marker spans ~120 px at 0.65 m; mounted on a mast at the platform's front-left corner,
    looking 48° down at the part's marker 0.67 m away.
    """

    model_config = ConfigDict(allow_inf_nan=False)  # every number finite

    mount: Pose = Field(default=Pose(xyz=(0.45, 0.40, 1.35), rpy=(-2.41075, 0.0, -2.24554)),
                        description="H_bc: the optical frame in the platform frame b")
    width: int = Field(default=640, ge=16, le=4096, description="px: 16 (the marker needs pixels) to 4096 "
                       "(TinyRenderer's largest image)")
    height: int = Field(default=480, ge=16, le=4096, description="px, as width")
    fov: float = Field(default=math.radians(32.0), ge=0.05, le=math.pi - 0.05, description="vertical field of view "
                       "(rad): a pinhole camera has 0 < fov < pi (at pi the focal length is 0); kept 0.05 rad from both ends")
    rate_hz: float = Field(default=40.0, ge=1.0, le=120.0, description="marker rate (Hz; paper: 40): 1-120, what "
                           "industrial cameras deliver (the paper's IDS UI-5240CP: up to 50 fps)")
    near: float = Field(default=0.05, gt=0.0, le=1.0, description="near clip plane (m): > 0, at most 1 m")
    far: float = Field(default=5.0, gt=0.0, le=1000.0, description="far clip plane (m): beyond near, at most 1 km")

    @model_validator(mode="after")
    def _clip(self) -> CameraParams:
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

    length: float = Field(default=0.15, gt=0.0, le=0.5, description="m: at most 0.5 (a longer tool on the iiwa's "
                          "flange leaves the part's bolts out of the arm's reach from the platform)")
    radius: float = Field(default=0.025, gt=0.0, le=0.1, description="m: at most 0.1 (a wider tool hits the "
                          "neighbouring bolts, 4-12 cm apart on the default part)")
    bit_radius: float = Field(default=0.004, gt=0.0, le=0.02, description="m: at most 0.02, and within the tool")
    bit_length: float = Field(default=0.03, gt=0.0, le=0.2, description="m: shorter than the tool")
    mass: float = Field(default=0.6, gt=0.0, le=7.0, description="kg: at most 7, the LBR iiwa 7's payload")
    activation_s: float = Field(default=1.0, gt=0.0, le=60.0, description="s the coupling takes: at most 60")
    tol_t: float = Field(default=0.003, gt=0.0, le=0.02, description="lateral coupling tolerance (m): at most 2 cm; "
                         "beyond, a bit beside its bolt would count as coupled though it meets the part or the next bolt")
    tol_axial: float = Field(default=0.003, gt=0.0, le=0.02, description="axial coupling tolerance (m): at most 2 cm, "
                             "as tol_t")
    tol_r: float = Field(default=math.radians(3.0), gt=0.0, lt=0.5 * math.pi, description="angular coupling "
                         "tolerance (rad): below pi/2 (a bit across the bolt's axis does not engage it)")
    slip_t: float = Field(default=0.005, gt=0.0, le=0.02, description="lateral error at which the bit slips off (m): "
                          "at least tol_t, at most 2 cm")

    @model_validator(mode="after")
    def _bit(self) -> ToolParams:
        if self.bit_radius >= self.radius:
            raise ValueError(f"bit_radius ({self.bit_radius}) must be below the tool's radius ({self.radius})")
        if self.bit_length >= self.length:
            raise ValueError(f"bit_length ({self.bit_length}) must be shorter than the tool ({self.length})")
        if self.slip_t < self.tol_t:
            raise ValueError(f"slip_t ({self.slip_t}) must be at least the coupling tolerance tol_t ({self.tol_t}): "
                             "a bit coupled within tol_t would otherwise count as slipped off at once")
        return self


IIWA_JOINT_LIMITS_DEG = (170.0, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0)  # KUKA LBR iiwa 7 R800 datasheet
_Q_HOME = (0.0, -0.35, 0.0, -1.74, 0.0, 1.75, 0.0)  # tool tip at b (0.55, 0, 1.10), pointing down


class MobileIiwaParams(StrictModel):
    """Platform limits, arm mount ``H_ba``, camera ``H_bc``, tool, home configuration and DLS damping."""

    model_config = ConfigDict(allow_inf_nan=False)  # every number finite

    v_max: float = Field(default=1.0, gt=0.0, le=1.0, description="platform speed limit (m/s): at most the paper's "
                         "platform's 1.0")
    w_max: float = Field(default=1.0, gt=0.0, le=2.0, description="platform yaw-rate limit (rad/s): at most 2, what "
                         "wheels at the 1 m/s limit give the 1.0 x 0.7 m platform about its centre (1 / 0.61 m = 1.6 rad/s)")
    accel_max: float = Field(default=1.0, gt=0.0, le=5.0, description="platform acceleration limit (m/s²): at most 5, "
                             "half the grip mu g of its wheels")
    brake_decel: float = Field(default=2.0, gt=0.0, le=9.8, description="platform deceleration of a safe stop (m/s²): "
                               "rest within v_max / brake_decel s; at most the wheels' grip mu g = 9.8 m/s²")
    platform_size: Vec3 = Field(default=(1.0, 0.7, 0.55), description="length, width, height of the platform box "
                                "(m): each 0.1-3 m")
    arm_mount: Pose = Field(default=Pose(xyz=(0.30, 0.0, 0.55)), description="H_ba: the arm's base in the platform frame b")
    camera: CameraParams = Field(default=CameraParams(), description="the eye-to-hand camera")
    tool: ToolParams = Field(default=ToolParams(), description="the screwdriver")
    q_home: tuple[float, ...] = Field(default=_Q_HOME, description="the arm's home configuration (rad): 7 joint "
                                      "angles within the LBR iiwa's joint limits (±170, ±120, ±170, ±120, ±170, ±120, ±175 deg)")
    qd_max: float = Field(default=1.5, gt=0.0, le=3.14, description="joint speed limit of the arm command (rad/s): "
                          "at most 3.14, the LBR iiwa 7's fastest joint (180 deg/s)")
    dls_damping: float = Field(default=0.02, ge=0.0, le=1.0, description="λ of the damped least-squares J⁺: at most 1 "
                               "(J's singular values are below ~1 m: a larger λ damps every motion, not only the singular ones)")

    @field_validator("platform_size")
    @classmethod
    def _size(cls, v: Vec3) -> Vec3:
        if not all(0.1 <= x <= 3.0 for x in v):
            raise ValueError(f"platform_size needs 3 lengths of 0.1-3 m, got {v}")
        return v

    @field_validator("q_home")
    @classmethod
    def _q7(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if len(v) != 7 or not all(math.isfinite(x) for x in v):
            raise ValueError(f"q_home needs 7 finite joint angles (rad), got {len(v)}")
        for j, (q, lim) in enumerate(zip(v, IIWA_JOINT_LIMITS_DEG), start=1):
            if abs(q) > math.radians(lim):
                raise ValueError(f"q_home joint {j} = {q:g} rad is beyond the LBR iiwa's ±{lim:g} deg limit")
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
    kinematics_model: ClassVar[type | None] = IiwaKinematics

    params: MobileIiwaParams

    @cached_property
    def urdf_text(self) -> str:
        """The run-time URDF (absolute mesh paths, tool and camera frames); the sim writes it to a file."""
        return build_urdf_text(self.params.urdf_spec())

    @property
    def kinematics(self) -> IiwaKinematics:
        """Pinocchio kinematics of the same URDF (shared per distinct URDF text)."""
        return kinematics_for(self.urdf_text)
