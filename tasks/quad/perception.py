"""Perception of the visual-path follower on rendered pixels (Toro-Arcila et al., Alg. 1 and §5).

* ``matchingKeyPoints``: ORB (default) or SIFT keypoints and descriptors, brute-force matching with
  Lowe's ratio test, RANSAC on a homography (planar / small-parallax scenes) or on the fundamental
  matrix (general scenes) to keep the inliers — :func:`match_keyframe`.
* ``sortPoints``: the three points of the largest triangle first (:func:`taskflow_tasks.quad.homography.sort_points`).
* ``tracking``: pyramidal Lucas–Kanade with a forward–backward check, each point re-anchored on its
  keyframe patch through the homography of the tracked plane, so frame-to-frame drift does not add
  up — :class:`PointTracker`.
* ``computeHomography``: the Euclidean homography (current → keyframe) from the tracked points, either
  the RANSAC homography of the dominant plane or the generic homography of the virtual plane through
  the three points (Malis & Chaumette 2000) — :func:`estimate_homography`.
* Obstacle: colour segmentation (HSV range) → bounding box of the largest blob → its two edge points
  at the middle row of the image (§5.1) — :func:`obstacle_edges`.

Images are numpy arrays: RGB ``(H, W, 3)`` uint8 or grey ``(H, W)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.quad.homography import (
    normalize_homography,
    normalize_pixels,
    sort_points,
    virtual_plane_homography,
)

Array = NDArray[np.float64]

__all__ = [
    "Features",
    "ObstacleDetection",
    "PointTracker",
    "anchor_on_keyframe",
    "detect",
    "estimate_homography",
    "make_detector",
    "match_keyframe",
    "obstacle_edges",
    "to_grey",
    "transfer_errors",
]


def to_grey(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Grey image from RGB (or pass a grey image through)."""
    if image.ndim == 2:
        return image
    return np.asarray(cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY), dtype=np.uint8)


def make_detector(kind: str, n_features: int) -> cv2.Feature2D:
    """``orb`` (default of this port; fast) or ``sift`` (the paper's detector; ~2x slower)."""
    if kind == "orb":
        return cv2.ORB.create(nfeatures=n_features, scaleFactor=1.2, nlevels=6, edgeThreshold=15, patchSize=15,
                              fastThreshold=12)
    if kind == "sift":
        return cv2.SIFT.create(nfeatures=n_features)
    raise ValueError(f"unknown feature detector {kind!r}: use 'orb' or 'sift'")


@dataclass(frozen=True)
class Features:
    """Keypoint locations ``(N, 2)`` (px) and their descriptors; ``kind`` is the detector."""

    pts: NDArray[np.float32]
    des: NDArray[np.uint8] | NDArray[np.float32] | None
    kind: str


def detect(detector: cv2.Feature2D, grey: NDArray[np.uint8], kind: str) -> Features:
    kps, des = detector.detectAndCompute(grey, None)
    pts = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
    if des is None:
        return Features(pts, None, kind)
    return Features(pts, np.asarray(des, dtype=np.uint8) if kind == "orb" else np.asarray(des, dtype=np.float32), kind)


Criteria = tuple[int, int, float]
LK_CRITERIA: Criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)


def _lk(prev: NDArray[np.uint8], nxt: NDArray[np.uint8], pts: NDArray[np.float32], init: NDArray[np.float32] | None,
        win: int, levels: int, criteria: Criteria = LK_CRITERIA, flags: int = 0) -> tuple[NDArray[np.float32],
                                                                                        NDArray[np.uint8]]:
    """Pyramidal LK from ``prev`` to ``nxt`` for ``pts`` ``(N, 1, 2)``, started at ``init`` with
    ``flags=cv2.OPTFLOW_USE_INITIAL_FLOW`` (``None``: at ``pts``); the found points and their status."""
    p1, st, _ = cv2.calcOpticalFlowPyrLK(prev, nxt, pts, init,  # type: ignore[arg-type]  # the stubs want nextPts; None lets OpenCV allocate it
                                         winSize=(win, win), maxLevel=levels, criteria=criteria, flags=flags)
    return np.asarray(p1, dtype=np.float32), np.asarray(st, dtype=np.uint8)


