"""``geometric`` perception: the object's box from its 3-D shape projected through the camera model.

Fast stand-in for the rendered pipeline (SIMULATOR_NOTES.md: rendering every frame runs near real
time), with the same camera model and the same depth rule (:mod:`taskflow_sim.viki.camera`):

1. silhouette: hull points of the object (:meth:`PlacedObject.hull_points`) projected with the camera
   intrinsics; their extents plus Gaussian pixel noise (``pixel_noise`` px per edge, seeded), quantised
   to the pixels whose centres they cover (as TinyRenderer rasterises), clipped to the image;
   fewer than ``min_pixels`` visible pixels → no detection;
2. occlusion: one PyBullet ray from the camera to the object centre must hit the object first;
3. ``Z_o`` (eq. 16–17): rays through the pixel centres of the 40 %-shrunk box (every pixel, or a regular
   subsample above 400 pixels) intersected analytically with the object and the floor; mean of the
   valid camera depths (0 beyond ``depth_max``).  A per-frame multiplicative depth error
   ``1 + N(0, depth_noise)`` applies to ``Z_o`` and to ``depth_at`` alike;
4. ``depth_at(u, v)``: the same analytic ray cast for one pixel (eq. 19's ``Z_d``); ``depth_in(box)``: rule 3
   for any box.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_sim.viki.camera import CameraModel, pixel_box, quantise_box
from taskflow_sim.viki.depth import shrunk_box
from taskflow_sim.viki.objects import PlacedObject, ray_ground

MAX_DEPTH_RAYS = 400


class GeometricPerception:
    def __init__(self, client: int, camera: CameraModel, obj: PlacedObject, body: int, rng: np.random.Generator,
                 pixel_noise: float, depth_noise: float, min_pixels: int) -> None:
        self.client, self.cam, self.obj, self.body, self.rng = client, camera, obj, body, rng
        self.pixel_noise, self.depth_noise, self.min_pixels = pixel_noise, depth_noise, min_pixels
        self._hull = obj.hull_points()

    def _depths(self, T_world_camera: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Camera depth of pixel rays (0 where nothing within ``depth_max``)."""
        o, d = self.cam.rays(T_world_camera, u, v)
        t = np.minimum(self.obj.ray_hit(o, d), ray_ground(o, d))
        return np.where(t <= self.cam.depth_max, t, 0.0)

    def detect(self, T_world_camera: NDArray[np.float64]) -> tuple[tuple[float, float, float, float] | None, float | None,
                                                          Callable[[float, float], float | None],
                                                          Callable[[tuple[float, float, float, float]], float | None]]:
        cam = self.cam
        W, H = cam.width, cam.height
        # draws first, in a fixed number, so the random stream does not depend on visibility
        noise = self.rng.normal(0.0, 1.0, 4) * self.pixel_noise
        scale = 1.0 + float(self.rng.normal(0.0, 1.0)) * self.depth_noise
        scale = max(scale, 0.1)

        def depth_at(u: float, v: float) -> float | None:
            if not (-0.5 <= u < W - 0.5 and -0.5 <= v < H - 0.5):
                return None
            z = float(self._depths(T_world_camera, np.array([u]), np.array([v]))[0])
            return z * scale if z > 0.0 else None

        def depth_in(box: tuple[float, float, float, float]) -> float | None:
            z = self._object_depth(T_world_camera, pixel_box(box))
            return z * scale if z is not None else None

        uv, z = cam.project(T_world_camera, self._hull)
        front = z > cam.mount.near
        if not np.any(front):
            return None, None, depth_at, depth_in
        uv = uv[front]
        u0, v0 = uv.min(axis=0)
        u2, v2 = uv.max(axis=0)
        u0, v0, u2, v2 = u0 + noise[0], v0 + noise[1], u2 + noise[2], v2 + noise[3]
        if u2 < u0:
            u0 = u2 = 0.5 * (u0 + u2)
        if v2 < v0:
            v0 = v2 = 0.5 * (v0 + v2)
        box = quantise_box(u0, v0, u2, v2)
        a, c, b, d = pixel_box(box)
        a, c, b, d = max(a, 0), max(c, 0), min(b, W - 1), min(d, H - 1)
        if a > b or c > d or (b - a + 1) * (d - c + 1) < self.min_pixels:
            return None, None, depth_at, depth_in
        if not self._line_of_sight(T_world_camera):
            return None, None, depth_at, depth_in
        bbox = (a - 0.5, c - 0.5, b + 0.5, d + 0.5)
        depth = self._object_depth(T_world_camera, (a, c, b, d))
        return bbox, (depth * scale if depth is not None else None), depth_at, depth_in

    def _object_depth(self, T_world_camera: NDArray[np.float64], pbox: tuple[int, int, int, int]) -> float | None:
        """Eq. 16–17 over the pixel centres of the shrunk box."""
        umin, vmin, umax, vmax = shrunk_box(np.asarray(pbox, dtype=float))
        umin, vmin = max(umin, 0), max(vmin, 0)
        umax, vmax = min(umax, self.cam.width - 1), min(vmax, self.cam.height - 1)
        if umin > umax or vmin > vmax:
            return None
        nu, nv = umax - umin + 1, vmax - vmin + 1
        su = max(1, int(np.ceil(np.sqrt(nu * nv / MAX_DEPTH_RAYS))))
        us = np.arange(umin, umax + 1, su, dtype=float)
        vs = np.arange(vmin, vmax + 1, su, dtype=float)
        U, V = np.meshgrid(us, vs)
        z = self._depths(T_world_camera, U.ravel(), V.ravel())
        ok = z > 0.0
        if not np.any(ok):
            return None
        return float(z[ok].mean())

    def _line_of_sight(self, T_world_camera: NDArray[np.float64]) -> bool:
        start = T_world_camera[:3, 3]
        end = self.obj.centre()
        hit = p.rayTest(start.tolist(), end.tolist(), physicsClientId=self.client)[0]
        return hit[0] in (-1, self.body)
