"""The yaw-from-H solve (issue 24): a scan of the rank-one residual, then a bracketed 1-D solve, against
the 12-level zoom it replaced (kept here as the reference), the SVD, finite differences and hand-checked
minima."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_tasks.quad.homography import euclidean_homography, intrinsic_matrix, normalize_pixels
from taskflow_tasks.quad.yaw_decoupling import (
    _bracketed_minimum,
    _gram_terms,
    _scan,
    _scan_residuals,
    axis_rotation,
    homography_yaw,
    rank_one_residual,
)

from taskflow.spatial import R_FLU_OPTICAL

YAW_AXIS = np.array([0.0, -1.0, 0.0])  # body z (up) in the optical camera frame (y down)
K = intrinsic_matrix(208.0, 208.0, 160.0, 120.0)


def svd_residual(H: np.ndarray, angles: np.ndarray) -> np.ndarray:
    s = np.linalg.svd(H[None] - axis_rotation(angles, YAW_AXIS), compute_uv=False)
    return s[:, 1] ** 2 + s[:, 2] ** 2


def zoom_yaw(H: np.ndarray, m: np.ndarray, max_angle: float = math.pi / 2, grid: int = 181) -> float:
    """The implementation before issue 24: the scan, then 12 levels of 9 points over ±step, a quarter
    of it each time, each level one batched SVD; the same choice of candidate."""
    pts = np.column_stack((m, np.ones(len(m))))
    angles = np.linspace(-max_angle, max_angle, grid)
    f = svd_residual(H, angles)
    step = angles[1] - angles[0]
    interior = np.flatnonzero((f[1:-1] <= f[:-2]) & (f[1:-1] <= f[2:])) + 1
    cand = angles[interior] if len(interior) else angles[[int(np.argmin(f))]]
    offsets = np.linspace(-1.0, 1.0, 9)
    while step > 1e-9:
        trial = cand[:, None] + step * offsets[None, :]
        r = svd_residual(H, trial.ravel()).reshape(trial.shape)
        cand = trial[np.arange(len(cand)), np.argmin(r, axis=1)]
        step *= 0.25
    _, sv, vt = np.linalg.svd(H[None] - axis_rotation(cand, YAW_AXIS))
    side = np.where(sv[:, 0] > 1e-12, np.abs(np.sum(np.sign(pts @ vt[:, 0, :].T), axis=0)), len(pts))
    ok = np.flatnonzero(side == side.max())
    return float(cand[int(ok[np.argmin(sv[ok, 1] ** 2 + sv[ok, 2] ** 2)])])


def random_h(rng: np.random.Generator) -> np.ndarray:
    n = np.array([rng.normal() * 0.3, rng.normal() * 0.1, 1.0])
    H = axis_rotation(rng.uniform(-1.2, 1.2), YAW_AXIS) + np.outer(rng.normal(size=3) * 0.2, n) / np.linalg.norm(n) \
        / rng.uniform(1.0, 5.0) + rng.normal(size=(3, 3)) * 1e-3
    return H / np.linalg.svd(H, compute_uv=False)[1]


def view(x: float, y: float, yaw: float, X: np.ndarray) -> np.ndarray:
    """Pixels of world points ``X`` seen by a level forward camera at ``(x, y, 1 m)`` turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R_FLU_OPTICAL
    Xc = (X - [x, y, 1.0]) @ R
    return (Xc[:, :2] / Xc[:, 2:3]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]


