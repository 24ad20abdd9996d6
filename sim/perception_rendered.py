"""``rendered`` perception: pixels from PyBullet's TinyRenderer, depth fusion of ViKi-HyCo eq. 11–17.

Per frame of the active camera:

* ``getCameraImage`` (TinyRenderer, DIRECT) at the camera's resolution with the camera model of
  :mod:`taskflow_sim.perception_common` (vertical FOV, principal point ``(W/2, H/2 - 1)``); its colour
  image is kept as ``last_rgb`` (a read-only view, no copy) for the world to publish;
* bounding box = extents of the object's pixels in the segmentation mask (a perfect detector; misses
  come from the shared dropout model), edges at ``.5`` (OpenCV convention); fewer than ``min_pixels``
  pixels → no detection;
* camera depth image from the depth buffer, linearised ``Z = f n / (f - (f - n) d)``, 0 beyond
  ``depth_max`` and on the far plane;
* **front camera**: the 16-layer LiDAR (``rayTestBatch``, at the LiDAR's own rate, returns on the car
  itself discarded) is interpolated to 112 virtual layers, turned into points, kept in the world frame
  and projected into each frame with the camera pose of that frame (eq. 11–12, value = camera Z); the
  blind-spot mask of eq. 13–14 (computed once per mount) selects the camera depth on the ground disc
  the LiDAR cannot see, the LiDAR depth elsewhere (eq. 15 as meant, :func:`taskflow_sim.car_depth.fuse_depth`);
  **rear camera**: its own depth image (paper section II-C, ``dI_c2``);
* ``Z_o`` = eq. 16–17 on that depth image; ``depth_at`` reads it at a pixel, ``depth_in`` applies eq. 16–17
  to any box.

With the racecar's default mounts the front camera only sees ground inside the LiDAR's 4.1 m blind
disc, so the fused image equals the camera depth except where the LiDAR hits something tall; the
fusion is computed anyway (it is part of the per-frame cost the benchmark measures).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_robots.racecar import LidarMount
from taskflow_sim.car_depth import (
    blind_spot_mask,
    fuse_depth,
    interpolate_lidar_layers,
    lidar_ranges_to_points,
    object_depth,
    project_lidar_points,
)
from taskflow_sim.perception_common import CameraModel, pixel_box

VIRTUAL_LAYERS = 112


class LidarScanner:
    """The 16-layer LiDAR: scans at its rate, keeps the interpolated cloud in the world frame."""

    def __init__(self, client: int, mount: LidarMount, car_body: int) -> None:
        self.client, self.mount, self.car_body = client, mount, car_body
        self.elevations = np.linspace(mount.v_fov[0], mount.v_fov[1], mount.layers)
        self.azimuths = np.linspace(-0.5 * mount.h_fov, 0.5 * mount.h_fov, mount.azimuths)
        ce, se = np.cos(self.elevations)[:, None], np.sin(self.elevations)[:, None]
        ca, sa = np.cos(self.azimuths)[None, :], np.sin(self.azimuths)[None, :]
        self._dirs = np.stack([ce * ca, ce * sa, se * np.ones_like(ca)], axis=-1).reshape(-1, 3)
        self.points_w: NDArray[np.float64] = np.zeros((0, 3))
        self.next_scan = 0.0
        self.scans = 0
        self.scan_s = 0.0

    def maybe_scan(self, t: float, T_world_robot: NDArray[np.float64]) -> None:
        if t + 1e-9 < self.next_scan:
            return
        self.next_scan = t + 1.0 / self.mount.rate_hz
        t0 = time.perf_counter()
        T_world_lidar = T_world_robot @ self.mount.T_body_mount()
        R, o = T_world_lidar[:3, :3], T_world_lidar[:3, 3]
        rng = self.mount.max_range
        ends = o + (self._dirs @ R.T) * rng
        starts = np.broadcast_to(o, ends.shape)
        hits = p.rayTestBatch(starts.tolist(), ends.tolist(), physicsClientId=self.client)
        ranges = np.array([h[2] * rng if (h[0] >= 0 and h[0] != self.car_body) else 0.0 for h in hits])
        ranges = np.where(ranges >= self.mount.min_range, ranges, 0.0).reshape(self.mount.layers, -1)
        rv, ev = interpolate_lidar_layers(ranges, self.elevations, VIRTUAL_LAYERS)
        pts_l = lidar_ranges_to_points(rv, ev, self.azimuths)
        self.points_w = pts_l @ R.T + o
        self.scans += 1
        self.scan_s += time.perf_counter() - t0


class RenderedPerception:
    def __init__(self, client: int, camera: CameraModel, body: int, min_pixels: int,
                 lidar: LidarScanner | None = None) -> None:
        self.client, self.cam, self.body, self.min_pixels, self.lidar = client, camera, body, min_pixels, lidar
        m = camera.mount
        self._proj = p.computeProjectionMatrixFOV(math.degrees(m.fov), camera.width / camera.height, m.near, m.far)
        self._mask: NDArray[np.bool_] | None = None
        if lidar is not None:
            # numpy's general (LU) inverses here, not spatial.inverse: the closed form differs in the last bits
            # (kept so the rendered runs' records stay the same)
            T_camera_lidar = np.linalg.inv(camera.T_robot_camera()) @ lidar.mount.T_body_mount()
            self._mask = blind_spot_mask(T_camera_lidar, camera.intrinsics, camera.width, camera.height,
                                         lidar_height=lidar.mount.xyz[2], lowest_beam=lidar.mount.v_fov[0])
        self.render_s = 0.0
        self.fusion_s = 0.0
        self.frames = 0
        self.last_depth: NDArray[np.float64] | None = None
        self.last_rgb: NDArray[np.uint8] | None = None  # the last frame's colour image (H, W, 3), read-only

    def detect(self, T_world_camera: NDArray[np.float64], t: float, T_world_robot: NDArray[np.float64]) -> tuple[
            tuple[float, float, float, float] | None, float | None, Callable[[float, float], float | None],
            Callable[[tuple[float, float, float, float]], float | None]]:
        cam, m = self.cam, self.cam.mount
        W, H = cam.width, cam.height
        eye = T_world_camera[:3, 3]
        view = p.computeViewMatrix(eye.tolist(), (eye + T_world_camera[:3, 2]).tolist(), (-T_world_camera[:3, 1]).tolist())
        t0 = time.perf_counter()
        _, _, rgba, zbuf, seg = p.getCameraImage(W, H, view, self._proj, shadow=0, renderer=p.ER_TINY_RENDERER,
                                              physicsClientId=self.client)
        t1 = time.perf_counter()
        self.render_s += t1 - t0
        self.frames += 1
        # the colour image TinyRenderer drew anyway: a view of its RGBA buffer, no copy (published by the world)
        rgb = np.reshape(np.asarray(rgba, dtype=np.uint8), (H, W, 4))[:, :, :3]
        rgb.setflags(write=False)
        self.last_rgb = rgb
        d = np.reshape(np.asarray(zbuf, dtype=np.float64), (H, W))
        depth = m.far * m.near / (m.far - (m.far - m.near) * d)
        depth = np.where((d < 1.0 - 1e-7) & (depth <= cam.depth_max), depth, 0.0)
        if self.lidar is not None and self._mask is not None:
            self.lidar.maybe_scan(t, T_world_robot)
            # (numpy inverse kept: see __init__)
            dI_l = project_lidar_points(self.lidar.points_w, np.linalg.inv(T_world_camera), cam.intrinsics, W, H,
                                        value="camera_z")
            depth = fuse_depth(dI_l, depth, self._mask)
        self.last_depth = depth
        mask = np.reshape(np.asarray(seg), (H, W)) == self.body
        depth_img = depth

        def depth_at(u: float, v: float) -> float | None:
            iu, iv = int(round(u)), int(round(v))
            if not (0 <= iu < W and 0 <= iv < H):
                return None
            z = float(depth_img[iv, iu])
            return z if z > 0.0 else None

        def depth_in(box: tuple[float, float, float, float]) -> float | None:
            return object_depth(depth_img, pixel_box(box))

        bbox = None
        z_o = None
        if int(mask.sum()) >= self.min_pixels:
            rows = np.flatnonzero(mask.any(axis=1))
            cols = np.flatnonzero(mask.any(axis=0))
            a, b, c, dd = int(cols[0]), int(cols[-1]), int(rows[0]), int(rows[-1])
            bbox = (a - 0.5, c - 0.5, b + 0.5, dd + 0.5)
            z_o = object_depth(depth, (a, c, b, dd))
        self.fusion_s += time.perf_counter() - t1
        return bbox, z_o, depth_at, depth_in
