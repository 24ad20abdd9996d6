"""What matches between the current image and a keyframe: the interface behind ``visual_path_servo``.

Both perception pipelines of the visual-path tasks answer the same question each frame — which
current pixels correspond to which keyframe pixels (largest triangle first), the homography of the
plane they lie on, and the obstacle in view — and the servo law (:class:`~taskflow_tasks.quad.law.ServoLaw`)
only ever sees that answer (:class:`Matched`) or that there is none (:class:`Lost`):

* :class:`LandmarkCorrespondences` (this module): the world's geometric camera, whose
  :class:`~taskflow.messages.FeatureView` names each landmark, so correspondences are by id;
* :class:`~taskflow_tasks.quad.tracking.ImageCorrespondences`: rendered frames, ORB/SIFT matching
  and Lucas–Kanade tracking (:mod:`taskflow_tasks.quad.perception`).

The type of the camera's message (:func:`camera_view`) chooses the pipeline.  Each also gives the
correspondences between consecutive keyframes (:meth:`Correspondences.keyframe_pairs`), from which
the feed-forward of Alg. 2 is computed (:mod:`taskflow_tasks.quad.feedforward`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.quad.gains import HierarchyGains
from taskflow_tasks.quad.homography import sort_points
from taskflow_tasks.quad.params import VisualPathParams
from taskflow_tasks.quad.perception import ObstacleDetection, estimate_homography

from taskflow.api import Observation, ObsKey, sequence
from taskflow.messages import FeatureView, Image, Silhouette

Array = NDArray[np.float64]
Pixels = NDArray[np.floating[Any]]  # (N, 2) px: float64 landmarks, float32 tracked keypoints
Pairs = list[tuple[Pixels, Pixels]]

__all__ = [
    "IMAGE",
    "KEYFRAMES",
    "KEYFRAME_POINTS",
    "OBSTACLE",
    "POINTS",
    "Correspondences",
    "LandmarkCorrespondences",
    "Lost",
    "Matched",
    "Pairs",
    "Pixels",
    "Rebase",
    "by_id",
    "camera_view",
    "count_landmark_matches",
    "keyframe_image",
    "silhouette_detection",
]

# the camera's messages: one per frame, a FeatureView (geometric camera) or an Image (rendered), and the
# keyframes' messages of the same type; the world's perception mode decides which pair it sends
POINTS = ObsKey("sensors.points", FeatureView, optional=True)
KEYFRAME_POINTS: ObsKey[Sequence[FeatureView] | None] = ObsKey("sensors.keyframe_points",
                                                               sequence(optional=True, of=FeatureView))
IMAGE = ObsKey("sensors.image", Image, optional=True)
KEYFRAMES: ObsKey[Sequence[Image] | None] = ObsKey("sensors.keyframes", sequence(optional=True, of=Image))
OBSTACLE = ObsKey("sensors.obstacle", Silhouette, optional=True)  # the geometric camera's column silhouette


@dataclass(frozen=True)
class Rebase:
    """The point set changed on this frame (re-matched points were added): ``ratio`` is ε of the new
    set over ε of the old one (``None``: no old point left), for :meth:`ServoLaw.rebase`."""

    ratio: float | None


@dataclass(frozen=True)
class Matched:
    """This frame's correspondences: current and keyframe pixels ``(N, 2)`` (the largest triangle's
    three first), the Euclidean homography ``H`` (current → keyframe) and the obstacle in view."""

    cur: Pixels
    kf: Pixels
    H: Array
    obstacle: ObstacleDetection | None
    rebase: Rebase | None = None


@dataclass(frozen=True)
class Lost:
    """Too few correspondences (or no homography) on this frame: the task hovers and raises
    ``features_lost``; ``metrics`` update the metrics it holds."""

    metrics: dict[str, float] = field(default_factory=dict)
    rebase: Rebase | None = None


class Correspondences(Protocol):
    """A perception pipeline of ``visual_path_servo`` for one keyframe (it may keep state from frame to
    frame: tracked points, the plane of ``H``)."""

    @property
    def name(self) -> str:
        """What the correspondences come from (part of the feed-forward's cache key)."""
        ...

    def match(self, obs: Observation) -> Matched | Lost:
        """This frame's correspondences with the keyframe being servoed to."""
        ...

    def keyframe_pairs(self, obs: Observation) -> Pairs:
        """For each segment ``k → k+1`` of the path: the pixels in keyframe ``k`` and their partners in
        keyframe ``k+1`` (largest triangle first when there are enough)."""
        ...


def camera_view(obs: Observation) -> FeatureView | Image:
    """This tick's camera message, whose type chooses the perception pipeline: the geometric camera's
    landmark :class:`FeatureView` (``sensors.points``: correspondences by id) or the rendered camera's
    :class:`Image` (``sensors.image``: ORB matching and LK tracking)."""
    view = POINTS(obs)
    if view is not None:
        return view
    image = IMAGE(obs)
    if image is not None:
        return image
    raise RuntimeError("visual path tasks read the camera's sensors.points (FeatureView) or sensors.image (Image); "
                       f"this observation has: {', '.join(sorted(obs.sensors)) or 'no sensors'}")


def keyframe_image(obs: Observation, kf_id: int) -> NDArray[np.uint8]:
    """Keyframe ``kf_id``'s taught image (rendered camera)."""
    kfs = KEYFRAMES(obs)
    n = 0 if kfs is None else len(kfs)
    if kfs is None or kf_id >= n:
        raise RuntimeError(f"keyframe {kf_id} has no image: the world provides {n} keyframe images")
    pixels: NDArray[np.uint8] = kfs[kf_id].pixels
    return pixels


def keyframe_view(obs: Observation, kf_id: int) -> FeatureView:
    """Keyframe ``kf_id``'s taught landmark view (geometric camera)."""
    kf_views = KEYFRAME_POINTS(obs)
    n = 0 if kf_views is None else len(kf_views)
    if kf_views is None or kf_id >= n:
        raise RuntimeError(f"keyframe {kf_id} has no view: the world provides {n}")
    return kf_views[kf_id]


def by_id(view: FeatureView, kf: FeatureView) -> tuple[Array, Array, NDArray[np.int64]]:
    """Pixels of the landmarks seen in both ``view`` and ``kf`` (geometric camera), and their ids."""
    ids, i, j = np.intersect1d(view.ids, kf.ids, assume_unique=True, return_indices=True)
    return np.asarray(view.uv)[i], np.asarray(kf.uv)[j], ids


def silhouette_detection(edges: Silhouette | None, size: tuple[int, int], min_area: int) -> ObstacleDetection | None:
    """The geometric camera's column :class:`Silhouette` as the detection
    :func:`~taskflow_tasks.quad.perception.obstacle_edges` makes from pixels (a full-height blob)."""
    if edges is None:
        return None
    u0, u1, border = edges.u_left, edges.u_right, edges.touches_border
    w, h = size
    area = int(round((u1 - u0) * h))
    if area < min_area:
        return None
    vm = 0.5 * (h - 1)
    bbox = (max(0, int(math.ceil(u0 + 0.5))), 0, min(w - 1, int(math.floor(u1 - 0.5))), h - 1)
    return ObstacleDetection(bbox, (u0, vm), (u1, vm), area, bool(border))


def count_landmark_matches(view: FeatureView, kf: FeatureView, K: Array) -> int:
    """How many landmarks of ``kf`` are back in ``view`` on one plane (the homography's inliers; all
    of them below the 8 a robust fit needs)."""
    cur, kfp, _ = by_id(view, kf)
    return int(estimate_homography(cur, kfp, K)[1].sum()) if len(cur) >= 8 else len(cur)


class LandmarkCorrespondences:
    """The geometric camera's correspondences, by landmark id.

    As with tracked points, the first frame keeps the RANSAC inliers of one plane and later frames
    drop the points that stop fitting it; the largest triangle's landmarks stay first."""

    name = "points"

    def __init__(self, params: VisualPathParams, hier: HierarchyGains, K: Array, size: tuple[int, int]) -> None:
        self.p, self.hier, self.K, self.size = params, hier, K, size
        self.plane_ids: NDArray[np.int64] | None = None  # landmarks of the plane of H
        self.tri_ids: NDArray[np.int64] | None = None  # … and those of the largest triangle

    def match(self, obs: Observation) -> Matched | Lost:
        p = self.p
        view = camera_view(obs)
        if not isinstance(view, FeatureView):
            raise RuntimeError("visual_path_servo: the camera switched from landmarks to images (internal error)")
        cur, kfp, ids = by_id(view, keyframe_view(obs, p.keyframe.id))
        if self.plane_ids is not None:
            keep = np.isin(ids, self.plane_ids, assume_unique=True)
            cur, kfp, ids = cur[keep], kfp[keep], ids[keep]
        if len(ids) < p.min_points:
            return Lost({"n_points": float(len(ids)), "keyframe": float(p.keyframe.id)})
        try:
            H, fits = estimate_homography(cur, kfp, self.K, p.homography, p.plane_px)
        except ValueError:
            return Lost()
        if self.plane_ids is None or (not fits.all() and fits.sum() >= p.min_points):
            cur, kfp, ids = cur[fits], kfp[fits], ids[fits]
            self.plane_ids = ids
        in_tri = np.isin(ids, self.tri_ids, assume_unique=True) if self.tri_ids is not None else None
        if in_tri is None or in_tri.sum() < 3:
            self.tri_ids = ids[sort_points(kfp)[:3]]
            in_tri = np.isin(ids, self.tri_ids, assume_unique=True)
        order = np.concatenate((np.flatnonzero(in_tri), np.flatnonzero(~in_tri)))  # the triangle first
        hier = self.hier
        obstacle = silhouette_detection(OBSTACLE(obs), self.size, hier.min_obstacle_px) \
            if hier.collision else None
        return Matched(cur[order], kfp[order], H, obstacle)

    def keyframe_pairs(self, obs: Observation) -> Pairs:
        views = KEYFRAME_POINTS(obs)
        if views is None:
            raise RuntimeError("visual_path_servo: feed-forward needs the keyframes' views (sensors.keyframe_points)")
        return landmark_pairs(tuple(views))


def landmark_pairs(views: tuple[FeatureView, ...]) -> Pairs:
    """Keyframe ``k``'s and ``k+1``'s landmark views correspond by id (largest triangle first from 8)."""
    out: Pairs = []
    for a, b in zip(views[:-1], views[1:]):
        cur, kf, _ = by_id(a, b)
        if len(cur) >= 8:
            order = sort_points(kf)
            cur, kf = cur[order], kf[order]
        out.append((cur, kf))
    return out
