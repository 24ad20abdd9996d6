"""PyBullet building blocks of the quadcopter worlds: an indoor room with seeded, generated textures,
column obstacles, the iris body, and the forward camera.

* Textures are generated at run time from the seed (random blobs, bars, rings and speckle in many
  colours — feature-rich for ORB/SIFT) and mapped on quad meshes with explicit UVs (a texture on a
  ``GEOM_BOX`` lands only partly on each face).  The obstacle colour (green by default) is kept out of
  every texture so colour segmentation finds only the obstacles.
* Walls, floor and ceiling also carry thin collision boxes, so the drone's clearance to them comes
  from ``getClosestPoints`` like its clearance to obstacles.  The floor is a thin box, never
  ``plane.urdf`` (5x slower to render).
* The iris URDF of example-robot-data is rewritten with absolute mesh paths (PyBullet does not resolve
  ``package://``) into the scene's temporary directory.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_robots.quadcopter import QuadCamera

from taskflow.spatial import quaternion_from_rotation, rotation_from_quaternion

OBSTACLE_RGB = (0.1, 0.8, 0.15)
"""Default column colour: a saturated green that no generated texture contains."""


def example_robot_data_dir() -> Path:
    """``.../share/example-robot-data/robots`` of the installed example-robot-data (files only)."""
    for base in map(Path, sys.path):
        cand = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if cand.is_dir():
            return cand
    raise FileNotFoundError("example-robot-data robots directory not found (is example-robot-data installed?)")


def iris_urdf(out_dir: Path) -> Path:
    """The iris URDF (fixed rotor joints) with ``package://`` mesh paths made absolute."""
    robots = example_robot_data_dir()
    src = robots / "iris_description" / "robots" / "iris_simple.urdf"
    text = src.read_text().replace("package://example-robot-data/robots/", str(robots) + "/")
    dst = out_dir / "iris.urdf"
    dst.write_text(text)
    return dst


# ---------------------------------------------------------------------------------------------
# textures


def _palette(rng: np.random.Generator, n: int, forbidden_hue: float, width: float = 50.0) -> NDArray[np.uint8]:
    """``n`` random BGR colours, none within ``width`` degrees of ``forbidden_hue`` unless nearly grey."""
    out = np.zeros((0, 3), dtype=np.uint8)
    while len(out) < n:
        c = rng.integers(0, 256, (2 * n, 3)).astype(np.uint8)
        hsv = cv2.cvtColor(c.reshape(-1, 1, 3), cv2.COLOR_BGR2HSV).reshape(-1, 3).astype(np.float64)
        dh = np.abs((hsv[:, 0] * 2.0 - forbidden_hue + 180.0) % 360.0 - 180.0)
        out = np.vstack((out, c[(dh > width) | (hsv[:, 1] < 40)]))
    return out[:n]


def generate_texture(rng: np.random.Generator, width: int, height: int, px_per_m: float,
                     forbidden_hue: float = 125.0) -> NDArray[np.uint8]:
    """A feature-rich BGR texture: speckled background, then circles, rectangles, bars and rings of
    sizes 3–40 cm (at ``px_per_m``), avoiding hues within 50° of ``forbidden_hue`` (degrees) unless nearly grey."""
    area = width * height / (px_per_m * px_per_m)  # m^2
    n = int(90 * area) + 20
    palette = _palette(rng, n + 1, forbidden_hue)
    base = palette[n].astype(np.float64)
    img = np.empty((height, width, 3), dtype=np.float64)
    img[:] = 0.6 * base + 0.4 * 200.0
    noise = rng.normal(0.0, 18.0, (height // 8 + 1, width // 8 + 1)).astype(np.float32)
    img += cv2.resize(noise, (width, height), interpolation=cv2.INTER_LINEAR)[..., None]
    out = np.clip(img, 0, 255).astype(np.uint8)
    for i in range(n):
        c = tuple(int(v) for v in palette[i])
        kind = rng.integers(0, 4)
        size = float(np.exp(rng.uniform(math.log(0.03), math.log(0.40)))) * px_per_m
        cx, cy = int(rng.integers(0, width)), int(rng.integers(0, height))
        if kind == 0:
            cv2.circle(out, (cx, cy), max(2, int(size / 2)), c, -1, cv2.LINE_AA)
        elif kind == 1:
            w, h = size, size * rng.uniform(0.3, 1.5)
            cv2.rectangle(out, (int(cx - w / 2), int(cy - h / 2)), (int(cx + w / 2), int(cy + h / 2)), c, -1)
        elif kind == 2:
            ang = rng.uniform(0, math.pi)
            dx, dy = math.cos(ang) * size, math.sin(ang) * size
            cv2.line(out, (int(cx - dx), int(cy - dy)), (int(cx + dx), int(cy + dy)), c,
                     max(2, int(size / 8)), cv2.LINE_AA)
        else:
            cv2.circle(out, (cx, cy), max(3, int(size / 2)), c, max(2, int(size / 10)), cv2.LINE_AA)
    return out


# ---------------------------------------------------------------------------------------------
# geometry helpers


def _quad_obj(path: Path, corners: NDArray[np.float64], uv_repeat: tuple[float, float] = (1.0, 1.0)) -> None:
    """An OBJ quad (two triangles) with UVs; corners in order (0,0) (1,0) (1,1) (0,1) of the texture."""
    su, sv = uv_repeat
    uvs = [(0.0, 0.0), (su, 0.0), (su, sv), (0.0, sv)]
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in corners]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in uvs]
    e1, e2 = corners[1] - corners[0], corners[3] - corners[0]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n)
    lines.append(f"vn {n[0]:.6f} {n[1]:.6f} {n[2]:.6f}")
    lines += ["f 1/1/1 2/2/1 3/3/1", "f 1/1/1 3/3/1 4/4/1"]
    path.write_text("\n".join(lines) + "\n")


