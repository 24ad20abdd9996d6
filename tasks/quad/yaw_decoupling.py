"""Yaw decoupling of the homography-based law (not in the paper): the robot's yaw estimated from
``H`` and eq. (2)'s error split into that yaw and the translation, so that turning toward a keyframe
does not slide the drone sideways (``VisualGains.yaw_decoupling``).

Conventions as in :mod:`taskflow_tasks.quad.homography` (``H`` maps the current image to the keyframe,
``m* ∝ H m``, scaled as :func:`~taskflow_tasks.quad.homography.normalize_homography` does).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.quad.homography import homogeneous, keyframe_point

from taskflow.spatial import skew

Array = NDArray[np.float64]

__all__ = ["axis_rotation", "homography_yaw", "yaw_decoupled_error"]


def axis_rotation(angle: float | Array, axis: ArrayLike) -> Array:
    """Rotation by ``angle`` (rad, scalar or (N,)) about the unit ``axis`` (3,): Rodrigues' formula,
    ``I + sin θ [a]x + (1 − cos θ) [a]x²``; (3, 3), or (N, 3, 3) for N angles."""
    a = np.asarray(axis, dtype=np.float64).reshape(3)
    A = skew(a)
    th = np.asarray(angle, dtype=np.float64)
    s, c = np.sin(th)[..., None, None], np.cos(th)[..., None, None]
    return np.eye(3) + s * A + (1.0 - c) * (A @ A)


def _unit_axis(yaw_axis: ArrayLike) -> Array:
    a = np.asarray(yaw_axis, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(a))
    if not (np.isfinite(n) and n > 0.0):
        raise ValueError("yaw_axis must be a non-zero 3-vector")
    return a / n


def _rank_one_residual(H: Array, angles: Array, a: Array) -> Array:
    """``σ2² + σ3²`` of ``H − R_a(θ)`` for each angle: how far ``H − R`` is from the rank-one ``t nᵀ/d``."""
    s = np.linalg.svd(H[None] - axis_rotation(angles, a), compute_uv=False)
    return s[:, 1] ** 2 + s[:, 2] ** 2


def homography_yaw(H: ArrayLike, yaw_axis: ArrayLike, m: ArrayLike, max_angle: float = math.pi / 2,
                   grid: int = 181) -> float:
    """The rotation of ``H = R + t nᵀ / d`` (eq. 2) for a robot that only yaws: the angle θ (rad) about
    ``yaw_axis`` for which ``H − R_a(θ)`` is closest to rank one (least ``σ2² + σ3²``).  Not in the paper.

    A planar homography has two decompositions (Faugeras & Lustman 1988); for a level camera moving
    level in front of a vertical plane both have a yaw-only ``R``: the true one and one turned by about
    the translation over the plane's distance.  The local minima of a ``grid``-point scan over
    ``±max_angle``, each refined to 1e-9 rad by successive finer scans, are the candidates.  Kept are
    those whose plane puts the most current points ``m`` (normalised, (N, 2) or (N, 3)) on one side
    (``nᵀ m_j`` of one sign: positive depths, the visibility constraint), and of these the one of least
    residual.  The visibility test rejects the other decomposition when the translation is mostly
    sideways (its normal then lies nearly in the image plane, with points on both sides); when it is
    mostly along the optical axis both may pass and the choice is the residual's (with noise, either):
    the two yaws then differ by up to about ‖t‖/d (they coincide as the translation vanishes).  Tracking the plane's
    normal from frame to frame to choose instead was tried and is worse (it can lock on the other
    branch: geometric oval seed 1, 40 cm off).  ``H`` must map the current image to the keyframe
    (``m* ∝ H m``) and be scaled as :func:`normalize_homography` does.
    """
    h = np.asarray(H, dtype=np.float64).reshape(3, 3)
    a = _unit_axis(yaw_axis)
    pts = np.asarray(m, dtype=np.float64)
    pts = homogeneous(pts) if pts.shape[-1] == 2 else pts.reshape(-1, 3)
    angles = np.linspace(-max_angle, max_angle, grid)
    f = _rank_one_residual(h, angles, a)
    step = angles[1] - angles[0]
    interior = np.flatnonzero((f[1:-1] <= f[:-2]) & (f[1:-1] <= f[2:])) + 1
    cand = angles[interior] if len(interior) else angles[[int(np.argmin(f))]]
    offsets = np.linspace(-1.0, 1.0, 9)
    while step > 1e-9:  # zoom on every minimum at once: 9 points over ±step, then a quarter of it
        trial = cand[:, None] + step * offsets[None, :]
        r = _rank_one_residual(h, trial.ravel(), a).reshape(trial.shape)
        cand = trial[np.arange(len(cand)), np.argmin(r, axis=1)]
        step *= 0.25
    _, sv, vt = np.linalg.svd(h[None] - axis_rotation(cand, a))
    # the rank-one part's row direction is the plane normal (current frame); points on its side (all of
    # them when H − R vanishes: no translation, any plane), then the residual
    side = np.where(sv[:, 0] > 1e-12, np.abs(np.sum(np.sign(pts @ vt[:, 0, :].T), axis=0)), len(pts))
    ok = np.flatnonzero(side == side.max())
    return float(cand[int(ok[np.argmin(sv[ok, 1] ** 2 + sv[ok, 2] ** 2)])])


def yaw_decoupled_error(H: ArrayLike, m_star: ArrayLike, yaw_axis: ArrayLike, theta: float) -> Array:
    """Eq. (2)'s error split into the robot's yaw ``θ`` (rad about ``yaw_axis``, from
    :func:`homography_yaw`) and its translation: with ``R = R_a(θ)``, ``e_v' = (Rᵀ H − I) m* =
    Rᵀ t (nᵀ m*) / d`` and ``e_w' = 2 sin θ a`` (6,).  Not in the paper.

    With ``H = R + t nᵀ / d``, the paper's ``e_v = (R − I) m* + t (nᵀ m*) / d`` carries the rotation
    as well as the translation (``(R − I) m* ≈ [θ]x m*``), so law (3) answers a pure yaw error with a
    sideways translation as large as the rotation itself: at each keyframe of a curve (a 16° yaw step on
    the shipped oval) the drone slides toward the inside while it turns, ε (7) reaches ``T_ε`` with a
    sideways offset the yaw hides in the image, and the offsets add up: the curve is cut.  And its
    ``e_w = vee(H − Hᵀ)`` holds ``(n × t) / d`` besides ``2 sin θ a``, so a translation toward an oblique
    wall reads as a yaw.  Here the translation is what remains of ``H`` once the yaw is taken out,
    expressed in the current camera frame (``Rᵀ``, the frame the velocity is commanded in), and the
    rotation error is the yaw alone: law (3) on ``e'`` drives translation and yaw independently.  For a
    pure yaw ``e_w' = e_w``; for ``θ = 0``, ``e_v' = e_v``.  ``m_star`` ``(x, y)`` or ``(x, y, 1)``
    normalised as in :func:`task_error`; ``yaw_axis`` the body's z axis in camera coordinates (3,).
    """
    h = np.asarray(H, dtype=np.float64).reshape(3, 3)
    ms = keyframe_point(m_star)
    a = _unit_axis(yaw_axis)
    R = axis_rotation(theta, a)
    return np.concatenate((R.T @ h @ ms - ms, 2.0 * math.sin(theta) * a))
