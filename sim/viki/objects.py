"""Waste-like objects of the ViKi-HyCo world and the pure geometry both perception modes share.

Kinds (paper section III: "domestic waste": cans, bottles, cartons), upright on the floor, each with
its own colour so a colour or segmentation detector tells it from the grey floor:

===========  =====================================  =========================
kind         shape (m)                              colour
===========  =====================================  =========================
``can``      cylinder r 0.033, h 0.122 (330 ml)     red
``bottle``   cylinder r 0.040, h 0.250 (1 l PET)    blue
``carton``   box 0.095 x 0.065 x 0.200 (1 l)        white-yellow
===========  =====================================  =========================

The pose of an object is its **base centre** ``(x, y)`` on the floor and a yaw (which only matters for
the carton).  Ground truth "object position" everywhere in this world means that base centre.

Geometry here is numpy only (ray/box/cylinder intersection, silhouette points); :func:`create_body`
is the one PyBullet function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from taskflow.spatial import planar_apply

Kind = Literal["can", "bottle", "carton"]


@dataclass(frozen=True)
class ObjectShape:
    kind: str
    shape: Literal["cylinder", "box"]
    size: tuple[float, float, float]  # cylinder: (r, r, h); box: full extents (sx, sy, sz)
    rgba: tuple[float, float, float, float]

    @property
    def height(self) -> float:
        return self.size[2]

    def footprint_radius(self) -> float:
        """Largest horizontal distance from the base centre to the object's surface."""
        if self.shape == "cylinder":
            return self.size[0]
        return 0.5 * math.hypot(self.size[0], self.size[1])

    def front_size(self) -> tuple[float, float]:
        """(W, H) of the object seen from the side: what an MGBM-YOLO user would measure."""
        if self.shape == "cylinder":
            return 2.0 * self.size[0], self.size[2]
        return self.size[0], self.size[2]


SHAPES: dict[str, ObjectShape] = {
    "can": ObjectShape("can", "cylinder", (0.033, 0.033, 0.122), (0.85, 0.08, 0.08, 1.0)),
    "bottle": ObjectShape("bottle", "cylinder", (0.040, 0.040, 0.250), (0.10, 0.45, 0.95, 1.0)),
    "carton": ObjectShape("carton", "box", (0.095, 0.065, 0.200), (0.97, 0.93, 0.70, 1.0)),
}


@dataclass(frozen=True)
class PlacedObject:
    """A shape at base centre ``(x, y)`` with ``yaw`` (rad), world frame."""

    shape: ObjectShape
    x: float
    y: float
    yaw: float = 0.0

    def centre(self) -> NDArray[np.float64]:
        """Geometric centre (m, world)."""
        return np.array([self.x, self.y, 0.5 * self.shape.height])

    def hull_points(self, n: int = 48) -> NDArray[np.float64]:
        """Points whose projection's bounding box is the object's image bounding box (N x 3, world).

        Cylinder: ``n`` points on each of the bottom and top circles (the bbox error of the sampling is
        below ``r (1 - cos(pi / n))``, 0.07 mm for the bottle); box: its 8 corners.
        """
        s = self.shape
        if s.shape == "cylinder":
            a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
            r = s.size[0]
            ring = np.stack([self.x + r * np.cos(a), self.y + r * np.sin(a)], axis=1)
            bottom = np.column_stack([ring, np.zeros(n)])
            top = np.column_stack([ring, np.full(n, s.height)])
            return np.vstack([bottom, top])
        hx, hy = 0.5 * s.size[0], 0.5 * s.size[1]
        T_world_object = (self.x, self.y, self.yaw)
        ring = planar_apply(T_world_object, [(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)])
        return np.vstack([np.column_stack([ring, np.full(4, z)]) for z in (0.0, s.height)])

    def ray_hit(self, origin: NDArray[np.float64], dirs: NDArray[np.float64]) -> NDArray[np.float64]:
        """Ray parameter ``t`` of the first hit of rays ``origin + t dirs`` (t > 0) with the object.

        ``dirs`` is (N, 3), not necessarily unit; ``inf`` where a ray misses.
        """
        s = self.shape
        o = np.asarray(origin, dtype=float)
        d = np.asarray(dirs, dtype=float).reshape(-1, 3)
        if s.shape == "cylinder":
            return _ray_cylinder(o - np.array([self.x, self.y, 0.0]), d, s.size[0], s.height)
        c, si = math.cos(self.yaw), math.sin(self.yaw)
        rot_t = np.array([[c, si, 0.0], [-si, c, 0.0], [0.0, 0.0, 1.0]])  # world → object axes
        ol = rot_t @ (o - np.array([self.x, self.y, 0.5 * s.height]))
        dl = d @ rot_t.T
        half = 0.5 * np.asarray(s.size)
        return _ray_box(ol, dl, half)