@dataclass
class Column:
    """A vertical obstacle: box (``depth`` > 0) or cylinder (``depth`` == 0) of width ``width`` (m)."""

    x: float
    y: float
    width: float
    depth: float = 0.0
    height: float = 3.0
    yaw: float = 0.0


@dataclass
class Room:
    """Axis-aligned room ``[x0, x1] x [y0, y1] x [0, height]`` (m)."""

    x0: float = -1.5
    x1: float = 6.0
    y0: float = -3.0
    y1: float = 3.0
    height: float = 3.0


@dataclass
class QuadScene:
    """A PyBullet client holding the room, obstacles and the drone."""

    client: int
    tmp: Path
    drone: int
    walls: list[int] = field(default_factory=list)
    obstacles: list[int] = field(default_factory=list)
    camera: QuadCamera = field(default_factory=QuadCamera)
    inertial_offset: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def build(cls, room: Room, columns: list[Column], seed: int, camera: QuadCamera, scale: float = 0.75,
              gui: bool = False, texture_px_per_m: float = 160.0,
              obstacle_rgb: tuple[float, float, float] = OBSTACLE_RGB) -> QuadScene:
        client = p.connect(p.GUI if gui else p.DIRECT)
        if client < 0:
            raise RuntimeError("pybullet.connect failed")
        tmp = Path(tempfile.mkdtemp(prefix="taskflow_quad_"))
        try:
            p.resetSimulation(physicsClientId=client)
            if gui:
                p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=client)
            rng = np.random.default_rng(seed)
            bgr = np.asarray([[np.array(obstacle_rgb[::-1]) * 255]]).astype(np.uint8)
            hue = float(np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV))[0, 0, 0]) * 2
            walls = _build_room(client, tmp, room, rng, texture_px_per_m, hue)
            obstacles = [_build_column(client, c, obstacle_rgb) for c in columns]
            urdf = iris_urdf(tmp)
            drone = p.loadURDF(str(urdf), [0.0, 0.0, 1.0], useFixedBase=False, globalScaling=scale,
                               flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
            for j in range(-1, p.getNumJoints(drone, physicsClientId=client)):
                p.changeVisualShape(drone, j, rgbaColor=[0.15, 0.15, 0.18, 1.0], physicsClientId=client)
            off = np.asarray(p.getDynamicsInfo(drone, -1, physicsClientId=client)[3], dtype=np.float64)
        except Exception:
            p.disconnect(client)
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return cls(client, tmp, drone, walls, obstacles, camera, off)

    # -- the drone -------------------------------------------------------------------------------
    def set_drone_pose(self, x: float, y: float, z: float, yaw: float) -> None:
        """Place the body frame at ``(x, y, z)`` with heading ``yaw`` (kinematic)."""
        q = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        R_world_body = rotation_from_quaternion(q)
        pos = np.array([x, y, z]) + R_world_body @ self.inertial_offset
        p.resetBasePositionAndOrientation(self.drone, pos.tolist(), q, physicsClientId=self.client)

    def clearances(self, max_distance: float = 5.0) -> tuple[float, float]:
        """(min distance to an obstacle, min distance to a wall/floor/ceiling) in m; negative when
        penetrating; ``max_distance`` when nothing is nearer."""

        def nearest(bodies: list[int]) -> float:
            best = max_distance
            for b in bodies:
                pts = p.getClosestPoints(self.drone, b, max_distance, physicsClientId=self.client)
                for c in pts:
                    best = min(best, float(c[8]))
            return best

        return nearest(self.obstacles), nearest(self.walls)

    # -- the camera --------------------------------------------------------------------------------
    def _camera_image(self, pose: tuple[float, float, float, float], cam: QuadCamera) -> tuple[NDArray[np.uint8], Any]:
        R_world_camera, eye = cam.pose_in_world(pose)
        target = eye + R_world_camera[:, 2]
        up = -R_world_camera[:, 1]
        view = p.computeViewMatrix(eye.tolist(), target.tolist(), up.tolist())
        proj = p.computeProjectionMatrixFOV(math.degrees(cam.fovy), cam.width / cam.height, cam.near, cam.far)
        _, _, rgba, depth, _ = p.getCameraImage(cam.width, cam.height, view, proj, renderer=p.ER_TINY_RENDERER,
                                                flags=p.ER_NO_SEGMENTATION_MASK, shadow=0,
                                                physicsClientId=self.client)
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(cam.height, cam.width, 4)[:, :, :3].copy()
        return rgb, depth

    def render(self, pose: tuple[float, float, float, float], camera: QuadCamera | None = None) -> NDArray[np.uint8]:
        """RGB image (H, W, 3) of the forward camera with the body at ``pose = (x, y, z, yaw)``."""
        return self._camera_image(pose, camera or self.camera)[0]

    def render_with_depth(self, pose: tuple[float, float, float, float],
                          camera: QuadCamera | None = None) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
        """RGB image and metric depth along the optical axis, ``Z = f n / (f - (f - n) d)`` (m)."""
        cam = camera or self.camera
        rgb, d = self._camera_image(pose, cam)
        d = np.asarray(d, dtype=np.float64).reshape(cam.height, cam.width)
        n, f = cam.near, cam.far
        return rgb, f * n / (f - (f - n) * d)

    def close(self) -> None:
        try:
            p.disconnect(self.client)
        except p.error:  # already gone
            pass
        shutil.rmtree(self.tmp, ignore_errors=True)


def _build_room(client: int, tmp: Path, room: Room, rng: np.random.Generator, px_per_m: float,
                forbidden_hue: float) -> list[int]:
    x0, x1, y0, y1, h = room.x0, room.x1, room.y0, room.y1, room.height
    # corners ordered so the texture's u runs along the surface and v upward/inward
    surfaces = {
        "front": np.array([[x1, y1, 0], [x1, y0, 0], [x1, y0, h], [x1, y1, h]], dtype=float),
        "back": np.array([[x0, y0, 0], [x0, y1, 0], [x0, y1, h], [x0, y0, h]], dtype=float),
        "left": np.array([[x0, y1, 0], [x1, y1, 0], [x1, y1, h], [x0, y1, h]], dtype=float),
        "right": np.array([[x1, y0, 0], [x0, y0, 0], [x0, y0, h], [x1, y0, h]], dtype=float),
        "floor": np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], dtype=float),
        "ceiling": np.array([[x0, y1, h], [x1, y1, h], [x1, y0, h], [x0, y0, h]], dtype=float),
    }
    bodies = []
    for name, corners in surfaces.items():
        w = float(np.linalg.norm(corners[1] - corners[0]))
        hh = float(np.linalg.norm(corners[3] - corners[0]))
        scale = px_per_m if name not in ("floor", "ceiling") else 0.5 * px_per_m
        tex = generate_texture(rng, max(16, int(w * scale)), max(16, int(hh * scale)), scale, forbidden_hue)
        if name == "floor":
            tex = (0.75 * tex).astype(np.uint8)
        png = tmp / f"{name}.png"
        cv2.imwrite(str(png), tex)
        # one static body per surface: a thin collision slab just behind it, the textured quad as its
        # visual (a body without a visual shape would be drawn from its collision box: z-fighting)
        n = np.cross(corners[1] - corners[0], corners[3] - corners[0])
        n /= np.linalg.norm(n)
        ex = (corners[1] - corners[0]) / w
        ey = (corners[3] - corners[0]) / hh
        R = np.column_stack((ex, ey, n))
        centre = corners.mean(axis=0) - 0.01 * n
        obj = tmp / f"{name}.obj"
        _quad_obj(obj, (corners - centre) @ R)  # vertices in the body frame
        vis = p.createVisualShape(p.GEOM_MESH, fileName=str(obj), physicsClientId=client)
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.5 * w, 0.5 * hh, 0.01], physicsClientId=client)
        body = p.createMultiBody(0.0, col, vis, centre.tolist(), quaternion_from_rotation(R), physicsClientId=client)
        tid = p.loadTexture(str(png), physicsClientId=client)
        p.changeVisualShape(body, -1, textureUniqueId=tid, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
        bodies.append(body)
    return bodies




def _build_column(client: int, c: Column, rgb: tuple[float, float, float]) -> int:
    if c.depth > 0.0:
        half = [0.5 * c.depth, 0.5 * c.width, 0.5 * c.height]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=[*rgb, 1.0], physicsClientId=client)
    else:
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=0.5 * c.width, height=c.height, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_CYLINDER, radius=0.5 * c.width, length=c.height, rgbaColor=[*rgb, 1.0],
                                  physicsClientId=client)
    quat = p.getQuaternionFromEuler([0.0, 0.0, c.yaw])
    return int(p.createMultiBody(0.0, col, vis, [c.x, c.y, 0.5 * c.height], quat, physicsClientId=client))


def cleanup_dir(path: str | os.PathLike[str]) -> None:
    shutil.rmtree(path, ignore_errors=True)
