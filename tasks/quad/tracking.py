"""The rendered camera's correspondences: keypoint matching, then Lucas–Kanade tracking (Alg. 1).

:class:`ImageCorrespondences` implements :class:`~taskflow_tasks.quad.correspondences.Correspondences`
on rendered frames with the pieces of :mod:`taskflow_tasks.quad.perception`: the keyframe is matched
once (``matchingKeyPoints``, with a larger budget when too few match: :func:`match_with_retry`), the
points are then tracked from frame to frame, pruned to the plane of ``H``, re-anchored on their
keyframe patches (``anchor``) and topped up by matching again when the set has shrunk
(``refresh_fraction``).  What the keyframe images give is memoised per run in ``TaskContext.cache``
(derived from the run's constant keyframes, shared by the states of one run, not mission data — an
empty cache only costs time).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.quad.correspondences import KEYFRAMES, Lost, Matched, Pairs, Rebase, camera_view, keyframe_image
from taskflow_tasks.quad.gains import HierarchyGains
from taskflow_tasks.quad.homography import mean_pixel_error
from taskflow_tasks.quad.params import RematchParams, VisualPathParams
from taskflow_tasks.quad.perception import (
    Features,
    PointTracker,
    detect,
    estimate_homography,
    make_detector,
    match_keyframe,
    obstacle_edges,
    to_grey,
)

from taskflow.api import Observation
from taskflow.messages import Image

Array = NDArray[np.float64]
Points = NDArray[np.float32]

__all__ = ["ImageCorrespondences", "image_pairs", "keyframe_features", "match_with_retry"]


def keyframe_features(cache: dict[str, Any], image: NDArray[np.uint8], kf_id: int, kind: str, n: int) -> Features:
    """Keypoints and descriptors of keyframe ``kf_id`` (``n`` of detector ``kind``), memoised in ``cache``."""
    memo: dict[tuple[int, str, int], Features] = cache.setdefault("visual_path.keyframe_features", {})
    key = (kf_id, kind, n)
    if key not in memo:
        memo[key] = detect(make_detector(kind, n), to_grey(image), kind)
    return memo[key]


def match_with_retry(cache: dict[str, Any], kf_image: NDArray[np.uint8], kf_id: int, grey: NDArray[np.uint8],
                     p: VisualPathParams | RematchParams, model: str = "homography") -> tuple[Points, Points]:
    """``matchingKeyPoints`` of the current frame against keyframe ``kf_id``, with ``p.n_features``
    keypoints per image and, when that gives fewer than ``p.min_points`` inliers, once more with
    ``p.retry_scale`` times as many.

    Each image keeps its strongest keypoints over its whole area; when the view shares only a part of
    the keyframe (the drone off the taught pose, e.g. cutting a curve), few of those fall in the shared
    part of both images, and a larger budget finds the matches that are there (ORB at an oval's last
    keyframes: 9 RANSAC inliers with 1000 keypoints, 34 with 3000)."""
    budgets = [p.n_features] + ([p.n_features * p.retry_scale] if p.retry_scale > 1 else [])
    cur = kfp = np.zeros((0, 2), np.float32)
    for n in budgets:
        kf = keyframe_features(cache, kf_image, kf_id, p.features, n)
        cur, kfp = match_keyframe(kf, detect(make_detector(p.features, n), grey, p.features), model=model)
        if len(cur) >= p.min_points:
            break
    return cur, kfp


def image_pairs(keyframes: tuple[NDArray[np.uint8], ...], kind: str = "orb", n_features: int = 1000,
                cache: dict[str, Any] | None = None) -> Pairs:
    """For each segment ``k → k+1``: the matched pixels in keyframe ``k``'s image and their partners in
    ``k+1``'s (RANSAC inliers, largest triangle first)."""
    mem = cache if cache is not None else {}
    out: Pairs = []
    for k in range(len(keyframes) - 1):
        fa = keyframe_features(mem, keyframes[k], k, kind, n_features)
        fb = keyframe_features(mem, keyframes[k + 1], k + 1, kind, n_features)
        cur, kf = match_keyframe(fb, fa)  # (points in k, points in k+1)
        out.append((cur, kf))
    return out


