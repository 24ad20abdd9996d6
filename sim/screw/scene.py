"""The screw-fastening scene: a floor, a conveyor, the motor-cover part with its bolts (a layout in
``P``: the world's ``bolts`` parameter, :data:`BOLTS_XY` by default) and an ArUco marker, and the
mobile iiwa.

Part frame ``P``: centre of the part's top face, x along its length (the conveyor's direction at
yaw 0), z up.  The object frame ``o`` of the paper is the **marker frame** (OpenCV/ArUco convention:
origin at the marker's centre, x to the marker's right, y up in the marker image, z out of the
marker), which lies on the top face at ``MARKER_IN_P`` with the same axes as ``P``.  Bolt ``i``'s
operation frame ``t_i`` sits on the centre of its head's top, z pointing down into the part (the
screwdriver's approach direction) and x along −y_P, so the tool reaches it without turning its wrist
(``R_part_bolt = Rz(−90°) Rx(180°)``).

The marker is a textured OBJ quad with explicit UVs (a texture on a ``GEOM_BOX`` is not detected,
SIMULATOR_NOTES.md); the floor is a thin box (``plane.urdf`` makes TinyRenderer up to 5x slower).
The part is one static body (box and bolt heads as a compound shape, the marker quad as a fixed,
massless link) moved kinematically with ``resetBasePositionAndOrientation``; tool–part contact is
soft (``contactStiffness``/``contactDamping``).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from taskflow.spatial import inverse, quaternion_from_yaw, transform, transform_xyz_yaw

PART_SIZE = (0.40, 0.24, 0.13)  # length (x_P), width (y_P), height (m)
CONVEYOR_TOP = 0.72  # m; the part's top face is at CONVEYOR_TOP + PART_SIZE[2]
CONVEYOR_WIDTH = 0.40
CONVEYOR_LENGTH = 8.0
BOLT_RADIUS = 0.008
BOLT_HEIGHT = 0.008
BOLTS_XY = ((0.02, 0.06), (0.02, -0.06), (0.12, 0.06), (0.12, -0.06))  # the default layout, in P (m)
MARKER_SIZE = 0.10  # black square side (m)
MARKER_QUIET = 0.015  # white margin around it (m), rounded to whole texture pixels in marker_texture()
MARKER_IN_P = (-0.12, 0.0, 0.0005)
MARKER_ID = 7
MARKER_DICT = "DICT_4X4_50"

R_PART_BOLT = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # Rz(-90°) Rx(180°)


def part_top_height() -> float:
    return CONVEYOR_TOP + PART_SIZE[2]


NOMINAL_DISTANCE = 0.80  # platform origin → part frame, across the conveyor (m)


def nominal_platform(part: tuple[float, float, float]) -> tuple[float, float, float]:
    """The platform pose beside the part where the mission's ``H*_co`` was designed: facing the
    conveyor (yaw = part yaw + 90°), ``NOMINAL_DISTANCE`` from the part frame."""
    x, y, yaw = part
    th = yaw + 0.5 * math.pi
    return (x - NOMINAL_DISTANCE * math.cos(th), y - NOMINAL_DISTANCE * math.sin(th), th)


BoltLayout = tuple[tuple[float, float], ...]
"""Bolt centres ``(x, y)`` in the part frame ``P`` (m), one per bolt, in the world's bolt order."""


def bolt_layout_problem(bolts: BoltLayout) -> str | None:
    """What is wrong with a bolt layout (None: nothing): at least one bolt, every head wholly on the
    part's top face and off the marker (a head on it would hide it from the camera), no two heads closer
    than two bolt radii (centre to centre: touching or overlapping)."""
    if not bolts:
        return "the part needs at least one bolt"
    hx, hy = 0.5 * PART_SIZE[0] - BOLT_RADIUS, 0.5 * PART_SIZE[1] - BOLT_RADIUS
    for i, (x, y) in enumerate(bolts):
        if abs(x) > hx or abs(y) > hy:
            return (f"bolt {i} at ({x:g}, {y:g}) m is not on the part's top face: its centre must lie within "
                    f"|x| <= {hx:g} and |y| <= {hy:g} m of the face centre (a {PART_SIZE[0]:g} x {PART_SIZE[1]:g} m "
                    f"face, bolt radius {BOLT_RADIUS:g} m)")
    mx, my, _ = MARKER_IN_P
    reach = _texture_geometry()[2] + BOLT_RADIUS  # the marker quad's half side (with its quiet zone) + a head
    for i, (x, y) in enumerate(bolts):
        if abs(x - mx) < reach and abs(y - my) < reach:
            return (f"bolt {i} at ({x:g}, {y:g}) m covers the ArUco marker: the marker (with its white margin) spans "
                    f"x {mx - reach + BOLT_RADIUS:.3f}..{mx + reach - BOLT_RADIUS:.3f}, y {my - reach + BOLT_RADIUS:.3f}.."
                    f"{my + reach - BOLT_RADIUS:.3f} m, and a head must stay {BOLT_RADIUS:g} m clear of it")
    for i, (xi, yi) in enumerate(bolts):
        for j in range(i):
            xj, yj = bolts[j]
            d = math.hypot(xi - xj, yi - yj)
            if d < 2.0 * BOLT_RADIUS:
                return (f"bolts {j} and {i} are {d * 1e3:.1f} mm apart (centre to centre); two heads need at least "
                        f"{2e3 * BOLT_RADIUS:g} mm (two bolt radii)")
    return None


