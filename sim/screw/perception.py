"""Marker pose estimation for the screw world: ``H_co`` at the camera rate, two modes.

* ``rendered`` — the faithful pipeline: PyBullet renders the platform camera (TinyRenderer), OpenCV's
  ArUco detector finds the marker (DICT_4X4_50, sub-pixel corners) and ``solvePnP`` with
  ``SOLVEPNP_IPPE_SQUARE`` gives ``H_co``.  IPPE returns two candidate poses for a square; the one with
  the lower reprojection error is taken unless the two are close, in which case the one nearer the
  previous estimate wins (the flip of SIMULATOR_NOTES.md).  Intrinsics: ``fx = fy = H / (2 tan(fovy/2))``,
  principal point ``(W/2, H/2 − 1)``.
  The camera's sensor noise is added to every rendered image (:class:`ImageNoise`: white Gaussian
  noise of ``image_noise`` grey levels per pixel from the world's seeded stream) before detection, so
  the corner jitter comes out of the detector as on a real camera — larger for a small, blurred or
  low-contrast marker, smaller for a large sharp one — instead of a fixed pixel error on the corners.
* ``pose`` (default, tests and batches) — the true ``H_co`` with a noise, a latency and a dropout
  calibrated against the rendered mode (``benchmarks/screw_fastening.py --calibrate`` measures it):
  translation noise along the camera's x/y and, larger, along its viewing axis z, a rotation noise,
  each a first-order Gauss–Markov process (time constant ``noise_tau``: rendered errors are smooth
  functions of the pose, not white), plus a visibility test (in the image with a margin, facing the
  camera, within range).

Both modes report a :class:`MarkerDetection` with the capture time; it becomes visible to the robot
``latency`` seconds later (image transfer + processing, as on the real system).  The world's
``dropout`` (a frame that misses the marker) acts in both modes (:mod:`taskflow_sim.screw.world`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_robots.camera import tinyrenderer_intrinsics
from taskflow_robots.mobile_iiwa import CameraParams
from taskflow_sim.screw.scene import MARKER_DICT, MARKER_ID, MARKER_SIZE

from taskflow.spatial import rotation_angle, transform

APRILTAG_OFFSET_PX = 0.5


@dataclass
class MarkerDetection:
    """One camera frame's result: ``H_co`` (None: marker not found) captured at ``t``."""

    t: float
    H_co: NDArray[np.float64] | None
    reproj_px: float = 0.0


