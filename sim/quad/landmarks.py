"""Geometric (fast) camera of the ``quad_room`` world: textured surfaces as landmark points, columns
as silhouettes, projected exactly and perturbed with pixel noise — no rendering.

What the rendered pipeline gets from pixels (ORB keypoints matched to a keyframe, the green blob of a
column), this module gets from geometry: every landmark has an id, so correspondences between a view
and a keyframe are the ids both see; a column's silhouette gives the same edge points ``p1``, ``p2``
at the image's middle row that :func:`taskflow_tasks.quad.perception.obstacle_edges` measures.

* Landmarks are drawn uniformly on the walls, floor and ceiling (``density`` per m², seeded): the
  rendered room's textures are feature-rich everywhere, the columns plain.
* A landmark is seen when it is in front of the camera, inside the image (``margin`` px) and no
  column stands between it and the camera (columns are vertical prisms from the floor to their
  height; the room is convex, so walls hide nothing else).
* Pixel noise: Gaussian, ``pixel_noise`` px per coordinate, drawn per frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray
from taskflow_sim.quad.scene import Column, Room

from taskflow.spatial import planar_apply, planar_apply_inverse

Array = NDArray[np.float64]


def sample_landmarks(room: Room, density: float, rng: np.random.Generator) -> Array:
    """Points (N, 3) drawn uniformly on the four walls, the floor and the ceiling, ``density`` per m²."""
    x0, x1, y0, y1, h = room.x0, room.x1, room.y0, room.y1, room.height
    lx, ly = x1 - x0, y1 - y0
    faces: list[tuple[float, Callable[[int], Array]]] = [  # (area, sampler of n points)
        (lx * h, lambda n: np.column_stack((rng.uniform(x0, x1, n), np.full(n, y0), rng.uniform(0, h, n)))),
        (lx * h, lambda n: np.column_stack((rng.uniform(x0, x1, n), np.full(n, y1), rng.uniform(0, h, n)))),
        (ly * h, lambda n: np.column_stack((np.full(n, x0), rng.uniform(y0, y1, n), rng.uniform(0, h, n)))),
        (ly * h, lambda n: np.column_stack((np.full(n, x1), rng.uniform(y0, y1, n), rng.uniform(0, h, n)))),
        (lx * ly, lambda n: np.column_stack((rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), np.zeros(n)))),
        (lx * ly, lambda n: np.column_stack((rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), np.full(n, h)))),
    ]
    return np.vstack([draw(max(1, round(density * area))) for area, draw in faces])


def _blocked_by(c: Column, eye: Array, pts: Array) -> NDArray[np.bool_]:
    """Which segments ``eye → pts`` cross column ``c`` below its top (vectorised over ``pts``)."""
    # segment in the column's frame (xy); the parameter s in [0, 1] runs from the eye to the point
    e = planar_apply_inverse((c.x, c.y, c.yaw), eye[:2])
    d = planar_apply_inverse((0.0, 0.0, c.yaw), pts[:, :2] - eye[:2])  # directions: the rotation only
    n = len(pts)
    if c.depth > 0.0:  # box: slab test
        half = np.array([0.5 * c.depth, 0.5 * c.width])
        s_in, s_out = np.zeros(n), np.ones(n)
        hit = np.ones(n, dtype=bool)
        for k in range(2):
            dk = d[:, k]
            par = np.abs(dk) < 1e-12
            hit &= ~(par & (np.abs(e[k]) > half[k]))
            with np.errstate(divide="ignore", invalid="ignore"):
                a, b = (-half[k] - e[k]) / dk, (half[k] - e[k]) / dk
            lo, hi = np.where(par, -np.inf, np.minimum(a, b)), np.where(par, np.inf, np.maximum(a, b))
            s_in, s_out = np.maximum(s_in, lo), np.minimum(s_out, hi)
        hit &= s_in <= s_out
        s = s_in
    else:  # cylinder: closest approach of the segment to the axis
        r = 0.5 * c.width
        dd = np.einsum("ij,ij->i", d, d)
        s = np.clip(-(d @ e) / np.maximum(dd, 1e-12), 0.0, 1.0)
        closest = e[None, :] + s[:, None] * d
        hit = np.einsum("ij,ij->i", closest, closest) < r * r
    z = eye[2] + s * (pts[:, 2] - eye[2])
    return np.asarray(hit & (z <= c.height), dtype=np.bool_)


def project(points: Array, R_world_camera: Array, t_world_camera: Array, K: Array) -> tuple[Array, Array]:
    """Camera-frame depth (N,) and pixels (N, 2) of world points for the camera at ``(R_world_camera, t_world_camera)``
    (world ← optical frame rotation, camera position)."""
    Xc = (points - t_world_camera) @ R_world_camera
    z = Xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = Xc[:, :2] / z[:, None] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    return z, uv


def visible_landmarks(points: Array, columns: Sequence[Column], R_world_camera: Array, t_world_camera: Array, K: Array,
                      size: tuple[int, int], margin: float = 2.0, near: float = 0.05) -> tuple[NDArray[np.int64], Array]:
    """Ids and exact pixels of the landmarks the camera sees (see module doc)."""
    w, h = size
    z, uv = project(points, R_world_camera, t_world_camera, K)
    ok = (z > near) & (uv[:, 0] >= margin) & (uv[:, 0] <= w - 1 - margin) & (uv[:, 1] >= margin) & (uv[:, 1] <= h - 1 - margin)
    idx = np.flatnonzero(ok)
    for c in columns:
        if len(idx):
            idx = idx[~_blocked_by(c, t_world_camera, points[idx])]
    return idx.astype(np.int64), uv[idx]


def column_silhouette(c: Column, R_world_camera: Array, t_world_camera: Array, K: Array, size: tuple[int, int],
                      n: int = 48, near: float = 0.05) -> tuple[float, float, bool] | None:
    """Left and right image columns (px, pixel boundaries) of column ``c`` at the camera's height and
    whether it is cut by the image border or the camera plane; ``None`` when out of view."""
    w, _ = size
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    if c.depth > 0.0:  # box outline
        hx, hy = 0.5 * c.depth, 0.5 * c.width
        m = np.maximum(np.abs(np.cos(a)) / hx, np.abs(np.sin(a)) / hy)
        lx, ly = np.cos(a) / m, np.sin(a) / m
    else:
        lx, ly = 0.5 * c.width * np.cos(a), 0.5 * c.width * np.sin(a)
    if t_world_camera[2] > c.height:
        return None
    pts = np.column_stack((planar_apply((c.x, c.y, c.yaw), np.column_stack((lx, ly))), np.full(n, t_world_camera[2])))
    z, uv = project(pts, R_world_camera, t_world_camera, K)
    front = z > near
    if not np.any(front):
        return None
    u = uv[front, 0]
    u0, u1 = float(u.min()) - 0.5, float(u.max()) + 0.5
    cut = not np.all(front)
    if cut:  # part of the outline behind the camera: it spans to a border on that side
        u0, u1 = (-0.5, u1) if u0 > 0.5 * w else (u0, w - 0.5)
    if u1 < 0.0 or u0 > w - 1.0:
        return None
    border = cut or u0 <= 0.5 or u1 >= w - 1.5
    return max(u0, -0.5), min(u1, w - 0.5), border