def match_keyframe(kf: Features, cur: Features, ratio: float = 0.8, ransac_px: float = 2.0,
                   model: str = "homography") -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """``matchingKeyPoints`` of Alg. 1: ratio-test matches filtered by RANSAC; returns the matched
    ``(current_px, keyframe_px)`` inliers, ordered by :func:`taskflow_tasks.quad.homography.sort_points`.

    ``model`` is the RANSAC model: ``homography`` (scene seen as one plane: right for small parallax or
    a dominant wall) or ``fundamental`` (any rigid scene; needs ≥ 8 matches).
    """
    empty = (np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32))
    if kf.des is None or cur.des is None or len(kf.pts) < 4 or len(cur.pts) < 4:
        return empty
    norm = cv2.NORM_HAMMING if kf.kind == "orb" else cv2.NORM_L2
    knn = cv2.BFMatcher(norm).knnMatch(kf.des, cur.des, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < ratio * m[1].distance]
    if len(good) < 8:
        return empty
    kpts = kf.pts[[m.queryIdx for m in good]]
    cpts = cur.pts[[m.trainIdx for m in good]]
    # one keyframe point per current point (a many-to-one match is ambiguous)
    _, first = np.unique(np.round(cpts, 1), axis=0, return_index=True)
    keep = np.sort(first)
    kpts, cpts = kpts[keep], cpts[keep]
    if len(kpts) < 8:
        return empty
    if model == "fundamental":
        _, mask = cv2.findFundamentalMat(cpts, kpts, cv2.FM_RANSAC, ransac_px, 0.999)
    else:
        _, mask = cv2.findHomography(cpts, kpts, cv2.RANSAC, ransac_px)
    if mask is None:
        return empty
    inl = mask.ravel().astype(bool)
    cpts, kpts = cpts[inl], kpts[inl]
    if len(cpts) < 3:
        return empty
    try:
        order = sort_points(kpts)
    except ValueError:
        return empty
    return cpts[order], kpts[order]