def T_part_bolts(bolts: BoltLayout = BOLTS_XY) -> list[NDArray[np.float64]]:
    """``T_part_bolt`` of every bolt of the layout ``bolts``: its operation frame (head top centre, z
    into the part)."""
    return [transform(R_PART_BOLT, (x, y, BOLT_HEIGHT)) for x, y in bolts]


def T_part_marker() -> NDArray[np.float64]:
    """``T_part_marker``: the marker frame in the part frame (a translation)."""
    return transform(np.eye(3), MARKER_IN_P)


def T_marker_bolts(bolts: BoltLayout = BOLTS_XY) -> list[NDArray[np.float64]]:
    """The true ``T_marker_bolt`` (the paper's ``H_ot_i``) of the layout ``bolts``: what a mission's
    ``screws`` parameter should hold."""
    T_marker_part = inverse(T_part_marker())
    return [T_marker_part @ T for T in T_part_bolts(bolts)]


TEXTURE_PX_PER_CELL = 64


def _texture_geometry(pixels_per_cell: int = TEXTURE_PX_PER_CELL) -> tuple[int, int, float]:
    """(marker side px, quiet-zone px, quad half size m): the quad is sized from whole texture pixels
    so the black square is exactly MARKER_SIZE (a rounding here is a scale bias in every pose)."""
    side = 6 * pixels_per_cell  # 4x4 bits + the black border
    quiet = round(side * MARKER_QUIET / MARKER_SIZE)
    half = 0.5 * MARKER_SIZE * (side + 2 * quiet) / side
    return side, quiet, half


def marker_texture(pixels_per_cell: int = TEXTURE_PX_PER_CELL) -> Path:
    """PNG of the ArUco marker with its white quiet zone (cached in $TMPDIR)."""
    import cv2

    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, MARKER_DICT))
    side, quiet, _ = _texture_geometry(pixels_per_cell)
    out = Path(tempfile.gettempdir()) / "taskflow_urdf" / f"aruco_{MARKER_DICT}_{MARKER_ID}_{side}_{quiet}.png"
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        img = d.generateImageMarker(MARKER_ID, side) if hasattr(d, "generateImageMarker") else cv2.aruco.generateImageMarker(d, MARKER_ID, side)
        img = cv2.copyMakeBorder(img, quiet, quiet, quiet, quiet, cv2.BORDER_CONSTANT, value=255)
        tmp = out.with_suffix(f".{os.getpid()}.png")
        cv2.imwrite(str(tmp), img)
        os.replace(tmp, out)
    return out


def marker_quad_obj() -> Path:
    """An OBJ quad of the marker's full size (with quiet zone), UVs mapping the image upright:
    image top → +y, image right → +x (so the marker frame is the ArUco frame)."""
    h = _texture_geometry()[2]
    out = Path(tempfile.gettempdir()) / "taskflow_urdf" / f"marker_quad_{h:.6f}.obj"
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        text = (
            f"v {-h} {-h} 0\nv {h} {-h} 0\nv {h} {h} 0\nv {-h} {h} 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
            "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
        )
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, out)
    return out


def _box(client: int, half: tuple[float, float, float], pos: tuple[float, float, float], rgba: tuple[float, ...],
         collide: bool = True) -> int:
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=client) if collide else -1
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=client)
    return int(p.createMultiBody(0.0, col, vis, basePosition=list(pos), physicsClientId=client))


@dataclass
class PartBodies:
    part: int
    marker: int  # the body carrying the marker quad (the part itself: link 0)