def test_residual_is_the_svd_one_from_the_scan_and_from_m_itself():
    """σ2² + σ3² of H − R(θ): the scan's closed form (S = S0 + cos θ S1 + sin θ S2, largest eigenvalue of
    the cubic) and the refinement's (from M itself) against numpy's SVD.  At a rank-one H − R the
    refinement's is zero to ``tr S − λ1``'s rounding, eps σ1² (σ1² = 0.0126 here)."""
    rng = np.random.default_rng(0)
    angles, trig = _scan(math.pi / 2, 181)
    for _ in range(50):
        H = random_h(rng)
        ref = svd_residual(H, angles)
        assert rank_one_residual(H, YAW_AXIS, angles) == pytest.approx(ref, rel=1e-9, abs=1e-15)
        assert _scan_residuals(_gram_terms(H, YAW_AXIS), trig) == pytest.approx(ref, rel=1e-9, abs=1e-14)
    H = axis_rotation(0.3, YAW_AXIS) + np.outer([0.2, 0.0, 0.1], [0.1, 0.0, 1.0]) / 2.0  # exactly R + t nᵀ/d
    assert rank_one_residual(H, YAW_AXIS, [0.3])[0] == pytest.approx(0.0, abs=1e-17)
    assert rank_one_residual(H, YAW_AXIS, [0.3 + 1e-4])[0] > 1e-9  # and grows away from it


def test_bracketed_minimum_of_hand_checked_functions():
    """Brent's method finds (x − 0.3)² + 1 at 0.3 in [0, 1] and cos at π in [2, 4], from a start whose
    parabola is off, and stays in its bracket when the minimum is at an end."""
    def f(x: float) -> float:
        return (x - 0.3) ** 2 + 1.0

    assert _bracketed_minimum(f, 0.0, 1.0, 0.5, 0.0, f(0.0), 1.0, f(1.0)) == pytest.approx(0.3, abs=1e-8)
    assert _bracketed_minimum(math.cos, 2.0, 4.0, 3.5, 4.0, math.cos(4.0), 2.0, math.cos(2.0)) \
        == pytest.approx(math.pi, abs=1e-8)
    x = _bracketed_minimum(math.sin, 0.0, 1.0, 0.2, 0.6, math.sin(0.6), 1.0, math.sin(1.0))
    assert 0.0 <= x < 1e-8  # sin is least at the bracket's left end


def test_yaw_is_a_local_minimum_by_finite_differences():
    """At the returned θ the residual rises both ways (central differences: slope 0 to the residual's
    precision, curvature positive)."""
    rng = np.random.default_rng(1)
    m = np.column_stack((rng.uniform(-0.7, 0.7, 60), rng.uniform(-0.5, 0.5, 60)))
    for _ in range(40):
        H = random_h(rng)
        th = homography_yaw(H, YAW_AXIS, m)
        f0, fm, fp = rank_one_residual(H, YAW_AXIS, [th, th - 1e-5, th + 1e-5])
        assert fm >= f0 and fp >= f0
        assert abs(fp - fm) / 2e-5 < 1e-6 * max(1.0, (fp + fm - 2 * f0) / 1e-10)


def test_yaw_matches_the_zoom_on_views_of_a_wall():
    """Drone views of a textured wall 3 m ahead, 0–25 cm and 0–20° from the keyframe, 0.5 px pixel
    noise (the geometric camera's), H by least squares: the solve gives the zoom's yaw to 1e-7 rad (which
    is the pose's, or the other decomposition's)."""
    rng = np.random.default_rng(2)
    X = np.column_stack((np.full(150, 3.2), rng.uniform(-2.0, 2.0, 150), rng.uniform(0.2, 2.3, 150)))
    kf = view(0.0, 0.0, 0.0, X)
    for _ in range(60):
        x, y, yaw = rng.uniform(-0.25, 0.1), rng.uniform(-0.25, 0.25), rng.uniform(-0.35, 0.35)
        cur = view(x, y, yaw, X) + rng.normal(scale=0.5, size=kf.shape)
        H = euclidean_homography(cur, kf + rng.normal(scale=0.5, size=kf.shape), K)
        m = normalize_pixels(cur, K)
        th = homography_yaw(H, YAW_AXIS, m)
        assert th == pytest.approx(zoom_yaw(H, m), abs=1e-7)
        # the current camera's yaw, or the other decomposition's, up to about ‖t‖/d away (homography_yaw)
        assert abs(th - yaw) < math.hypot(x, y) / 3.2 + 0.02