def _ray_cylinder(o: NDArray[np.float64], d: NDArray[np.float64], r: float, h: float) -> NDArray[np.float64]:
    """Upright cylinder ``x^2 + y^2 <= r^2, 0 <= z <= h`` (origin at the base centre): side and top cap."""
    t_best = np.full(d.shape[0], np.inf)
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2.0 * (o[0] * d[:, 0] + o[1] * d[:, 1])
    cc = o[0] ** 2 + o[1] ** 2 - r * r
    disc = b * b - 4.0 * a * cc
    ok = (a > 1e-15) & (disc >= 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(np.where(ok, disc, 0.0))
        t1 = (-b - sq) / (2.0 * np.where(ok, a, 1.0))
    z1 = o[2] + t1 * d[:, 2]
    side = ok & (t1 > 1e-9) & (z1 >= 0.0) & (z1 <= h)
    t_best = np.where(side, t1, t_best)
    # top cap
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = (h - o[2]) / d[:, 2]
    xc = o[0] + tc * d[:, 0]
    yc = o[1] + tc * d[:, 1]
    cap = (np.abs(d[:, 2]) > 1e-15) & (tc > 1e-9) & (xc * xc + yc * yc <= r * r)
    return np.where(cap & (tc < t_best), tc, t_best)


def _ray_box(o: NDArray[np.float64], d: NDArray[np.float64], half: NDArray[np.float64]) -> NDArray[np.float64]:
    """Axis-aligned box ``|x_i| <= half_i`` (slab method)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0 = (-half - o) * inv
        t1 = (half - o) * inv
    t0 = np.nan_to_num(t0, nan=-np.inf)
    t1 = np.nan_to_num(t1, nan=np.inf)
    tmin = np.minimum(t0, t1).max(axis=1)
    tmax = np.maximum(t0, t1).min(axis=1)
    hit = (tmax >= tmin) & (tmax > 1e-9)
    t = np.where(tmin > 1e-9, tmin, tmax)
    return np.where(hit, t, np.inf)


def ray_ground(origin: NDArray[np.float64], dirs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Ray parameter of the hit with the floor ``z = 0`` (``inf`` for rays not going down)."""
    d = np.asarray(dirs, dtype=float).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -float(origin[2]) / d[:, 2]
    return np.where((d[:, 2] < -1e-12) & (t > 0.0), t, np.inf)


def create_body(client: int, obj: PlacedObject) -> int:
    """A static PyBullet body for ``obj`` (mass 0: the car cannot push it; ground truth stays put)."""
    s = obj.shape
    if s.shape == "cylinder":
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=s.size[0], height=s.height, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_CYLINDER, radius=s.size[0], length=s.height, rgbaColor=list(s.rgba),
                                  physicsClientId=client)
    else:
        half = [0.5 * v for v in s.size]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=list(s.rgba), physicsClientId=client)
    body: int = p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=col,
        baseVisualShapeIndex=vis,
        basePosition=[obj.x, obj.y, 0.5 * s.height],
        baseOrientation=p.getQuaternionFromEuler([0.0, 0.0, obj.yaw]),
        physicsClientId=client,
    )
    return body
