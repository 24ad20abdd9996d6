"""Visual path following for a quadcopter: one keyframe of the path per state (Toro-Arcila et al.).

``visual_path_servo`` drives the robot toward one keyframe image with the hierarchical homography-based
visual servoing of Alg. 1 (collision avoidance > visibility > visual task, eqs. 2–20), the keyframe
transition ``h_t`` (eqs. 28–30) and, optionally, the feed-forward term of Alg. 2 (eqs. 31–32).  A
mission iterates it over the path with ``foreach`` and switches keyframes on its metrics:

* ``epsilon`` (px): eq. (7), mean distance between the tracked points and their keyframe partners;
* ``epsilon_margin`` (px): ``ε − T_ε`` with ``T_ε = t_eps_px`` for intermediate keyframes and
  ``t_eps_final_px`` for the last one (``imgChVerif``: switch when ``epsilon_margin < 0 px``);
* ``epsilon_rising``: consecutive frames over which ε increased — counted only with feed-forward and
  not on the last keyframe (Alg. 2's second switching rule: ``epsilon_rising >= 5``);
* ``epsilon_progress`` (px): how much ε fell over the last ``progress_window_s`` (NaN until the
  keyframe has been servoed that long).  Not in the paper: with feed-forward the blend (31) has an
  equilibrium where ``p nu_e = −(1 − p) nu_p``, just past the keyframe; when the drone settles there
  with ε above ``T_ε`` and flat (the along-path error growing as fast as the cross-path error
  shrinks), neither of Alg. 2's rules fires and the drone hovers there.  A guard such as
  ``epsilon_progress < 0.5 px`` ends that stall.

Fewer than ``min_points`` matched points (the paper needs ≥ 16 for a well-conditioned homography), or
tracked points that a new matching of the keyframe cannot bring back to ``min_points``, raise the
``features_lost`` event and command a hover; ``visual_path_rematch`` hovers and re-matches until it
raises ``features_found``.

Only images (and, for the obstacle memory, the measured body velocity) are used: the current frame (``obs.sensors["image"]``, an :class:`~taskflow.messages.Image`)
and the keyframe images (``obs.sensors["keyframes"]``); the keyframe poses in the parameters are ground
truth for the world's summary and are never read here.  With the world's geometric camera the frame's
message is a :class:`~taskflow.messages.FeatureView` instead (``obs.sensors["points"]``, and
``["keyframe_points"]``: landmark ids and noisy pixels; ``["obstacle"]``: a column's
:class:`~taskflow.messages.Silhouette`): the type of the camera's message (:func:`camera_view`) chooses
the pipeline, correspondences by landmark id instead of ORB matching and LK tracking; everything from
the homography on is the same code.

Feed-forward (Alg. 2, lines 2–15): the velocity ``nu_p`` of each segment ``k → k+1`` is computed once
per run from the keyframe images (memoised in the run's cache, ``TaskContext.cache``) and applied while servoing toward
keyframe ``k`` (Alg. 2's ``vVec`` = ``k``); the last keyframe has no segment, so it is reached with
feedback alone.

Choices where the paper is silent or its reading would not work (each marked in the code):

* **Obstacle at the image border, and beside the drone.**  Eq. (8) needs both edges (§3.1); a blob
  touching the left or right border is leaving the field of view.  The paper's task then lets ``e_a``
  go to its reference and ``h_a`` decay (``hierarchy.memory: false``, the last ``J_a`` kept) — but the
  camera loses a column 0.4–0.6 m before the drone reaches it, and the visual task pulls the drone back
  into it.  By default (``memory: true``) the task remembers the obstacle in the body frame, carries it
  along with the measured body velocity (``state.nu``: odometry, the only non-image input) and acts on
  it until it is behind the drone (:mod:`~taskflow_tasks.quad.obstacle_memory`: eq. 8 seen from the body's
  centre, a keep-out distance ``keep_out_m``); the memory lasts across the keyframes of a run
  (mission data ``visual_path.obstacle``, not in the summary).
* **Symmetric block.**  With the obstacle dead ahead eq. (9) has no yaw term and the task only holds
  the drone back (rendered, it hovered in front of the column at ~1 mm/s).  When the task first
  activates for an obstacle it commits to a side (away from the obstacle's offset in the image, or
  ``escape_side`` when it is centred) and eq. (9) is evaluated with the obstacle at least
  ``escape_offset`` off the axis on the other side, so the drone turns and slides away
  (``escape_offset: 0`` or ``memory: false``: the paper's eq. 9).
* **Safety area.**  ``checkPoints`` only considers points whose keyframe location is inside the
  safety rectangle; otherwise a keyframe with features near its border keeps the visibility task
  active at the goal, where it fights the visual task.
* **Plane of H.**  Matching keeps the RANSAC inliers of one plane; every frame H is RANSAC + least
  squares on the tracked points and the points that stop fitting (parallax grows, mistracking) are
  dropped for good, so H does not jump between inlier subsets.
* **Anchoring on the keyframe.**  Frame-to-frame LK drifts (a few points reach 2–3.5 px after 10 s,
  growing smoothly, as the scale of the view changes), and detector keypoints (ORB pyramid levels)
  carry ~1 px biases.  With the tracked points on one wall a few metres away, a sideways offset and
  a yaw that cancel in the image change its points by ~1 px only, so those errors tilt the
  perspective row of H enough to hold the drone several cm to the side while the tracked ε says it
  has converged.  Every frame, after tracking, each point is therefore re-anchored on its keyframe
  patch (``anchor``): the current image is warped into the keyframe's geometry through the plane's
  homography and LK finds the keyframe patch in it (:meth:`PointTracker.refine`); H is then computed
  from the anchored points.
* **Re-matching with a larger budget.**  ``matchingKeyPoints`` keeps the ``n_features`` strongest
  keypoints of each whole image; when the view shares only a part of the keyframe (the drone off the
  taught path, e.g. cutting a curve) too few of them fall in the shared part and the keyframe is
  lost although it is in view.  Matching that finds fewer than ``min_points`` inliers detects again
  with ``retry_scale`` times the budget (:func:`match_with_retry`, also in ``visual_path_rematch``).
* **Matching again while tracking.**  Alg. 1 matches once per keyframe and then only tracks, so the
  set only shrinks (points leave the view or stop fitting the plane).  A keyframe entered far from
  its pose (feed-forward cutting a curve) kept the 16–40 points of that first view, a cluster from
  which H is ill-conditioned, while the view closed in on the keyframe.  Once the set has shrunk
  below ``refresh_fraction`` of the last matching, or below ``min_points``, the keyframe is matched
  again and the new matches are added (:meth:`VisualPathServo._track`); ε is a mean over the set, so
  its history is rescaled to the new set on that frame (:meth:`ServoLaw.rebase`) and the rising
  count and the progress do not read the change of set as motion.
* **Yaw decoupling** (``VisualGains.yaw_decoupling``, off by default).  ``e_v`` of eq. (2) holds the
  rotation as well as the translation, so law (3) answers a keyframe's yaw step with a sideways
  slide; on a curve ε (7) then passes ``T_ε`` with a sideways offset the yaw hides, and the offsets
  add up over the keyframes (the shipped oval was cut by 45–55 cm).  With it on, the yaw is estimated
  from H (:func:`~taskflow_tasks.quad.homography.homography_yaw`) and the translation and the yaw are driven
  separately (:func:`~taskflow_tasks.quad.homography.yaw_decoupled_error`), in the feedback and in ``nu_p``.
* **Feed-forward segment** (``PathGains.segment``).  Alg. 2 applies ``nu_p`` of segment ``k → k+1``
  while servoing to keyframe ``k`` (``next``), so the drone turns one keyframe early on a curve;
  ``current`` applies the segment being flown, ``k−1 → k`` (keyframe 0: ``0 → 1``).
* ``sigma`` may be set per keyframe (§5.2 uses 0.13 then 0.06 for its two obstacles).
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field, model_validator
from taskflow_robots.quadcopter import QuadCamera
from taskflow_tasks.quad.hierarchy import (
    Activation,
    collision_error,
    collision_jacobian,
    hierarchical_control,
    points_outside,
    transition_weight,
    visibility_error,
    visibility_jacobian,
)
from taskflow_tasks.quad.homography import (
    HomographyGains,
    adaptive_gain,
    feedforward_blend,
    feedforward_velocity,
    gain_matrix,
    homography_yaw,
    mean_pixel_error,
    normalize_pixels,
    robot_velocity,
    sort_points,
    task_error,
    yaw_decoupled_error,
)
from taskflow_tasks.quad.obstacle_memory import (
    LEFT,
    RIGHT,
    ObstacleMemory,
    RememberedObstacle,
    associate,
    closing_in,
    committed_edges,
    edges_in_body,
    escape_side,
    has_passed,
    propagate,
    remembered_collision,
)
from taskflow_tasks.quad.perception import (
    Features,
    ObstacleDetection,
    PointTracker,
    detect,
    estimate_homography,
    make_detector,
    match_keyframe,
    obstacle_edges,
    to_grey,
)

from taskflow.api import (
    COUNT,
    FLAG,
    WEIGHT,
    MemoryKey,
    Metric,
    Observation,
    ObsSpec,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
    array,
    instance,
    message,
    scalar,
    sequence,
)
from taskflow.messages import FeatureView, Image, Silhouette
from taskflow.registry import register_task
from taskflow.spatial import transform, twist_adjoint, vee

Vec3 = tuple[float, float, float]


# ---------------------------------------------------------------------------------------------
# profiles


class VisualGains(StrictModel):
    """Adaptive gain of eq. (4) and its spread over the axes of eq. (3).

    ``λ_v = v_scale λ + v_offset`` per camera axis (x right, y down, z forward),
    ``λ_w = w_scale λ + w_offset``.  Paper §5.1: ``λ0 = 2.8, λ∞ = 0.1, λ0' = 5``, ``λ_vy = λ + 2.5``,
    ``λ_w = 0.5 λ``.
    """

    lambda_0: float = Field(default=2.8, gt=0.0, le=100.0, description="gain at zero error")
    lambda_inf: float = Field(default=0.1, gt=0.0, le=100.0, description="gain at large error")
    lambda_0_slope: float = Field(default=5.0, gt=0.0, le=1000.0, description="|dλ/d‖e‖| at zero error")
    v_scale: Vec3 = (1.0, 1.0, 1.0)
    v_offset: Vec3 = (0.0, 2.5, 0.0)
    w_scale: float = Field(default=0.5, gt=0.0, le=100.0)
    w_offset: float = Field(default=0.0, ge=0.0, le=100.0)
    yaw_decoupling: bool = Field(default=False, description="estimate the yaw from H (homography.homography_yaw) and "
                                 "drive translation and yaw separately (homography.yaw_decoupled_error), so turning toward "
                                 "a keyframe does not slide the drone sideways; off: the paper's law (3)")

    @model_validator(mode="after")
    def _valid(self) -> VisualGains:
        if self.lambda_0 < self.lambda_inf:
            raise ValueError(f"lambda_0 ({self.lambda_0}) must be >= lambda_inf ({self.lambda_inf}): eq. 4's gain "
                             "grows as the error shrinks")
        if not all(0.0 <= s <= 100.0 for s in self.v_scale) or not any(s > 0.0 for s in self.v_scale):
            raise ValueError(f"v_scale entries must be in [0, 100] and not all zero, got {self.v_scale}")
        if not all(0.0 <= s <= 100.0 for s in self.v_offset):
            raise ValueError(f"v_offset entries must be in [0, 100], got {self.v_offset}")
        return self

    def homography_gains(self) -> HomographyGains:
        return HomographyGains(self.v_scale, self.v_offset, self.w_scale, self.w_offset)


class HierarchyGains(StrictModel):
    """The two upper tasks of the hierarchy (§3.1–3.2) and their activation (eq. 20).

    Paper §5.1: ``σ = 0.05``, ``λ_a = 0.01``, ``λ_m = 0.2``, ``c*_m`` = the image centre; activation of
    the collision task takes ~3 s (Fig. 10).  ``z_obstacle`` and ``z_scene`` are the constant depth
    estimates the monocular Jacobians (9) and (12) need.
    """

    collision: bool = True
    visibility: bool = True
    sigma: float = Field(default=0.05, gt=0.0, le=2.0, description="reference obstacle width (normalised)")
    lambda_a: float = Field(default=0.01, gt=0.0, le=100.0)
    lambda_m: float = Field(default=0.2, gt=0.0, le=100.0)
    activation_s: float = Field(default=3.0, gt=0.0, le=60.0, description="h_a rise/fall time (s)")
    visibility_activation_s: float = Field(default=3.0, gt=0.0, le=60.0, description="h_m rise/fall time (s)")
    z_obstacle: float = Field(default=1.0, gt=0.0, le=100.0, description="depth estimate of the obstacle (m)")
    z_scene: float = Field(default=3.0, gt=0.0, le=100.0, description="depth estimate of the scene (m)")
    safety_margin_px: float = Field(default=12.0, ge=0.0, le=1000.0, description="safety rectangle inset (px)")
    hsv_low: Vec3 = (48.0, 120.0, 60.0)
    hsv_high: Vec3 = (75.0, 255.0, 255.0)
    min_obstacle_px: int = Field(default=80, ge=1)
    memory: bool = Field(default=True, description="remember the obstacle in the body frame once it leaves the view and "
                         "keep the collision task on it until it is behind the body (obstacle_memory); off: the paper's "
                         "task, which lets h_a decay as soon as an edge leaves the image")
    obstacle_width: float | None = Field(default=None, gt=0.0, le=5.0,
                                         description="width (m) that places a seen obstacle in the body frame; "
                                                     "default sigma x z_obstacle (the width that looks sigma wide at "
                                                     "the depth estimate)")
    pass_margin_m: float = Field(default=0.3, ge=0.0, le=5.0,
                                 description="a remembered obstacle is forgotten once both its edges are this far "
                                             "behind the body's centre (m)")
    keep_out_m: float = Field(default=0.55, gt=0.0, le=5.0,
                              description="the collision task acts on a remembered obstacle once the body's centre "
                                          "is within this distance (m) of it")
    escape_offset: float = Field(default=0.1, ge=0.0, le=1.0,
                                 description="while the task is active, eq. 9 sees the obstacle's centre at least this "
                                             "far (normalised) off the optical axis on the side away from the committed "
                                             "escape side; 0: the paper's eq. 9")
    escape_side: Literal["left", "right"] = Field(default="left", description="escape side for an obstacle centred "
                                                  "within escape_offset / 2 when the task first activates")


class PathGains(StrictModel):
    """Keyframe transition (eq. 29: ``h0``, duration) and feed-forward (eqs. 31–32: ``γ``, ``p``).
    Paper §5.2: ``h0 = 0.2`` over 1.6 s; §5.3: ``γ = 0.75``, ``p = 0.5``."""

    h0: float = Field(default=0.2, ge=0.0, le=1.0)
    transition_s: float = Field(default=1.6, gt=0.0, le=60.0)
    gamma: float = Field(default=0.75, ge=0.0, le=1.0)
    p: float = Field(default=0.5, ge=0.0, le=1.0)
    segment: Literal["next", "current"] = Field(
        default="next", description="nu_p applied while servoing to keyframe k: next = segment k -> k+1 (Alg. 2's vVec); "
        "current = segment k-1 -> k, the one being flown (k = 0: 0 -> 1)")


# ---------------------------------------------------------------------------------------------
# parameters


class KeyframeRef(StrictModel):
    """A keyframe of the path: its index (into the world's keyframe images) and its taught pose
    (ground truth, unused by the control law)."""

    id: int = Field(ge=0)
    pose: tuple[float, float, float, float] | None = None
    sigma: float | None = Field(default=None, gt=0.0, le=2.0,
                                description="collision reference σ while servoing to this keyframe (§5.2 changes it per obstacle)")


class VisualPathParams(StrictModel):
    """One keyframe to servo to, the path it belongs to, the switching thresholds and the perception."""

    keyframe: KeyframeRef
    path: list[KeyframeRef] = Field(default_factory=list)
    t_eps_px: float = Field(default=12.0, gt=0.0, le=1000.0, description="T_ε of intermediate keyframes (px)")
    t_eps_final_px: float = Field(default=7.0, gt=0.0, le=1000.0, description="T_ε of the last keyframe (px)")
    feedforward: bool = False
    progress_window_s: float = Field(default=1.0, gt=0.0, le=60.0,
                                     description="window of the epsilon_progress metric (s)")
    transition: bool | None = Field(default=None, description="apply h_t (eq. 28); default: when the path has > 1 keyframe")
    features: Literal["orb", "sift"] = "orb"
    n_features: int = Field(default=1000, ge=50, le=20000)
    min_points: int = Field(default=16, ge=8, le=10000)
    homography: Literal["ransac", "virtual_plane"] = "ransac"
    plane_px: float = Field(default=3.0, gt=0.0, le=100.0,
                            description="transfer error beyond which a tracked point leaves the plane of H (px)")
    anchor: bool = Field(default=True, description="re-anchor the tracked points on their keyframe patches every frame "
                                                   "(through the homography of the tracked plane)")
    retry_scale: int = Field(default=4, ge=1, le=20,
                             description="when matching finds fewer than min_points, detect again with retry_scale x "
                                         "n_features keypoints (a view sharing only part of the keyframe); 1: no retry")
    refresh_fraction: float = Field(default=0.5, ge=0.0, lt=1.0,
                                    description="match the keyframe again (adding the new matches) when the tracked set "
                                                "has shrunk below this fraction of the last matching; 0: only below min_points")

    @model_validator(mode="after")
    def _consistent(self) -> VisualPathParams:
        n = len(self.path)
        if n and (self.keyframe.id >= n or self.path[self.keyframe.id] != self.keyframe):
            raise ValueError(f"keyframe {self.keyframe.id} is not entry {self.keyframe.id} of the path")
        if self.feedforward and n < 2:
            raise ValueError(f"feed-forward (eq. 32) needs a path of at least two keyframes, this one has {n}")
        return self

    @property
    def n_keyframes(self) -> int:
        return max(len(self.path), self.keyframe.id + 1)

    @property
    def is_last(self) -> bool:
        return self.keyframe.id == self.n_keyframes - 1


class RematchParams(StrictModel):
    """Keyframe to re-match while hovering, and the matcher settings."""

    keyframe: KeyframeRef
    path: list[KeyframeRef] = Field(default_factory=list)
    features: Literal["orb", "sift"] = "orb"
    n_features: int = Field(default=1000, ge=50, le=20000)
    min_points: int = Field(default=16, ge=8, le=10000)
    retry_scale: int = Field(default=4, ge=1, le=20,
                             description="when matching finds fewer than min_points, detect again with retry_scale x "
                                         "n_features keypoints; 1: no retry")


# ---------------------------------------------------------------------------------------------
# per-run memos of what the keyframe images give (TaskContext.cache: derived from the run's constant
# keyframes, shared by the states of one run, not mission data — an empty cache only costs time)


def _keyframe_features(cache: dict[str, Any], image: NDArray[np.uint8], kf_id: int, kind: str, n: int) -> Features:
    memo = cache.setdefault("visual_path.keyframe_features", {})
    key = (kf_id, kind, n)
    if key not in memo:
        memo[key] = detect(make_detector(kind, n), to_grey(image), kind)
    return memo[key]


def match_with_retry(cache: dict[str, Any], kf_image: NDArray[np.uint8], kf_id: int, grey: NDArray[np.uint8],
                     p: VisualPathParams | RematchParams, model: str = "homography") -> tuple[NDArray[np.float32],
                                                                                            NDArray[np.float32]]:
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
        kf = _keyframe_features(cache, kf_image, kf_id, p.features, n)
        cur, kfp = match_keyframe(kf, detect(make_detector(p.features, n), grey, p.features), model=model)
        if len(cur) >= p.min_points:
            break
    return cur, kfp


def segment_velocities(keyframes: tuple[NDArray[np.uint8], ...], K: NDArray[np.float64], Ad_body_camera: NDArray[np.float64],
                       gains: VisualGains, gamma: float, kind: str = "orb", n_features: int = 1000,
                       cache: dict[str, Any] | None = None) -> list[NDArray[np.float64]]:
    """Alg. 2 lines 2–15: ``nu_p`` (eq. 32) of every segment ``k → k+1`` from the keyframe images.

    Keyframe ``k``'s image plays the current image and ``k+1``'s the target: ``H`` maps ``k`` to ``k+1``,
    ``e`` is eq. (2), the gain eq. (4), the law eq. (3), scaled by ``γ`` and taken to the body frame.
    A segment whose images do not match gets ``nu_p = 0``.
    """
    mem = cache if cache is not None else {}
    out = []
    for k in range(len(keyframes) - 1):
        fa = _keyframe_features(mem, keyframes[k], k, kind, n_features)
        fb = _keyframe_features(mem, keyframes[k + 1], k + 1, kind, n_features)
        cur, kf = match_keyframe(fb, fa)  # (points in k, points in k+1)
        out.append(_segment_velocity(cur, kf, K, Ad_body_camera, gains, gamma))
    return out


def segment_velocities_from_points(views: tuple[FeatureView, ...], K: NDArray[np.float64], Ad_body_camera: NDArray[np.float64],
                                   gains: VisualGains, gamma: float) -> list[NDArray[np.float64]]:
    """:func:`segment_velocities` for the geometric camera: keyframe ``k``'s and ``k+1``'s landmark
    views (``.ids``, ``.uv``) correspond by id."""
    out = []
    for a, b in zip(views[:-1], views[1:]):
        cur, kf, _ = _by_id(a, b)
        if len(cur) >= 8:
            order = sort_points(kf)
            cur, kf = cur[order], kf[order]
        out.append(_segment_velocity(cur, kf, K, Ad_body_camera, gains, gamma))
    return out


def _segment_velocity(cur: NDArray[np.float64], kf: NDArray[np.float64], K: NDArray[np.float64],
                      Ad_body_camera: NDArray[np.float64], gains: VisualGains, gamma: float) -> NDArray[np.float64]:
    """Eq. (32) for one segment from its correspondences (largest triangle first); 0 when < 8."""
    if len(cur) < 8:
        return np.zeros(4)
    H, _ = estimate_homography(cur, kf, K)
    m_star = normalize_pixels(kf[:3], K).mean(axis=0)
    e = task_error(H, m_star)
    lam = adaptive_gain(float(np.linalg.norm(e)), gains.lambda_0, gains.lambda_inf, gains.lambda_0_slope)
    if gains.yaw_decoupling:  # the segment's yaw step would slide nu_p sideways as it does nu_e
        yaw_axis = Ad_body_camera[2, :3]
        e = yaw_decoupled_error(H, m_star, yaw_axis, homography_yaw(H, yaw_axis, normalize_pixels(cur, K)))
    return feedforward_velocity(e, gain_matrix(lam, gains.homography_gains()), gamma, Ad_body_camera)


def _by_id(view: FeatureView, kf: FeatureView) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Pixels of the landmarks seen in both ``view`` and ``kf`` (geometric camera), and their ids."""
    ids, i, j = np.intersect1d(view.ids, kf.ids, assume_unique=True, return_indices=True)
    return np.asarray(view.uv)[i], np.asarray(kf.uv)[j], ids


# ---------------------------------------------------------------------------------------------
# the tasks

# the obstacle the collision task remembers, carried across the keyframes of a run (a controller's state)
OBSTACLE_MEMORY: MemoryKey[ObstacleMemory] = MemoryKey(
    "visual_path.obstacle", instance(ObstacleMemory), output=False,
    doc="the obstacle the collision task remembers in the body frame until it is behind the drone")

_METRICS: dict[str, str] = {
    "epsilon": Metric("px", low=0.0, reason="a mean pixel distance"),
    "epsilon_margin": "px",
    "epsilon_rising": Metric("", low=0.0, reason="a count of ticks"),
    "epsilon_progress": "px",
    "task_error": Metric("", low=0.0, reason="a norm"),
    "e_a": "",
    "e_m": Metric("", low=0.0, reason="a norm"),
    "h_a": WEIGHT,
    "h_m": WEIGHT,
    "h_t": WEIGHT,
    "n_points": COUNT,
    "keyframe": Metric("", low=0.0, reason="a keyframe index"),
    "last_keyframe": FLAG,
    "obstacle": FLAG,
}


class ForwardCamera(StrictModel):
    """The robot parameter the visual-path laws read: its forward camera (intrinsics and mount ``eT_c``)."""

    camera: QuadCamera


def _keyframe_image(obs: Observation, kf_id: int) -> NDArray[np.uint8]:
    kfs = obs.sensors.get("keyframes", ())
    if kf_id >= len(kfs):
        raise RuntimeError(f"keyframe {kf_id} has no image: the world provides {len(kfs)} keyframe images")
    return kfs[kf_id].pixels


def camera_view(obs: Observation) -> FeatureView | Image:
    """This tick's camera message, whose type chooses the perception pipeline: the geometric camera's
    landmark :class:`FeatureView` (``sensors.points``: correspondences by id) or the rendered camera's
    :class:`Image` (``sensors.image``: ORB matching and LK tracking)."""
    view = obs.sensors.get("points")
    if isinstance(view, FeatureView):
        return view
    image = obs.sensors.get("image")
    if isinstance(image, Image):
        return image
    raise RuntimeError("visual path tasks read the camera's sensors.points (FeatureView) or sensors.image (Image); "
                       f"this observation has: {', '.join(sorted(obs.sensors)) or 'no sensors'}")


# what both visual path tasks read: one camera message per frame (FeatureView or Image, by the world's
# perception mode) and the keyframes' messages of the same type
_CAMERA: dict[str, ObsSpec] = {
    "sensors.frame_id": scalar(),
    "sensors.points": message(FeatureView), "sensors.keyframe_points": sequence(optional=True, of=FeatureView),
    "sensors.image": message(Image), "sensors.keyframes": sequence(optional=True, of=Image)}


class ServoLaw:
    """The control part of ``visual_path_servo`` for one keyframe: tracked points (and the obstacle's
    edge points) in, body velocity and metrics out — Alg. 1 lines 19–45, Alg. 2 lines 32–48.

    Pure apart from its activation state (``h_a``, ``h_m``) and the ε history; no image processing, so
    it also runs on geometric (projected) points.
    """

    def __init__(self, K: NDArray[np.float64], Ad_body_camera: NDArray[np.float64], size: tuple[int, int], params: VisualPathParams,
                 visual: VisualGains, hier: HierarchyGains, path_gains: PathGains, t_enter: float,
                 nu_p: NDArray[np.float64] | None = None, memory: ObstacleMemory | None = None) -> None:
        self.K, self.Ad_body_camera, self.p = K, Ad_body_camera, params
        if params.keyframe.sigma is not None:
            hier = hier.model_copy(update={"sigma": params.keyframe.sigma})
        self.visual, self.hier, self.path_gains = visual, hier, path_gains
        w, h = size
        m = hier.safety_margin_px
        self.rect = (m, m, w - 1 - m, h - 1 - m)
        self.c_star = normalize_pixels([[w / 2.0, h / 2.0 - 1.0]], K)[0]
        self.t_enter = t_enter
        self.transition = params.transition if params.transition is not None else params.n_keyframes > 1
        self.act_a = Activation(hier.activation_s, t=t_enter)
        self.act_m = Activation(hier.visibility_activation_s, t=t_enter)
        self.gains = visual.homography_gains()
        self.nu_p = np.zeros(4) if nu_p is None else np.asarray(nu_p, dtype=np.float64)
        self.last_eps: float | None = None
        self.rising = 0
        self.eps_history: deque[tuple[float, float]] = deque()
        self.J_a_last: NDArray[np.float64] | None = None
        self.memory = memory if memory is not None else ObstacleMemory()
        R = Ad_body_camera[:3, :3]
        self.T_body_camera = transform(R, vee(Ad_body_camera[:3, 3:] @ R.T))  # eq. (5): [[R, [t]x R], [0, R]]

    def __call__(self, t: float, cur_px: NDArray, kf_px: NDArray, obstacle: ObstacleDetection | None,
                 H: NDArray[np.float64] | None = None, nu_body: NDArray[np.float64] | None = None
                 ) -> tuple[NDArray[np.float64], dict[str, float]]:
        """One frame: tracked and keyframe pixels, the obstacle detection (``None``: none), optionally
        ``H`` (else estimated) and the body's measured velocity ``nu_body = [vx, vy, vz, wz]`` (odometry,
        which carries a remembered obstacle along; ``None``: taken as zero)."""
        p, hier, K = self.p, self.hier, self.K
        if H is None:
            H, _ = estimate_homography(cur_px, kf_px, K, p.homography)
        m_star = normalize_pixels(kf_px[:3], K).mean(axis=0)
        e = task_error(H, m_star)
        eps = mean_pixel_error(cur_px, kf_px)
        norm_e = float(np.linalg.norm(e))
        lam = adaptive_gain(norm_e, self.visual.lambda_0, self.visual.lambda_inf, self.visual.lambda_0_slope)
        lam_v = gain_matrix(lam, self.gains)
        # collision avoidance, eqs. (8)-(9); h_a by eq. (20)
        if obstacle is not None and obstacle.touches_border:
            obstacle = None  # both edges must be visible (§3.1): it is leaving the field of view
        if hier.collision and hier.memory:
            e_a, J_a, active_a = self._collision(t, obstacle, np.zeros(4) if nu_body is None else nu_body)
            h_a = self.act_a.update(active_a, t)
        else:
            e_a, J_a, h_a = self._collision_paper(t, obstacle)
        # visibility, eqs. (10)-(12)
        m_cur = normalize_pixels(cur_px, K)
        e_m = visibility_error(m_cur, self.c_star)
        J_m = visibility_jacobian(m_cur.mean(axis=0), hier.z_scene)
        # checkPoints: only points the keyframe itself has inside the safety area count (a point the
        # keyframe shows outside it would keep the task active at the goal, against the visual task)
        u0, v0, u1, v1 = self.rect
        kf_in = (kf_px[:, 0] >= u0) & (kf_px[:, 0] <= u1) & (kf_px[:, 1] >= v0) & (kf_px[:, 1] <= v1)
        h_m = self.act_m.update(hier.visibility and points_outside(cur_px[kf_in], self.rect), t)
        # hierarchy (13)-(19), transition (28)-(29), robot velocities (6), feed-forward (31)
        if self.visual.yaw_decoupling:
            yaw_axis = self.Ad_body_camera[2, :3]
            e_c = yaw_decoupled_error(H, m_star, yaw_axis, homography_yaw(H, yaw_axis, m_cur))
        else:
            e_c = e
        res = hierarchical_control(J_a, [e_a], J_m, e_m, np.eye(6), e_c, hier.lambda_a, hier.lambda_m, lam_v, h_a, h_m)
        h_t = transition_weight(t - self.t_enter, self.path_gains.transition_s, self.path_gains.h0) if self.transition else 1.0
        nu_e = robot_velocity(h_t * res.nu, self.Ad_body_camera)
        if p.feedforward and not p.is_last:
            nu_e = feedforward_blend(nu_e, self.nu_p, self.path_gains.p)
        # imgChVerif inputs
        if self.last_eps is not None and eps > self.last_eps:
            self.rising += 1
        else:
            self.rising = 0
        self.last_eps = eps
        progress = self._progress(t, eps)
        t_eps = p.t_eps_final_px if p.is_last else p.t_eps_px
        metrics = {
            "epsilon": eps,
            "epsilon_margin": eps - t_eps,
            "epsilon_rising": float(self.rising if (p.feedforward and not p.is_last) else 0),
            "epsilon_progress": progress,
            "task_error": norm_e,
            "e_a": e_a,
            "e_m": float(np.linalg.norm(e_m)),
            "h_a": h_a,
            "h_m": h_m,
            "h_t": h_t,
            "n_points": float(len(cur_px)),
            "keyframe": float(p.keyframe.id),
            "last_keyframe": 1.0 if p.is_last else 0.0,
            "obstacle": 1.0 if obstacle is not None else 0.0,
        }
        return nu_e, metrics

    def _collision_paper(self, t: float, obstacle: ObstacleDetection | None) -> tuple[float, NDArray[np.float64], float]:
        """Eqs. (8)-(9) on the obstacle in view, ``h_a`` by eq. (20); out of view ``e_a`` is at its
        reference (0) while ``h_a`` decays with the last ``J_a`` (``hierarchy.memory: false``)."""
        hier = self.hier
        e_a, J_a, active_a = 0.0, np.zeros((1, 6)), False
        if obstacle is not None and hier.collision:
            p1n, p2n = normalize_pixels([obstacle.p1, obstacle.p2], self.K)
            e_a = collision_error(p1n, p2n, hier.sigma)
            J_a = collision_jacobian(p1n, p2n, hier.z_obstacle, hier.z_obstacle)
            active_a = e_a > 0.0
            self.J_a_last = J_a
        elif self.J_a_last is not None:
            J_a = self.J_a_last
        h_a = self.act_a.update(active_a, t)
        if (obstacle is None or not hier.collision) and h_a <= 0.0:
            self.J_a_last = None
            J_a = np.zeros((1, 6))
        return e_a, J_a, h_a

    def _collision(self, t: float, obstacle: ObstacleDetection | None,
                   nu_body: NDArray[np.float64]) -> tuple[float, NDArray[np.float64], bool]:
        """``(e_a, J_a, active)`` with the obstacle memory (:mod:`~taskflow_tasks.quad.obstacle_memory`).

        Every remembered obstacle is carried along with ``nu_body`` and forgotten once behind the body.
        A whole obstacle in view is placed in the body frame and replaces the remembered one it
        matches (centres within ``0.5 m``), keeping that one's escape side, or is added once the task
        activates for it (``e_a > 0``).  The task acts on a remembered obstacle out of view that the
        drone is inside of, or would reach within the activation time, the keep-out disc of
        (:func:`~taskflow_tasks.quad.obstacle_memory.closing_in`; the nearest by
        :func:`~taskflow_tasks.quad.obstacle_memory.remembered_collision`), and is then active, so that
        ``h_a`` (eq. 20) is up when the drone gets there; otherwise on the one in view: eq. (8), and
        eq. (9) at the edges moved to the committed escape side (chosen when the task first activates
        for it), active when ``e_a > 0``; otherwise, inactive, on the nearest remembered one."""
        hier, mem = self.hier, self.memory
        rems = [propagate(r, nu_body, t) for r in mem.obstacles]
        rems = [r for r in rems if not has_passed(r, hier.pass_margin_m)]
        seen, view = None, None
        if obstacle is not None:
            p1n, p2n = normalize_pixels([obstacle.p1, obstacle.p2], self.K)
            e_view = collision_error(p1n, p2n, hier.sigma)
            width = hier.obstacle_width if hier.obstacle_width is not None else hier.sigma * hier.z_obstacle
            seen = RememberedObstacle(*edges_in_body(p1n, p2n, width, self.T_body_camera), width, t)
            i = associate(rems, seen, 0.5)
            side = rems[i].side if i is not None else 0
            if side == 0 and e_view > 0.0:
                side = escape_side(p1n, p2n, 0.5 * hier.escape_offset, LEFT if hier.escape_side == "left" else RIGHT)
            seen = RememberedObstacle(seen.p1, seen.p2, width, t, side)
            if i is not None:
                rems[i] = seen
            elif e_view > 0.0:  # remembered once the task acts on it (a far one's place is too uncertain)
                rems.append(seen)
            c1, c2 = committed_edges(p1n, p2n, side, hier.escape_offset)
            view = (e_view, collision_jacobian(c1, c2, hier.z_obstacle, hier.z_obstacle))
        mem.obstacles = rems
        horizon = hier.activation_s
        out_of_view = [(*remembered_collision(r, hier.keep_out_m), closing_in(r, nu_body, hier.keep_out_m, horizon))
                       for r in rems if r is not seen]
        nearest = max(out_of_view, key=lambda eja: (eja[2], eja[0])) if out_of_view else None
        if nearest is not None and (nearest[2] or view is None):
            return nearest[0], nearest[1] @ self.Ad_body_camera, nearest[2]
        if view is not None:
            return view[0], view[1], view[0] > 0.0
        return 0.0, np.zeros((1, 6)), False

    def rebase(self, ratio: float | None) -> None:
        """The point set changed (re-matched points added): rescale the ε history by ``ratio`` (ε of
        the new set / ε of the old one, on the same frame) so that the rising count and the progress
        compare like with like; ``None`` (no old point left) forgets it."""
        if ratio is None:
            self.last_eps, self.rising = None, 0
            self.eps_history.clear()
            return
        if self.last_eps is not None:
            self.last_eps *= ratio
        self.eps_history = deque((t, e * ratio) for t, e in self.eps_history)

    def _progress(self, t: float, eps: float) -> float:
        """ε a window ago minus ε now (px); NaN until the window has been observed."""
        hist, window = self.eps_history, self.p.progress_window_s
        hist.append((t, eps))
        edge = t - window + 1e-9  # sample times are sums of float periods
        while len(hist) > 1 and hist[1][0] <= edge:
            hist.popleft()
        t0, eps0 = hist[0]
        return eps0 - eps if t0 <= edge else math.nan


@register_task("visual_path_servo")
class VisualPathServo(Task[VisualPathParams, ForwardCamera]):
    """Hierarchical homography-based servoing toward one keyframe (Alg. 1; Alg. 2 with feed-forward)."""

    Params: ClassVar[type[VisualPathParams]] = VisualPathParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"visual": VisualGains, "hierarchy": HierarchyGains,
                                                   "path": PathGains}
    metrics: ClassVar[dict[str, str]] = _METRICS
    events: ClassVar[tuple[str, ...]] = ("features_lost",)
    command_interface: ClassVar[str] = "body_velocity"
    robot_params: ClassVar[type[BaseModel]] = ForwardCamera
    requires: ClassVar[dict[str, ObsSpec]] = {**_CAMERA, "sensors.obstacle": message(Silhouette), "state.nu": array(4)}
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (OBSTACLE_MEMORY,)

    def __init__(self, ctx: TaskContext[VisualPathParams, ForwardCamera]) -> None:
        super().__init__(ctx)
        self.p = ctx.params
        self.visual = ctx.optional_profile("visual", VisualGains) or VisualGains()
        self.hier = ctx.optional_profile("hierarchy", HierarchyGains) or HierarchyGains()
        self.path_gains = ctx.optional_profile("path", PathGains) or PathGains()
        cam = ctx.robot_params.camera
        self.K = cam.K()
        self.Ad_body_camera = twist_adjoint(cam.T_body_camera())
        self.size = (cam.width, cam.height)
        self.t_enter = ctx.t
        self.tracker: PointTracker | None = None
        self.n_matched = 0
        self.law: ServoLaw | None = None
        self.last_frame = -1
        self.command = np.zeros(4)
        self.metrics_out: dict[str, float] = {}
        self.plane_ids: NDArray[np.int64] | None = None  # geometric camera: landmarks of the plane of H
        self.tri_ids: NDArray[np.int64] | None = None  # … and those of the largest triangle

    def _kf_grey(self, obs: Observation) -> NDArray[np.uint8]:
        cache = self.ctx.cache.setdefault("visual_path.keyframe_grey", {})
        k = self.p.keyframe.id
        if k not in cache:
            cache[k] = to_grey(_keyframe_image(obs, k))
        return cache[k]

    def _hover(self, events: tuple[str, ...] = ()) -> StepResult:
        self.command = np.zeros(4)
        return StepResult({"nu": self.command.copy()}, dict(self.metrics_out), events)

    def _feedforward(self, obs: Observation, view: FeatureView | Image) -> NDArray[np.float64]:
        if not self.p.feedforward or self.p.is_last:
            return np.zeros(4)
        mem = self.ctx.cache
        geometric = isinstance(view, FeatureView)
        key = ("visual_path.feedforward", "points" if geometric else self.p.features, self.p.n_features,
               self.path_gains.gamma, self.visual)
        table = mem.get(key)
        if table is None:
            if geometric:
                table = segment_velocities_from_points(tuple(obs.sensors["keyframe_points"]), self.K, self.Ad_body_camera,
                                                       self.visual, self.path_gains.gamma)
            else:
                kfs = tuple(k.pixels for k in obs.sensors.get("keyframes", ()))
                table = segment_velocities(kfs, self.K, self.Ad_body_camera, self.visual, self.path_gains.gamma, self.p.features,
                                           self.p.n_features, mem)
            mem[key] = table
        k = self.p.keyframe.id
        if self.path_gains.segment == "current":
            k = max(k - 1, 0)
        return table[k] if k < len(table) else np.zeros(4)

    def step(self, obs: Observation) -> StepResult:
        fid = int(obs.sensors.get("frame_id", -1))
        if fid == self.last_frame:  # no new image: hold the command (zero-order hold)
            return StepResult({"nu": self.command.copy()}, dict(self.metrics_out))
        self.last_frame = fid
        view = camera_view(obs)
        if isinstance(view, FeatureView):
            return self._step_points(obs, view)
        tic = time.perf_counter()
        image = view.pixels
        grey = to_grey(image)
        p = self.p
        if self.tracker is None:
            cur, kfp = match_with_retry(self.ctx.cache, _keyframe_image(obs, p.keyframe.id), p.keyframe.id, grey, p,
                                        "homography" if p.homography == "ransac" else "fundamental")
            if len(cur) < p.min_points:
                self.metrics_out = {"n_points": float(len(cur)), "keyframe": float(p.keyframe.id)}
                return self._hover(("features_lost",))
            self.tracker = PointTracker(grey, cur, kfp)
            self.n_matched = len(cur)
            self.law = ServoLaw(self.K, self.Ad_body_camera, self.size, p, self.visual, self.hier, self.path_gains, self.t_enter,
                                self._feedforward(obs, view), OBSTACLE_MEMORY.setdefault(self.ctx.memory, ObstacleMemory()))
        elif self._track(obs, grey) < p.min_points:
            self.metrics_out.update(n_points=float(len(self.tracker)))
            return self._hover(("features_lost",))
        tr = self.tracker
        if self.law is None:
            raise RuntimeError("visual_path_servo: tracker without a law (internal error)")
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
            return self._hover(("features_lost",))
        hier = self.hier
        obstacle = obstacle_edges(image, hier.hsv_low, hier.hsv_high, hier.min_obstacle_px) if hier.collision else None
        return self._control(obs, tic, tr.cur, tr.kf, obstacle, H)

    def _track(self, obs: Observation, grey: NDArray[np.uint8]) -> int:
        """Track into ``grey``; once the set has shrunk below ``refresh_fraction`` of what the last
        matching gave (points left the view or stopped fitting the plane), match the keyframe again and
        add the new matches, so the set keeps covering what the view shares with the keyframe (entered
        far from it, the drone keeps the few points of that first view otherwise, and H from a small
        cluster is ill-conditioned).  Returns the number of points."""
        tr, p = self.tracker, self.p
        if tr is None:
            raise RuntimeError("visual_path_servo: tracking before matching (internal error)")
        n = tr.track(grey)
        if n >= p.min_points and n >= p.refresh_fraction * self.n_matched:
            return n
        eps_old = mean_pixel_error(tr.cur, tr.kf) if n else 0.0
        cur, kfp = match_with_retry(self.ctx.cache, _keyframe_image(obs, p.keyframe.id), p.keyframe.id, grey, p,
                                    "homography" if p.homography == "ransac" else "fundamental")
        if len(kfp) and n:
            new = np.min(np.linalg.norm(kfp[:, None, :] - tr.kf[None, :, :], axis=2), axis=1) > 2.0
            cur, kfp = cur[new], kfp[new]
        if len(kfp):
            tr.add(cur, kfp)
            if self.law is not None:
                # ε is a mean over the point set: keep its history on the scale of the new set
                self.law.rebase(mean_pixel_error(tr.cur, tr.kf) / eps_old if eps_old > 1e-6 else None)
        self.n_matched = len(tr)
        return len(tr)

    def _step_points(self, obs: Observation, view: FeatureView) -> StepResult:
        """One frame of the geometric camera: correspondences by landmark id instead of ORB + LK.

        As with tracked points, the first frame keeps the RANSAC inliers of one plane and later frames
        drop the points that stop fitting it; the largest triangle's landmarks stay first."""
        tic = time.perf_counter()
        p = self.p
        kf_views = obs.sensors.get("keyframe_points", ())
        if p.keyframe.id >= len(kf_views):
            raise RuntimeError(f"keyframe {p.keyframe.id} has no view: the world provides {len(kf_views)}")
        cur, kfp, ids = _by_id(view, kf_views[p.keyframe.id])
        if self.plane_ids is not None:
            keep = np.isin(ids, self.plane_ids, assume_unique=True)
            cur, kfp, ids = cur[keep], kfp[keep], ids[keep]
        if len(ids) < p.min_points:
            self.metrics_out.update(n_points=float(len(ids)), keyframe=float(p.keyframe.id))
            return self._hover(("features_lost",))
        try:
            H, fits = estimate_homography(cur, kfp, self.K, p.homography, p.plane_px)
        except ValueError:
            return self._hover(("features_lost",))
        if self.plane_ids is None or (not fits.all() and fits.sum() >= p.min_points):
            cur, kfp, ids = cur[fits], kfp[fits], ids[fits]
            self.plane_ids = ids
        in_tri = np.isin(ids, self.tri_ids, assume_unique=True) if self.tri_ids is not None else None
        if in_tri is None or in_tri.sum() < 3:
            self.tri_ids = ids[sort_points(kfp)[:3]]
            in_tri = np.isin(ids, self.tri_ids, assume_unique=True)
        order = np.concatenate((np.flatnonzero(in_tri), np.flatnonzero(~in_tri)))  # the triangle first
        cur, kfp = cur[order], kfp[order]
        if self.law is None:
            self.law = ServoLaw(self.K, self.Ad_body_camera, self.size, p, self.visual, self.hier, self.path_gains, self.t_enter,
                                self._feedforward(obs, view), OBSTACLE_MEMORY.setdefault(self.ctx.memory, ObstacleMemory()))
        obstacle = _silhouette(obs.sensors.get("obstacle"), self.size, self.hier.min_obstacle_px) \
            if self.hier.collision else None
        return self._control(obs, tic, cur, kfp, obstacle, H)

    def _control(self, obs: Observation, tic: float, cur: NDArray[np.float64], kf: NDArray[np.float64],
                 obstacle: ObstacleDetection | None, H: NDArray[np.float64]) -> StepResult:
        """The law on this frame's correspondences; perception time counted from ``tic``."""
        if self.law is None:
            raise RuntimeError("visual_path_servo: no law before the first match (internal error)")
        tic2 = time.perf_counter()
        nu_e, metrics = self.law(obs.t, cur, kf, obstacle, H, np.asarray(obs.state["nu"], dtype=np.float64))
        toc = time.perf_counter()
        self.command = nu_e
        self.metrics_out = metrics
        return StepResult({"nu": nu_e.copy()}, dict(metrics),
                          timings={"perception": tic2 - tic, "control": toc - tic2, "frame": toc - tic})  # timing.json only


