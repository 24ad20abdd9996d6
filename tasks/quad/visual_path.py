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
and the keyframe images (``obs.sensors["keyframes"]``); the path in the parameters lists the keyframes by
index (and their settings), never by pose: the taught poses are the world's ground truth.  With the world's geometric camera the frame's
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
  it until it is behind the drone and outside its keep-out disc (:mod:`~taskflow_tasks.quad.obstacle_memory`:
  eq. 8 seen from the body's centre, a keep-out distance ``keep_out_m``); each obstacle's place and width
  are fitted to the edge rays of all its views (``width_from_views``; one view cannot tell a narrow near
  column from a wide far one); the memory lasts across the keyframes of a run
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
  again and the new matches are added (:meth:`ImageCorrespondences._track <taskflow_tasks.quad.tracking.ImageCorrespondences._track>`); ε is a mean over the set, so
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

import time
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel
from taskflow_tasks.quad.correspondences import (
    IMAGE,
    KEYFRAME_POINTS,
    KEYFRAMES,
    OBSTACLE,
    POINTS,
    Correspondences,
    LandmarkCorrespondences,
    Lost,
    camera_view,
    count_landmark_matches,
    keyframe_image,
    keyframe_view,
)
from taskflow_tasks.quad.feedforward import segment_velocities
from taskflow_tasks.quad.gains import HierarchyGains, PathGains, VisualGains
from taskflow_tasks.quad.law import ServoLaw
from taskflow_tasks.quad.obstacle_memory import ObstacleMemory
from taskflow_tasks.quad.params import ForwardCamera, RematchParams, VisualPathParams
from taskflow_tasks.quad.perception import to_grey
from taskflow_tasks.quad.tracking import ImageCorrespondences, match_with_retry

from taskflow.api import (
    COUNT,
    FLAG,
    WEIGHT,
    MemoryKey,
    Metric,
    Observation,
    ObsKey,
    StepResult,
    Task,
    TaskContext,
    array,
    instance,
    scalar,
)
from taskflow.messages import FeatureView
from taskflow.registry import register_task
from taskflow.spatial import twist_adjoint
from taskflow.specs import Requires

__all__ = ["OBSTACLE_MEMORY", "VisualPathRematch", "VisualPathServo"]

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


# what both visual path tasks read: one camera message per frame (FeatureView or Image, by the world's
# perception mode) and the keyframes' messages of the same type; the servo also the measured velocity
FRAME_ID: ObsKey[float] = ObsKey("sensors.frame_id", scalar())
NU: ObsKey[NDArray[np.float64]] = ObsKey("state.nu", array(4))
_CAMERA: tuple[ObsKey[Any], ...] = (FRAME_ID, POINTS, KEYFRAME_POINTS, IMAGE, KEYFRAMES)


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
    requires: ClassVar[Requires] = (*_CAMERA, OBSTACLE, NU)
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (OBSTACLE_MEMORY,)

    def __init__(self, ctx: TaskContext[VisualPathParams, ForwardCamera]) -> None:
        super().__init__(ctx)
        self.p = ctx.params
        self.visual = ctx.profile("visual", VisualGains)  # an unbound slot: the defaults, bound by the loader
        self.hier = ctx.profile("hierarchy", HierarchyGains)
        self.path_gains = ctx.profile("path", PathGains)
        cam = ctx.robot_params.camera
        self.K = cam.K()
        self.Ad_body_camera = twist_adjoint(cam.T_body_camera())
        self.size = (cam.width, cam.height)
        self.t_enter = ctx.t
        self.correspondences: Correspondences | None = None  # chosen by the camera's message on the first frame
        self.law: ServoLaw | None = None
        self.last_frame = -1
        self.command = np.zeros(4)
        self.metrics_out: dict[str, float] = {}

    def _pipeline(self, obs: Observation) -> Correspondences:
        if self.correspondences is None:
            if isinstance(camera_view(obs), FeatureView):
                self.correspondences = LandmarkCorrespondences(self.p, self.hier, self.K, self.size)
            else:
                self.correspondences = ImageCorrespondences(self.p, self.hier, self.K, self.ctx.cache)
        return self.correspondences

    def _feedforward(self, obs: Observation, corr: Correspondences) -> NDArray[np.float64]:
        """``nu_p`` of the segment flown toward this keyframe (Alg. 2's ``vVec``), from the run's table."""
        if not self.p.feedforward or self.p.is_last:
            return np.zeros(4)
        memo: dict[tuple[str, int, float, VisualGains], list[NDArray[np.float64]]] = \
            self.ctx.cache.setdefault("visual_path.feedforward", {})
        key = (corr.name, self.p.n_features, self.path_gains.gamma, self.visual)
        table = memo.get(key)
        if table is None:
            table = segment_velocities(corr.keyframe_pairs(obs), self.K, self.Ad_body_camera, self.visual,
                                       self.path_gains.gamma)
            memo[key] = table
        k = self.p.keyframe.id
        if self.path_gains.segment == "current":
            k = max(k - 1, 0)
        return table[k] if k < len(table) else np.zeros(4)

    def step(self, obs: Observation) -> StepResult:
        fid = int(FRAME_ID(obs))
        if fid == self.last_frame:  # no new image: hold the command (zero-order hold)
            return StepResult({"nu": self.command.copy()}, dict(self.metrics_out))
        self.last_frame = fid
        tic = time.perf_counter()
        corr = self._pipeline(obs)
        found = corr.match(obs)
        if found.rebase is not None and self.law is not None:  # ε is a mean over the set: keep its scale
            self.law.rebase(found.rebase.ratio)
        if isinstance(found, Lost):
            self.metrics_out.update(found.metrics)
            self.command = np.zeros(4)
            return StepResult({"nu": self.command.copy()}, dict(self.metrics_out), ("features_lost",))
        if self.law is None:
            self.law = ServoLaw(self.K, self.Ad_body_camera, self.size, self.p, self.visual, self.hier, self.path_gains,
                                self.t_enter, self._feedforward(obs, corr),
                                OBSTACLE_MEMORY.setdefault(self.ctx.memory, ObstacleMemory()))
        tic2 = time.perf_counter()
        nu_e, metrics = self.law(obs.t, found.cur, found.kf, found.obstacle, found.H,
                                 np.asarray(NU(obs), dtype=np.float64))
        toc = time.perf_counter()
        self.command = nu_e
        self.metrics_out = metrics
        return StepResult({"nu": nu_e.copy()}, dict(metrics),
                          timings={"perception": tic2 - tic, "control": toc - tic2, "frame": toc - tic})  # timing.json only


@register_task("visual_path_rematch")
class VisualPathRematch(Task[RematchParams, ForwardCamera]):
    """Hover and try to match the keyframe on every new frame; ``features_found`` once at least
    ``min_points`` RANSAC-consistent matches are back."""

    Params: ClassVar[type[RematchParams]] = RematchParams
    metrics: ClassVar[dict[str, str]] = {"n_points": _METRICS["n_points"], "keyframe": _METRICS["keyframe"]}
    events: ClassVar[tuple[str, ...]] = ("features_found",)
    command_interface: ClassVar[str] = "body_velocity"
    robot_params: ClassVar[type[BaseModel]] = ForwardCamera
    requires: ClassVar[Requires] = _CAMERA

    def __init__(self, ctx: TaskContext[RematchParams, ForwardCamera]) -> None:
        super().__init__(ctx)
        self.p = ctx.params
        self.last_frame = -1
        self.n = 0

    def step(self, obs: Observation) -> StepResult:
        fid = int(FRAME_ID(obs))
        events: tuple[str, ...] = ()
        if fid != self.last_frame:
            self.last_frame = fid
            p = self.p
            view = camera_view(obs)
            if isinstance(view, FeatureView):  # geometric camera: the landmarks seen in both
                self.n = count_landmark_matches(view, keyframe_view(obs, p.keyframe.id), self.ctx.robot_params.camera.K())
            else:
                matched, _ = match_with_retry(self.ctx.cache, keyframe_image(obs, p.keyframe.id), p.keyframe.id,
                                              to_grey(view.pixels), p)
                self.n = len(matched)
            if self.n >= p.min_points:
                events = ("features_found",)
        return StepResult({"nu": np.zeros(4)}, {"n_points": float(self.n), "keyframe": float(self.p.keyframe.id)},
                          events)