def add_floor_and_conveyor(client: int) -> tuple[int, int]:
    floor = _box(client, (6.0, 6.0, 0.01), (0.0, 0.0, -0.01), (0.55, 0.55, 0.5, 1.0))
    conveyor = _box(client, (0.5 * CONVEYOR_LENGTH, 0.5 * CONVEYOR_WIDTH, 0.5 * CONVEYOR_TOP),
                    (0.0, 0.0, 0.5 * CONVEYOR_TOP - 0.001), (0.25, 0.27, 0.3, 1.0), collide=False)
    return floor, conveyor


def add_part(client: int, contact_stiffness: float, contact_damping: float, bolts: BoltLayout = BOLTS_XY) -> PartBodies:
    """The part: box + the bolt heads of ``bolts`` (one static compound body) with the marker quad as link 0."""
    lx, ly, lz = PART_SIZE
    shapes_col = [dict(shapeType=p.GEOM_BOX, halfExtents=[0.5 * lx, 0.5 * ly, 0.5 * lz])]
    pos = [[0.0, 0.0, -0.5 * lz]]
    vis_kw = [dict(shapeType=p.GEOM_BOX, halfExtents=[0.5 * lx, 0.5 * ly, 0.5 * lz], rgbaColor=[0.55, 0.6, 0.65, 1.0])]
    for x, y in bolts:
        shapes_col.append(dict(shapeType=p.GEOM_CYLINDER, radius=BOLT_RADIUS, height=BOLT_HEIGHT))
        vis_kw.append(dict(shapeType=p.GEOM_CYLINDER, radius=BOLT_RADIUS, length=BOLT_HEIGHT, rgbaColor=[0.8, 0.7, 0.2, 1.0]))
        pos.append([x, y, 0.5 * BOLT_HEIGHT])
    col = p.createCollisionShapeArray(
        shapeTypes=[s["shapeType"] for s in shapes_col],
        halfExtents=[s.get("halfExtents", [0, 0, 0]) for s in shapes_col],
        radii=[s.get("radius", 0.0) for s in shapes_col],
        lengths=[s.get("height", 0.0) for s in shapes_col],
        collisionFramePositions=pos, physicsClientId=client)
    vis = p.createVisualShapeArray(
        shapeTypes=[s["shapeType"] for s in vis_kw],
        halfExtents=[s.get("halfExtents", [0, 0, 0]) for s in vis_kw],
        radii=[s.get("radius", 0.0) for s in vis_kw],
        lengths=[s.get("length", 0.0) for s in vis_kw],
        rgbaColors=[s["rgbaColor"] for s in vis_kw],
        visualFramePositions=pos, physicsClientId=client)
    mvis = p.createVisualShape(p.GEOM_MESH, fileName=str(marker_quad_obj()), meshScale=[1, 1, 1],
                               rgbaColor=[1, 1, 1, 1], physicsClientId=client)
    # the marker quad is a fixed, massless link of the part: one reset moves both
    part = p.createMultiBody(0.0, col, vis, basePosition=[0, 0, part_top_height()],
                             linkMasses=[0.0], linkCollisionShapeIndices=[-1], linkVisualShapeIndices=[mvis],
                             linkPositions=[list(MARKER_IN_P)], linkOrientations=[[0, 0, 0, 1]],
                             linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                             linkParentIndices=[0], linkJointTypes=[p.JOINT_FIXED], linkJointAxis=[[0, 0, 1]],
                             physicsClientId=client)
    p.changeDynamics(part, -1, contactStiffness=contact_stiffness, contactDamping=contact_damping,
                     lateralFriction=0.3, physicsClientId=client)
    tex = p.loadTexture(str(marker_texture()), physicsClientId=client)
    p.changeVisualShape(part, 0, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
    marker = part
    return PartBodies(part, marker)


def set_part_planar(client: int, bodies: PartBodies, x: float, y: float, yaw: float) -> None:
    """Place the part's frame ``P`` at ``(x, y, top height)`` with heading ``yaw`` (its marker follows)."""
    q = quaternion_from_yaw(yaw)
    p.resetBasePositionAndOrientation(bodies.part, [x, y, part_top_height()], q, physicsClientId=client)


def planar_pose(x: float, y: float, yaw: float, z: float) -> NDArray[np.float64]:
    """``T_world_frame`` of a frame at ``(x, y, z)`` turned by ``yaw`` about z."""
    return transform_xyz_yaw(x, y, z, yaw)