def project(K: NDArray[np.float64], H_co: NDArray[np.float64], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pinhole projection of object points (rows) seen at ``H_co``."""
    pc = pts @ H_co[:3, :3].T + H_co[:3, 3]
    uv = pc[:, :2] / pc[:, 2:3]
    out: NDArray[np.float64] = uv * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    return out


def marker_corners(size: float = MARKER_SIZE) -> NDArray[np.float64]:
    """ArUco corner order (top-left, top-right, bottom-right, bottom-left) in the marker frame."""
    h = 0.5 * size
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


_CORNERS = None


def visible(cam: CameraParams, H_co: NDArray[np.float64], margin_px: float = 8.0, max_incidence: float = math.radians(75.0),
            K: NDArray[np.float64] | None = None) -> bool:
    """The marker is in front of the camera, inside the image with a margin, and not seen edge-on."""
    global _CORNERS
    if H_co[2, 3] <= cam.near or H_co[2, 3] >= cam.far:
        return False
    if _CORNERS is None:
        _CORNERS = marker_corners()
    pc = _CORNERS @ H_co[:3, :3].T + H_co[:3, 3]
    if float(pc[:, 2].min()) <= cam.near:
        return False
    K = cam.K() if K is None else K
    u = K[0, 0] * pc[:, 0] / pc[:, 2] + K[0, 2]
    v = K[1, 1] * pc[:, 1] / pc[:, 2] + K[1, 2]
    if float(u.min()) < margin_px or float(v.min()) < margin_px or float(u.max()) > cam.width - margin_px \
            or float(v.max()) > cam.height - margin_px:
        return False
    # angle between the marker normal and the line of sight
    n = H_co[:3, 2]
    los = -H_co[:3, 3] / np.linalg.norm(H_co[:3, 3])
    return float(n @ los) > math.cos(max_incidence)


def _rotvec_matrix(w: NDArray[np.float64]) -> NDArray[np.float64]:
    th = float(np.linalg.norm(w))
    if th < 1e-12:
        return np.eye(3)
    k = w / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R: NDArray[np.float64] = np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * (K @ K)
    return R


class PoseNoise:
    """First-order Gauss–Markov noise on ``H_co``: stationary std ``sigma_xy``/``sigma_z`` (m) on the
    camera axes and ``sigma_r`` (rad) per rotation axis, correlation time ``tau`` (s)."""

    def __init__(self, rng: np.random.Generator, sigma_xy: float, sigma_z: float, sigma_r: float, tau: float) -> None:
        self.rng = rng
        self.sig = np.array([sigma_xy, sigma_xy, sigma_z, sigma_r, sigma_r, sigma_r])
        self.tau = tau
        self.state: NDArray[np.float64] = rng.normal(0.0, 1.0, 6) * self.sig
        self.t: float | None = None

    def sample(self, t: float) -> NDArray[np.float64]:
        if self.t is not None:
            dt = max(0.0, t - self.t)
            a = math.exp(-dt / self.tau) if self.tau > 0 else 0.0
            self.state = a * self.state + math.sqrt(max(0.0, 1 - a * a)) * self.rng.normal(0.0, 1.0, 6) * self.sig
        self.t = t
        return self.state

    def apply(self, H_co: NDArray[np.float64], t: float) -> NDArray[np.float64]:
        n = self.sample(t)
        out = H_co.copy()
        out[:3, 3] += n[:3]
        out[:3, :3] = _rotvec_matrix(n[3:]) @ H_co[:3, :3]
        return out


@dataclass
class ImageNoise:
    """A camera's temporal pixel noise: white Gaussian, std ``sigma`` grey levels (8 bit), drawn from
    ``rng`` for every pixel of every image, the result rounded and clipped to 0..255 as a sensor's ADC."""

    rng: np.random.Generator
    sigma: float

    def apply(self, gray: NDArray[np.uint8]) -> NDArray[np.uint8]:
        if self.sigma <= 0.0:
            return gray
        noisy = gray + self.rng.normal(0.0, self.sigma, gray.shape)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def window_projection(cam: CameraParams, u0: int, v0: int, w: int, h: int) -> list[float]:
    """OpenGL projection (column-major) rendering only the window ``[u0, u0+w) x [v0, v0+h)`` of the
    full ``cam`` image, with the full image's pinhole ``K`` (principal point ``(W/2, H/2 − 1)``).

    TinyRenderer maps NDC to window pixels as ``u = (x+1) w/2`` and ``v = (1−y) h/2 − 1``; solving
    for the frustum that keeps each pixel's ray gives the bounds below (for the full window they
    reduce to PyBullet's symmetric ``computeProjectionMatrixFOV``).  This is an industrial camera's
    region-of-interest readout: full-resolution pixels, a fraction of the rendering cost.
    """
    f, _, cx, cy = tinyrenderer_intrinsics(cam.width, cam.height, cam.fov)
    n, fa = cam.near, cam.far
    left, right = n * (u0 - cx) / f, n * (u0 + w - cx) / f
    top, bottom = -n * (v0 - 1 - cy) / f, -n * (v0 + h - 1 - cy) / f
    return [2 * n / (right - left), 0.0, 0.0, 0.0,
            0.0, 2 * n / (top - bottom), 0.0, 0.0,
            (right + left) / (right - left), (top + bottom) / (top - bottom), -(fa + n) / (fa - n), -1.0,
            0.0, 0.0, -2 * fa * n / (fa - n), 0.0]


class RenderedDetector:
    """PyBullet camera image → ArUco → IPPE pose, with a region of interest.

    The camera is ``cam`` (e.g. 1280x960); each frame renders only a ``roi`` x ``roi`` window around
    where the marker is expected (the last detection moved by its last displacement), or, without a
    recent detection, the whole field of view at ``search_scale`` of the resolution to find it.
    ``noise`` (None: a noiseless camera) is added to every rendered image before detection.
    """

    def __init__(self, client: int, cam: CameraParams, roi: int = 320, search_scale: float = 0.25,
                 noise: ImageNoise | None = None) -> None:
        import cv2

        self.cv2 = cv2
        self.client = client
        self.cam = cam
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, MARKER_DICT))
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
        self.detector = cv2.aruco.ArucoDetector(d, params)
        self.K = cam.K()
        self.dist = np.zeros(5)
        self.obj = marker_corners().astype(np.float64)
        self.roi = int(min(roi, cam.width, cam.height))
        self.search_scale = search_scale
        self.noise = noise
        self.last: NDArray[np.float64] | None = None
        self.last_center: NDArray[np.float64] | None = None
        self.prev_center: NDArray[np.float64] | None = None
        self.last_image: NDArray[np.uint8] | None = None
        self.frames = 0
        self.searches = 0

    def _view(self, H_wc: NDArray[np.float64]) -> list[float]:
        eye = H_wc[:3, 3]
        return list(p.computeViewMatrix(eye.tolist(), (eye + H_wc[:3, 2]).tolist(), (-H_wc[:3, 1]).tolist()))

    def _render(self, view: list[float], proj: list[float], w: int, h: int) -> NDArray[np.uint8]:
        img = p.getCameraImage(w, h, view, proj, renderer=p.ER_TINY_RENDERER, shadow=0,
                               flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client)
        rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (h, w, 4))[:, :, :3]
        gray = np.asarray(self.cv2.cvtColor(rgb, self.cv2.COLOR_RGB2GRAY), dtype=np.uint8)
        return gray if self.noise is None else self.noise.apply(gray)

    def render_full(self, H_wc: NDArray[np.float64], scale: float = 1.0) -> NDArray[np.uint8]:
        """The whole field of view at ``scale`` of the camera's resolution."""
        c = self.cam
        w, h = max(8, round(c.width * scale)), max(8, round(c.height * scale))
        proj = list(p.computeProjectionMatrixFOV(math.degrees(c.fov), c.width / c.height, c.near, c.far))
        return self._render(self._view(H_wc), proj, w, h)

    def _roi_corners(self, view: list[float], centre: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Render the ``roi`` x ``roi`` window around ``centre`` (px) and find the marker corners in it."""
        c, r = self.cam, self.roi
        u0 = int(np.clip(round(centre[0] - r / 2), 0, c.width - r))
        v0 = int(np.clip(round(centre[1] - r / 2), 0, c.height - r))
        gray = self._render(view, window_projection(c, u0, v0, r, r), r, r)
        self.last_image = gray
        pts = self._corners(gray)
        return None if pts is None else pts + [u0, v0]

    def _corners(self, gray: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        corners, ids, _ = self.detector.detectMarkers(gray)
        if ids is None:
            return None
        hits = [i for i, mid in enumerate(ids.ravel()) if mid == MARKER_ID]
        # the AprilTag refinement reports corners with pixel (0, 0)'s corner at the origin; OpenCV's
        # pinhole model puts pixel centres on integers
        return corners[hits[0]].reshape(4, 2).astype(np.float64) - APRILTAG_OFFSET_PX if hits else None

    def locate(self, H_wc: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Marker corners in full-resolution pixels (ROI around the prediction, else a coarse search)."""
        c = self.cam
        view = self._view(H_wc)
        if self.last_center is not None:
            pred = self.last_center
            if self.prev_center is not None:
                pred = pred + (self.last_center - self.prev_center)
            pts = self._roi_corners(view, pred)
            if pts is not None:
                return pts
        # coarse search over the whole field of view, then refine in a ROI
        self.searches += 1
        s = self.search_scale
        gray = self.render_full(H_wc, s)
        self.last_image = gray
        pts = self._corners(gray)
        if pts is None:
            return None
        scale = c.width / gray.shape[1]
        centre = (pts.mean(axis=0) + 0.5) * scale - 0.5
        self.last_center, self.prev_center = centre, None
        return self._roi_corners(view, centre)

    def solve(self, img_pts: NDArray[np.float64]) -> tuple[NDArray[np.float64] | None, float]:
        cv2 = self.cv2
        n, rvecs, tvecs, errs = cv2.solvePnPGeneric(self.obj, img_pts, self.K, self.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        if n == 0:
            return None, math.inf
        cands = []
        for rv, tv, e in zip(rvecs, tvecs, np.ravel(errs), strict=False):
            R_cm, _ = cv2.Rodrigues(rv)
            cands.append((float(e), transform(R_cm, tv.ravel())))
        cands.sort(key=lambda c: c[0])
        best = cands[0]
        if len(cands) > 1 and self.last is not None and cands[1][0] < 1.5 * cands[0][0] + 0.05:
            last = self.last

            def dist(H: NDArray[np.float64]) -> float:
                return rotation_angle(H[:3, :3].T @ last[:3, :3])

            best = min(cands[:2], key=lambda c: dist(c[1]))
        return best[1], best[0]

    def __call__(self, H_wc: NDArray[np.float64], t: float) -> MarkerDetection:
        self.frames += 1
        pts = self.locate(H_wc)
        if pts is None:
            self.last_center = self.prev_center = None
            return MarkerDetection(t, None)
        centre = pts.mean(axis=0)
        self.prev_center, self.last_center = self.last_center, centre
        H, err = self.solve(pts)
        if H is not None:
            self.last = H
        return MarkerDetection(t, H, err if H is not None else 0.0)
