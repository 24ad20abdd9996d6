"""The control part of ``visual_path_servo`` for one keyframe (Toro-Arcila et al., Alg. 1 lines 19–45,
Alg. 2 lines 32–48): correspondences in, body velocity and the switching metrics out.

The hierarchy of eqs. (13)–(19) over the collision task (:class:`~taskflow_tasks.quad.collision.CollisionTask`),
the visibility task (eqs. 10–12) and the visual task (eqs. 2–4, or its yaw-decoupled form), the keyframe
transition (eqs. 28–29) and the feed-forward blend (eq. 31); the metrics ``imgChVerif`` switches on.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.quad.collision import CollisionTask
from taskflow_tasks.quad.correspondences import Pixels
from taskflow_tasks.quad.gains import HierarchyGains, PathGains, VisualGains
from taskflow_tasks.quad.hierarchy import (
    Activation,
    hierarchical_control,
    points_outside,
    transition_weight,
    visibility_error,
    visibility_jacobian,
)
from taskflow_tasks.quad.homography import (
    adaptive_gain,
    feedforward_blend,
    gain_matrix,
    homography_control,
    mean_pixel_error,
    normalize_pixels,
    robot_velocity,
    task_error,
)
from taskflow_tasks.quad.obstacle_memory import ObstacleMemory
from taskflow_tasks.quad.params import VisualPathParams
from taskflow_tasks.quad.perception import ObstacleDetection, estimate_homography
from taskflow_tasks.quad.yaw_decoupling import homography_yaw, yaw_decoupled_error

Array = NDArray[np.float64]

__all__ = ["ServoLaw"]


class ServoLaw:
    """The control part of ``visual_path_servo`` for one keyframe: tracked points (and the obstacle's
    edge points) in, body velocity and metrics out — Alg. 1 lines 19–45, Alg. 2 lines 32–48.

    Pure apart from its activation state (``h_a``, ``h_m``) and the ε history; no image processing, so
    it also runs on geometric (projected) points.
    """

    def __init__(self, K: Array, Ad_body_camera: Array, size: tuple[int, int], params: VisualPathParams,
                 visual: VisualGains, hier: HierarchyGains, path_gains: PathGains, t_enter: float,
                 nu_p: Array | None = None, memory: ObstacleMemory | None = None) -> None:
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
        self.act_m = Activation(hier.visibility_activation_s, t=t_enter)
        self.gains = visual.homography_gains()
        self.nu_p = np.zeros(4) if nu_p is None else np.asarray(nu_p, dtype=np.float64)
        self.last_eps: float | None = None
        self.rising = 0
        self.eps_history: deque[tuple[float, float]] = deque()
        self.collision = CollisionTask(K, Ad_body_camera, hier, t_enter, memory)

    def __call__(self, t: float, cur_px: Pixels, kf_px: Pixels, obstacle: ObstacleDetection | None,
                 H: Array | None = None, nu_body: Array | None = None
                 ) -> tuple[Array, dict[str, float]]:
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
        lam = float(adaptive_gain(norm_e, self.visual.lambda_0, self.visual.lambda_inf, self.visual.lambda_0_slope))
        lam_v = gain_matrix(lam, self.gains)
        # collision avoidance, eqs. (8)-(9); h_a by eq. (20)
        if obstacle is not None and obstacle.touches_border:
            obstacle = None  # both edges must be visible (§3.1): it is leaving the field of view
        e_a, J_a, h_a = self.collision(t, obstacle, nu_body)
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
        if h_a == 0.0 and h_m == 0.0:  # both upper tasks inactive: (13)-(19) are the visual task's law (3)
            nu_c = homography_control(e_c, lam_v)
        else:
            nu_c = hierarchical_control(J_a, [e_a], J_m, e_m, np.eye(6), e_c, hier.lambda_a, hier.lambda_m, lam_v,
                                        h_a, h_m).nu
        h_t = transition_weight(t - self.t_enter, self.path_gains.transition_s, self.path_gains.h0) if self.transition else 1.0
        nu_e = robot_velocity(h_t * nu_c, self.Ad_body_camera)
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