class PointTracker:
    """Pyramidal Lucas–Kanade tracking of the current points from frame to frame (``tracking`` of
    Alg. 1), with a forward–backward consistency check; lost points are dropped together with their
    keyframe partners, and the largest-triangle order is restored when one of its three points goes."""

    def __init__(self, grey: NDArray[np.uint8], cur_px: ArrayLike, kf_px: ArrayLike, win: int = 21,
                 levels: int = 3, fb_px: float = 1.0) -> None:
        self.prev = grey
        self.cur = np.asarray(cur_px, dtype=np.float32).reshape(-1, 2)
        self.kf = np.asarray(kf_px, dtype=np.float32).reshape(-1, 2)
        self.win, self.levels = win, levels
        self.fb_px = fb_px

    def __len__(self) -> int:
        return len(self.cur)

    def track(self, grey: NDArray[np.uint8]) -> int:
        """Track into ``grey``; returns the number of points kept."""
        if len(self.cur) == 0:
            self.prev = grey
            return 0
        p0 = self.cur.reshape(-1, 1, 2)
        p1, st = _lk(self.prev, grey, p0, None, self.win, self.levels)
        p0r, st2 = _lk(grey, self.prev, p1, None, self.win, self.levels)
        h, w = grey.shape[:2]
        p1 = p1.reshape(-1, 2)
        fb = np.linalg.norm(p0r.reshape(-1, 2) - self.cur, axis=1)
        ok = (st.ravel() == 1) & (st2.ravel() == 1) & (fb < self.fb_px)
        ok &= (p1[:, 0] >= 0) & (p1[:, 0] <= w - 1) & (p1[:, 1] >= 0) & (p1[:, 1] <= h - 1)
        tri_lost = not bool(np.all(ok[:3])) if len(ok) >= 3 else True
        self.cur, self.kf = p1[ok], self.kf[ok]
        self.prev = grey
        if tri_lost:
            self._restore_triangle()
        return len(self.cur)

    def _restore_triangle(self) -> None:
        """Put the largest-triangle points first again after one of them was dropped (Alg. 1)."""
        if len(self.kf) < 3:
            return
        try:
            order = sort_points(self.kf)
        except ValueError:
            return
        self.cur, self.kf = self.cur[order], self.kf[order]

    def add(self, cur_px: ArrayLike, kf_px: ArrayLike) -> None:
        """Append correspondences after the tracked ones (the largest-triangle points stay first; with
        fewer than three tracked points the triangle is chosen again)."""
        short = len(self.cur) < 3
        self.cur = np.vstack((self.cur, np.asarray(cur_px, dtype=np.float32).reshape(-1, 2)))
        self.kf = np.vstack((self.kf, np.asarray(kf_px, dtype=np.float32).reshape(-1, 2)))
        if short:
            self._restore_triangle()

    def prune(self, keep: NDArray[np.bool_]) -> None:
        """Drop the points where ``keep`` is false (e.g. off the tracked plane); the largest-triangle
        order is restored if one of its vertices goes."""
        keep = np.asarray(keep, dtype=bool)
        tri_lost = not bool(np.all(keep[:3]))
        self.cur, self.kf = self.cur[keep], self.kf[keep]
        if tri_lost:
            self._restore_triangle()

    def refine(self, kf_grey: NDArray[np.uint8], grey: NDArray[np.uint8], G: ArrayLike | None = None,
               max_shift: float = 2.0, fb_px: float = 0.3, win: int = 15) -> int:
        """Re-anchor the current points on the keyframe's texture: removes the drift that frame-to-frame
        tracking accumulates and the keypoint quantisation of the detector (ORB pyramid levels).

        With ``G`` (current px → keyframe px, the homography of the tracked plane) each point is found
        again by :func:`anchor_on_keyframe`; a point whose keyframe patch is found more than
        ``max_shift`` px from where it is tracked is dropped (its track has slipped, or the patch is
        ambiguous: either way the correspondence is not trusted).  Without ``G`` the keyframe patches
        are searched in ``grey`` itself from the tracked positions (valid near the keyframe view only)
        and a point moves when the correction is below ``max_shift`` px.  Returns the number of points
        moved."""
        if len(self.cur) == 0:
            return 0
        if G is not None:
            found, ok = anchor_on_keyframe(kf_grey, grey, self.kf, G, fb_px=fb_px, win=win)
            near = np.linalg.norm(found - self.cur, axis=1) < max_shift
            self.cur[ok & near] = found[ok & near]
            if np.any(ok & ~near):
                self.prune(~(ok & ~near))
            return int(np.sum(ok & near))
        p0 = self.kf.reshape(-1, 1, 2)
        p1, st = _lk(kf_grey, grey, p0, self.cur.reshape(-1, 1, 2).copy(), win, 1, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        back, st2 = _lk(grey, kf_grey, p1, p0.copy(), win, 1, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        p1 = p1.reshape(-1, 2)
        ok = (st.ravel() == 1) & (st2.ravel() == 1)
        ok &= np.linalg.norm(p1 - self.cur, axis=1) < max_shift
        ok &= np.linalg.norm(back.reshape(-1, 2) - self.kf, axis=1) < fb_px
        self.cur[ok] = p1[ok]
        return int(ok.sum())


def anchor_on_keyframe(kf_grey: NDArray[np.uint8], grey: NDArray[np.uint8], kf_px: ArrayLike, G: ArrayLike,
                       fb_px: float = 0.3, win: int = 15) -> tuple[Array, NDArray[np.bool_]]:
    """Where the keyframe patches around ``kf_px`` are in the current image ``grey``, through the
    homography ``G`` (current px → keyframe px) of the plane they lie on.

    ``grey`` is warped into the keyframe's geometry, ``W(x) = grey(G⁻¹ x)``: around a point of that
    plane ``W`` shows the keyframe's scale, rotation and perspective, so pyramidal LK (keyframe image
    → ``W``, started at the keyframe location) only has a small translation left to find, at any
    distance from the keyframe view, and ``G`` need not be exact.  Returns the current pixels
    (``G⁻¹`` of what LK found) and which are valid: LK converged both ways, tracking back lands within
    ``fb_px`` of the keyframe location, and the window lies inside the current image (past its border
    ``W`` is black fill)."""
    k = np.asarray(kf_px, dtype=np.float32).reshape(-1, 2)
    if len(k) == 0:
        return np.zeros((0, 2), dtype=np.float64), np.zeros(0, dtype=bool)
    Gm = np.asarray(G, dtype=np.float64).reshape(3, 3)
    G_inv = np.linalg.inv(Gm)
    h, w = kf_grey.shape[:2]
    target = np.asarray(cv2.warpPerspective(grey, Gm, (w, h), flags=cv2.INTER_LINEAR), dtype=np.uint8)
    p0 = k.reshape(-1, 1, 2)
    p1, st = _lk(kf_grey, target, p0, p0.copy(), win, 1, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
    back, st2 = _lk(target, kf_grey, p1, p0.copy(), win, 1, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
    found = np.asarray(cv2.perspectiveTransform(np.asarray(p1, dtype=np.float64).reshape(-1, 1, 2), G_inv),
                       dtype=np.float64).reshape(-1, 2)
    ok = _window_inside(k, G_inv, 0.5 * win + 1.0, grey.shape[:2]) & (st.ravel() == 1) & (st2.ravel() == 1)
    ok &= np.all(np.isfinite(found), axis=1) & (np.linalg.norm(back.reshape(-1, 2) - k, axis=1) < fb_px)
    return found, ok


def _window_inside(kf_px: ArrayLike, G_inv: ArrayLike, half: float, shape: tuple[int, ...]) -> NDArray[np.bool_]:
    """Whether the square of half-size ``half`` around each keyframe point, mapped by ``G_inv`` into the
    current image, lies inside it (a window reaching past the border would see the warp's black fill)."""
    d = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    corners = (np.asarray(kf_px, dtype=np.float64).reshape(-1, 1, 2) + d[None, :, :]).reshape(-1, 1, 2)
    q = cv2.perspectiveTransform(corners, np.asarray(G_inv, dtype=np.float64)).reshape(-1, 4, 2)
    h, w = shape
    ok = np.all(np.isfinite(q), axis=(1, 2))
    with np.errstate(invalid="ignore"):
        ok &= np.all((q[..., 0] >= 0.0) & (q[..., 0] <= w - 1) & (q[..., 1] >= 0.0) & (q[..., 1] <= h - 1), axis=1)
    return np.asarray(ok, dtype=np.bool_)


def transfer_errors(G: NDArray[np.float64], cur_px: ArrayLike, kf_px: ArrayLike) -> NDArray[np.float64]:
    """Pixel distance between ``G`` applied to the current points and their keyframe partners."""
    c = np.asarray(cur_px, dtype=np.float64).reshape(-1, 2)
    k = np.asarray(kf_px, dtype=np.float64).reshape(-1, 2)
    q = np.column_stack((c, np.ones(len(c)))) @ np.asarray(G, dtype=np.float64).T
    return np.hypot(q[:, 0] / q[:, 2] - k[:, 0], q[:, 1] / q[:, 2] - k[:, 1])


def estimate_homography(cur_px: ArrayLike, kf_px: ArrayLike, K: ArrayLike, mode: str = "ransac",
                        ransac_px: float = 2.0, robust: bool = True) -> tuple[Array, NDArray[np.bool_]]:
    """``computeHomography`` of Alg. 1: the Euclidean homography ``H`` (``m* ∝ H m``) and the inlier
    mask.

    * ``ransac``: the homography of the dominant plane — RANSAC (``robust``) then a least-squares
      refit on its inliers; with ``robust=False`` a least-squares fit on all points (for a point set
      already restricted to one plane, e.g. by :meth:`PointTracker.prune`: no random inlier subsets,
      so no frame-to-frame jumps);
    * ``virtual_plane``: the plane through the first three points (the largest triangle, Alg. 1)
      with the epipolar geometry from all points (Malis & Chaumette 2000).  When the points are
      consistent with a single homography (no measurable parallax, e.g. near the keyframe) the
      epipolar geometry is undefined and the plane homography is used, as every plane then induces
      the same one.
    """
    c = np.asarray(cur_px, dtype=np.float64).reshape(-1, 2)
    k = np.asarray(kf_px, dtype=np.float64).reshape(-1, 2)
    Kq = np.asarray(K, dtype=np.float64)
    if len(c) < 4 or len(c) != len(k):
        raise ValueError(f"need >= 4 correspondences, got {len(c)}")
    if mode not in ("ransac", "virtual_plane"):
        raise ValueError(f"unknown homography mode {mode!r}: use 'ransac' or 'virtual_plane'")
    if robust:
        G, mask = cv2.findHomography(c, k, cv2.RANSAC, ransac_px)
        if G is None:
            raise ValueError("homography estimation failed")
        inl = mask.ravel().astype(bool)
        if inl.sum() >= 4:
            G2, _ = cv2.findHomography(c[inl], k[inl], 0)
            G = G2 if G2 is not None else G
    else:
        G, _ = cv2.findHomography(c, k, 0)
        if G is None:
            raise ValueError("homography estimation failed")
        inl = transfer_errors(np.asarray(G, dtype=np.float64), c, k) < ransac_px
    m, ms = normalize_pixels(c, Kq), normalize_pixels(k, Kq)
    if mode == "ransac" or len(c) < 8 or inl.mean() > 0.9:
        return normalize_homography(G, Kq, m[inl], ms[inl]), inl
    # fundamental matrix in normalised coordinates (m*^T F m = 0)
    F, fmask = cv2.findFundamentalMat(m, ms, cv2.FM_RANSAC, ransac_px / Kq[0, 0], 0.999)
    if F is None or F.shape != (3, 3):
        return normalize_homography(G, Kq, m[inl], ms[inl]), inl
    try:
        Hv = virtual_plane_homography(F, m[:3], ms[:3])
        Gv = Kq @ Hv @ np.linalg.inv(Kq)
        return normalize_homography(Gv, Kq, m[:3], ms[:3]), fmask.ravel().astype(bool)
    except ValueError:
        return normalize_homography(G, Kq, m[inl], ms[inl]), inl


@dataclass(frozen=True)
class ObstacleDetection:
    """A segmented obstacle: bounding box ``(u0, v0, u1, v1)`` (px, inclusive), its two edge points
    ``p1`` (left) and ``p2`` (right) at the middle row of the image (px), and its pixel area."""

    bbox: tuple[int, int, int, int]
    p1: tuple[float, float]
    p2: tuple[float, float]
    area: int
    touches_border: bool


def obstacle_edges(rgb: NDArray[np.uint8], hsv_low: ArrayLike = (48, 120, 60), hsv_high: ArrayLike = (75, 255, 255),
                   min_area: int = 80, min_aspect: float = 1.5) -> ObstacleDetection | None:
    """Colour segmentation of the obstacle (§5.1, Fig. 4): pixels within ``[hsv_low, hsv_high]``
    (OpenCV HSV, hue 0–180), largest connected blob, its bounding box and the edge points ``p1``,
    ``p2`` at the image's middle row.  ``None`` when no blob reaches ``min_area`` pixels or the blob
    is not a column (bounding box less than ``min_aspect`` times taller than wide, unless it spans
    the image height)."""
    hsv = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2HSV)
    mask = cv2.inRange(hsv, np.asarray(hsv_low, dtype=np.uint8), np.asarray(hsv_high, dtype=np.uint8))
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    i = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    area = int(stats[i, cv2.CC_STAT_AREA])
    if area < min_area:
        return None
    u0, v0 = int(stats[i, cv2.CC_STAT_LEFT]), int(stats[i, cv2.CC_STAT_TOP])
    u1 = u0 + int(stats[i, cv2.CC_STAT_WIDTH]) - 1
    v1 = v0 + int(stats[i, cv2.CC_STAT_HEIGHT]) - 1
    h, w = mask.shape
    if (v1 - v0 + 1) < min_aspect * (u1 - u0 + 1) and not (v0 <= 0 and v1 >= h - 1):
        return None
    vm = 0.5 * (h - 1)
    border = u0 <= 0 or u1 >= w - 1
    # edges as pixel boundaries: the left edge of column u0 and the right edge of column u1
    return ObstacleDetection((u0, v0, u1, v1), (u0 - 0.5, vm), (u1 + 0.5, vm), area, border)