def _silhouette(edges: Silhouette | None, size: tuple[int, int], min_area: int) -> ObstacleDetection | None:
    """The geometric camera's column :class:`Silhouette` as the detection :func:`obstacle_edges` makes
    from pixels (a full-height blob)."""
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


@register_task("visual_path_rematch")
class VisualPathRematch(Task[RematchParams, ForwardCamera]):
    """Hover and try to match the keyframe on every new frame; ``features_found`` once at least
    ``min_points`` RANSAC-consistent matches are back."""

    Params: ClassVar[type[RematchParams]] = RematchParams
    metrics: ClassVar[dict[str, str]] = {"n_points": _METRICS["n_points"], "keyframe": _METRICS["keyframe"]}
    events: ClassVar[tuple[str, ...]] = ("features_found",)
    command_interface: ClassVar[str] = "body_velocity"
    robot_params: ClassVar[type[BaseModel]] = ForwardCamera
    requires: ClassVar[dict[str, ObsSpec]] = _CAMERA

    def __init__(self, ctx: TaskContext[RematchParams, ForwardCamera]) -> None:
        super().__init__(ctx)
        self.p = ctx.params
        self.last_frame = -1
        self.n = 0

    def step(self, obs: Observation) -> StepResult:
        fid = int(obs.sensors.get("frame_id", -1))
        events: tuple[str, ...] = ()
        if fid != self.last_frame:
            self.last_frame = fid
            p = self.p
            view = camera_view(obs)
            if isinstance(view, FeatureView):  # geometric camera: the landmarks seen in both
                cur, kfp, _ = _by_id(view, obs.sensors["keyframe_points"][p.keyframe.id])
                self.n = int(estimate_homography(cur, kfp, self.ctx.robot_params.camera.K())[1].sum()) \
                    if len(cur) >= 8 else len(cur)
            else:
                matched, _ = match_with_retry(self.ctx.cache, _keyframe_image(obs, p.keyframe.id), p.keyframe.id,
                                              to_grey(view.pixels), p)
                self.n = len(matched)
            if self.n >= p.min_points:
                events = ("features_found",)
        return StepResult({"nu": np.zeros(4)}, {"n_points": float(self.n), "keyframe": float(self.p.keyframe.id)},
                          events)