class ImageCorrespondences:
    """Rendered frames: matched keypoints, tracked by LK, pruned to one plane and anchored on the keyframe."""

    def __init__(self, params: VisualPathParams, hier: HierarchyGains, K: Array, cache: dict[str, Any]) -> None:
        self.p, self.hier, self.K, self.cache = params, hier, K, cache
        self.tracker: PointTracker | None = None
        self.n_matched = 0

    @property
    def name(self) -> str:
        return self.p.features

    def _model(self) -> str:
        return "homography" if self.p.homography == "ransac" else "fundamental"

    def _kf_grey(self, obs: Observation) -> NDArray[np.uint8]:
        memo: dict[int, NDArray[np.uint8]] = self.cache.setdefault("visual_path.keyframe_grey", {})
        k = self.p.keyframe.id
        if k not in memo:
            memo[k] = to_grey(keyframe_image(obs, k))
        return memo[k]

    def match(self, obs: Observation) -> Matched | Lost:
        p = self.p
        view = camera_view(obs)
        if not isinstance(view, Image):
            raise RuntimeError("visual_path_servo: the camera switched from images to landmarks (internal error)")
        image = view.pixels
        grey = to_grey(image)
        rebase = None
        if self.tracker is None:
            cur, kfp = match_with_retry(self.cache, keyframe_image(obs, p.keyframe.id), p.keyframe.id, grey, p,
                                        self._model())
            if len(cur) < p.min_points:
                return Lost({"n_points": float(len(cur)), "keyframe": float(p.keyframe.id)})
            self.tracker = PointTracker(grey, cur, kfp)
            self.n_matched = len(cur)
        else:
            n, rebase = self._track(obs, grey)
            if n < p.min_points:
                return Lost({"n_points": float(len(self.tracker))}, rebase)
        tr = self.tracker
        try:
            # RANSAC + least-squares refit; points that stop fitting the plane (off-plane as parallax
            # grows, or mistracked) are dropped for good, so the set settles on one plane and H does not
            # jump between inlier subsets from frame to frame
            H, fits = estimate_homography(tr.cur, tr.kf, self.K, p.homography, p.plane_px)
            if not fits.all() and fits.sum() >= p.min_points:
                tr.prune(fits)
            if p.anchor:
                # re-anchor every point on its keyframe patch through the plane's homography (drift of
                # frame-to-frame LK would otherwise add up), then H from the anchored points
                Hp = H if p.homography == "ransac" else estimate_homography(tr.cur, tr.kf, self.K, "ransac", p.plane_px)[0]
                G = self.K @ Hp @ np.linalg.inv(self.K)
                tr.refine(self._kf_grey(obs), grey, G)
                H, _ = estimate_homography(tr.cur, tr.kf, self.K, p.homography, p.plane_px)
        except ValueError:
            return Lost(rebase=rebase)
        hier = self.hier
        obstacle = obstacle_edges(image, hier.hsv_low, hier.hsv_high, hier.min_obstacle_px) if hier.collision else None
        return Matched(tr.cur, tr.kf, H, obstacle, rebase)

    def _track(self, obs: Observation, grey: NDArray[np.uint8]) -> tuple[int, Rebase | None]:
        """Track into ``grey``; once the set has shrunk below ``refresh_fraction`` of what the last
        matching gave (points left the view or stopped fitting the plane), match the keyframe again and
        add the new matches, so the set keeps covering what the view shares with the keyframe (entered
        far from it, the drone keeps the few points of that first view otherwise, and H from a small
        cluster is ill-conditioned).  Returns the number of points, and how ε's scale changed when
        points were added (ε is a mean over the set: the law keeps its history on the new set's scale)."""
        tr, p = self.tracker, self.p
        if tr is None:
            raise RuntimeError("visual_path_servo: tracking before matching (internal error)")
        n = tr.track(grey)
        if n >= p.min_points and n >= p.refresh_fraction * self.n_matched:
            return n, None
        eps_old = mean_pixel_error(tr.cur, tr.kf) if n else 0.0
        cur, kfp = match_with_retry(self.cache, keyframe_image(obs, p.keyframe.id), p.keyframe.id, grey, p,
                                    self._model())
        if len(kfp) and n:
            new = np.min(np.linalg.norm(kfp[:, None, :] - tr.kf[None, :, :], axis=2), axis=1) > 2.0
            cur, kfp = cur[new], kfp[new]
        rebase = None
        if len(kfp):
            tr.add(cur, kfp)
            rebase = Rebase(mean_pixel_error(tr.cur, tr.kf) / eps_old if eps_old > 1e-6 else None)
        self.n_matched = len(tr)
        return len(tr), rebase

    def keyframe_pairs(self, obs: Observation) -> Pairs:
        images = KEYFRAMES(obs)
        if images is None:
            raise RuntimeError("visual_path_servo: feed-forward needs the keyframe images (sensors.keyframes)")
        kfs = tuple(k.pixels for k in images)
        return image_pairs(kfs, self.p.features, self.p.n_features, self.cache)
