"""The profiles of the visual-path tasks (Toro-Arcila et al.): the gains a mission binds per state.

``visual`` (:class:`VisualGains`, eqs. 3–4), ``hierarchy`` (:class:`HierarchyGains`, the collision and
visibility tasks, eqs. 8–20) and ``path`` (:class:`PathGains`, the keyframe transition and the
feed-forward, eqs. 29–32).  An unbound slot is the class's defaults, bound by the loader.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator
from taskflow_tasks.quad.homography import HomographyGains

from taskflow.api import StrictModel

Vec3 = tuple[float, float, float]


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
                                         description="width (m) that places a seen obstacle in the body frame "
                                                     "(with width_from_views: the prior of each obstacle's fit); "
                                                     "default sigma x z_obstacle (the width that looks sigma wide at "
                                                     "the depth estimate)")
    width_from_views: bool = Field(default=True, description="place a seen obstacle with the width its edge rays over "
                                   "the views give (obstacle_memory.fit_circle; obstacle_width, or sigma x z_obstacle, is "
                                   "the prior); false: every obstacle is placed with that one width")
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

