"""The mobile iiwa's URDF, built at run time, and its Pinocchio kinematics.

PyBullet (in ``sim/``) and Pinocchio (here, for the tasks) load **one and the same URDF text**:

* the installed ``pybullet_data/kuka_iiwa/model.urdf`` (the paper's KUKA LBR iiwa 7), with every mesh
  path made absolute (PyBullet does not resolve relative paths against a temporary file);
* a root link ``platform`` (the omnidirectional platform's base frame ``b``: centre of its footprint
  on the ground, x forward, z up) joined to ``lbr_iiwa_link_0`` by the fixed joint ``arm_mount``
  (``T_body_arm``);
* the screwdriver: link ``screwdriver`` on the fixed joint ``tool_joint`` at the flange (0.045 m
  beyond ``lbr_iiwa_link_7`` along its z), and the massless frame ``tool_tip`` (``e``) at the end of
  the bit, z along the tool axis;
* the camera: link ``camera_optical`` on the fixed joint ``camera_mount`` (``T_body_camera``), OpenCV optical
  axes (x right, y down, z along the view).

The installed file is located without importing ``pybullet_data`` (``importlib.util.find_spec``
only finds the package directory), so ``robots/`` stays free of simulator imports.  The text is
written once per distinct content to ``$TMPDIR/taskflow_urdf/<sha1>.urdf``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

ARM_JOINTS = tuple(f"lbr_iiwa_joint_{i}" for i in range(1, 8))
TOOL_JOINT = "tool_joint"
TOOL_TIP = "tool_tip"
CAMERA_LINK = "camera_optical"
PLATFORM_LINK = "platform"
FLANGE_OFFSET = 0.045  # lbr_iiwa_link_7 origin → flange face (m)


def installed_iiwa_urdf() -> Path:
    """``pybullet_data/kuka_iiwa/model.urdf`` of the installed pybullet, found without importing it."""
    spec = importlib.util.find_spec("pybullet_data")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("pybullet_data is not installed: cannot find kuka_iiwa/model.urdf")
    for loc in spec.submodule_search_locations:
        path = Path(loc) / "kuka_iiwa" / "model.urdf"
        if path.is_file():
            return path
    raise FileNotFoundError("kuka_iiwa/model.urdf not found in pybullet_data")


def _fmt(v: float) -> str:
    return repr(float(v))


def _origin(parent: ET.Element, xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> None:
    ET.SubElement(parent, "origin", xyz=" ".join(map(_fmt, xyz)), rpy=" ".join(map(_fmt, rpy)))


def _inertial(link: ET.Element, mass: float, xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
              inertia: float = 1e-6) -> None:
    inert = ET.SubElement(link, "inertial")
    _origin(inert, xyz, (0.0, 0.0, 0.0))
    ET.SubElement(inert, "mass", value=_fmt(mass))
    ET.SubElement(inert, "inertia", ixx=_fmt(inertia), ixy="0", ixz="0", iyy=_fmt(inertia), iyz="0", izz=_fmt(inertia))


def _shape(link: ET.Element, tag: str, geom: str, xyz: tuple[float, float, float], rgba: str | None = None,
           **attrs: str) -> None:
    el = ET.SubElement(link, tag)
    _origin(el, xyz, (0.0, 0.0, 0.0))
    g = ET.SubElement(ET.SubElement(el, "geometry"), geom, attrs)
    del g
    if rgba is not None and tag == "visual":
        mat = ET.SubElement(el, "material", name=f"{link.get('name')}_{geom}_{len(link)}")
        ET.SubElement(mat, "color", rgba=rgba)


def _fixed(root: ET.Element, name: str, parent: str, child: str, xyz: tuple[float, float, float],
           rpy: tuple[float, float, float]) -> None:
    j = ET.SubElement(root, "joint", name=name, type="fixed")
    ET.SubElement(j, "parent", link=parent)
    ET.SubElement(j, "child", link=child)
    _origin(j, xyz, rpy)


@dataclass(frozen=True)
class UrdfSpec:
    """What the run-time URDF adds to the installed arm (all lengths m, angles rad)."""

    arm_xyz: tuple[float, float, float] = (0.30, 0.0, 0.55)
    arm_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    camera_xyz: tuple[float, float, float] = (0.45, 0.40, 1.35)
    camera_rpy: tuple[float, float, float] = (-2.41075, 0.0, -2.24554)
    platform_size: tuple[float, float, float] = (1.0, 0.7, 0.55)
    tool_length: float = 0.15
    tool_radius: float = 0.025
    bit_radius: float = 0.004
    bit_length: float = 0.03
    tool_mass: float = 0.6


def build_urdf_text(spec: UrdfSpec, source: Path | None = None) -> str:
    """The combined platform + iiwa + screwdriver + camera URDF as text."""
    src = source or installed_iiwa_urdf()
    tree = ET.parse(src)
    arm = tree.getroot()
    mesh_dir = src.parent
    for mesh in arm.iter("mesh"):
        fn = mesh.get("filename", "")
        if fn and not os.path.isabs(fn):
            mesh.set("filename", str((mesh_dir / fn).resolve()))
    root = ET.Element("robot", name="mobile_iiwa")
    # the platform first: the first link is the root for both PyBullet and Pinocchio
    plat = ET.SubElement(root, "link", name=PLATFORM_LINK)
    _inertial(plat, 100.0, inertia=10.0)
    sx, sy, sz = spec.platform_size
    _shape(plat, "visual", "box", (0.0, 0.0, 0.5 * sz), rgba="0.85 0.85 0.8 1", size=f"{sx} {sy} {sz}")
    for el in arm:
        root.append(el)
    # lbr_iiwa_link_0 carries an inertial offset (-0.1, 0, 0.07) and mass 0; as a child link it is fine
    _fixed(root, "arm_mount", PLATFORM_LINK, "lbr_iiwa_link_0", spec.arm_xyz, spec.arm_rpy)
    # the screwdriver, z along the tool axis, origin at the flange
    tool = ET.SubElement(root, "link", name="screwdriver")
    body = spec.tool_length - spec.bit_length
    _inertial(tool, spec.tool_mass, (0.0, 0.0, 0.5 * body), inertia=1e-3)
    _shape(tool, "visual", "cylinder", (0.0, 0.0, 0.5 * body), rgba="0.15 0.15 0.15 1",
           radius=_fmt(spec.tool_radius), length=_fmt(body))
    _shape(tool, "visual", "cylinder", (0.0, 0.0, body + 0.5 * spec.bit_length), rgba="0.7 0.7 0.75 1",
           radius=_fmt(spec.bit_radius), length=_fmt(spec.bit_length))
    _shape(tool, "collision", "cylinder", (0.0, 0.0, 0.5 * body), radius=_fmt(spec.tool_radius), length=_fmt(body))
    _shape(tool, "collision", "cylinder", (0.0, 0.0, body + 0.5 * spec.bit_length),
           radius=_fmt(spec.bit_radius), length=_fmt(spec.bit_length))
    _fixed(root, TOOL_JOINT, "lbr_iiwa_link_7", "screwdriver", (0.0, 0.0, FLANGE_OFFSET), (0.0, 0.0, 0.0))
    tip = ET.SubElement(root, "link", name=TOOL_TIP)
    _inertial(tip, 1e-4)
    _fixed(root, "tool_tip_joint", "screwdriver", TOOL_TIP, (0.0, 0.0, spec.tool_length), (0.0, 0.0, 0.0))
    cam = ET.SubElement(root, "link", name=CAMERA_LINK)
    _inertial(cam, 1e-4)
    _fixed(root, "camera_mount", PLATFORM_LINK, CAMERA_LINK, spec.camera_xyz, spec.camera_rpy)
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_urdf(text: str) -> Path:
    """Write the URDF text to a content-addressed file (reused across runs) and return its path."""
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    d = Path(tempfile.gettempdir()) / "taskflow_urdf"
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"mobile_iiwa_{digest}.urdf"
    if not path.exists():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path


class IiwaKinematics:
    """Pinocchio model of the arm on the platform (root = platform frame ``b``, 7 revolute joints).

    ``fk(q)`` → ``T_body_tip`` (4x4, tool tip in the base frame); ``jacobian(q)`` → 6x7 in the paper's
    ``[ω; v]`` order, expressed in the base frame at the tool tip (Pinocchio's
    ``LOCAL_WORLD_ALIGNED``, rows swapped from its ``[v; ω]``); ``fk_jacobian`` gives both with one
    kinematics pass.
    """

    def __init__(self, urdf_text: str, frame: str = TOOL_TIP) -> None:
        import pinocchio as pin  # local: keeps `import taskflow_robots.mobile_iiwa` light

        self._pin = pin
        self.model = pin.buildModelFromXML(urdf_text)
        self.data = self.model.createData()
        names = [self.model.names[i] for i in range(1, self.model.njoints)]
        if tuple(names) != ARM_JOINTS:
            raise ValueError(f"unexpected joint order in the URDF: {names}")
        if not self.model.existFrame(frame):
            raise ValueError(f"frame {frame!r} not in the URDF")
        self.frame_id = self.model.getFrameId(frame)
        self.nq = self.model.nq
        self.lower = np.array(self.model.lowerPositionLimit)
        self.upper = np.array(self.model.upperPositionLimit)
        self._lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        self._swap = np.r_[3:6, 0:3]

    def frame_pose(self, q: NDArray[np.float64], frame: str) -> NDArray[np.float64]:
        pin = self._pin
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=np.float64))
        T: NDArray[np.float64] = self.data.oMf[self.model.getFrameId(frame)].homogeneous.copy()
        return T

    def fk(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        pin = self._pin
        pin.framesForwardKinematics(self.model, self.data, q)
        T: NDArray[np.float64] = self.data.oMf[self.frame_id].homogeneous.copy()
        return T

    def jacobian(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        J = self._pin.computeFrameJacobian(self.model, self.data, q, self.frame_id, self._lwa)
        J_swapped: NDArray[np.float64] = J[self._swap]
        return J_swapped

    def fk_jacobian(self, q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        pin = self._pin
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacement(self.model, self.data, self.frame_id)
        J = pin.getFrameJacobian(self.model, self.data, self.frame_id, self._lwa)
        return self.data.oMf[self.frame_id].homogeneous.copy(), J[self._swap]


@lru_cache(maxsize=8)
def kinematics_for(urdf_text: str) -> IiwaKinematics:
    """One Pinocchio model per distinct URDF text (models are reused across tasks and runs)."""
    return IiwaKinematics(urdf_text)

