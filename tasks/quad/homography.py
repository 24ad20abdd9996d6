"""Homography-based visual servoing of a quadcopter: pure laws (arrays in, arrays out).

Toro-Arcila, Becerra, Arechavaleta, *Visual path following with obstacle avoidance for quadcopters in
indoor environments* (Control Engineering Practice), section 2, eqs. (2)–(7), Alg. 1's choice of the
virtual plane, and the feed-forward term of section 4.2, eqs. (31)–(32).

Conventions
-----------
* Camera frame: OpenCV (x right, y down, z along the optical axis).  Camera twist
  ``nu_c = [v, w]`` (6,): velocity of the camera origin and angular velocity, in the camera frame.
* ``K`` is the 3x3 intrinsic matrix; ``m = K^-1 p`` are normalised homogeneous coordinates.
* **Direction of H (eq. 2 "as meant").**  ``H`` maps the *current* image to the *keyframe*:
  ``m* ∝ H m`` (projective ``G = K H K^-1`` is ``findHomography(current_px, keyframe_px)``).  With
  this direction ``H = R + t n^T / d`` where ``(R, t)`` is the pose of the current camera in the
  keyframe camera frame, so at small errors ``e_v ≈ t / Z*`` and ``e_w ≈ 2 θ`` (θ the rotation
  vector of the current camera w.r.t. the keyframe): the printed law (3) ``nu_c = -Λ e`` then
  drives the camera *to* the keyframe.  With the opposite direction (``findHomography(keyframe,
  current)``) the same printed law drives it away — checked in ``tests/unit/laws/quad/test_homography.py``
  with a synthetic camera (points on a plane, exact projection).
* Robot (quadcopter) body frame ``{e}``: x forward, y left, z up (FLU).  The paper's Bebop frame is
  x forward, y right, z down, hence its ``eR_c = [[0,0,1],[1,0,0],[0,1,0]]``; in FLU the same
  forward-looking camera is ``eR_c = [[0,0,1],[-1,0,0],[0,-1,0]]`` (:data:`taskflow.spatial.R_FLU_OPTICAL`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from taskflow.spatial import skew, vee

Array = NDArray[np.float64]

__all__ = [
    "SELECT_4DOF",
    "HomographyGains",
    "adaptive_gain",
    "euclidean_homography",
    "feedforward_blend",
    "feedforward_velocity",
    "gain_matrix",
    "homography_control",
    "homogeneous",
    "intrinsic_matrix",
    "keyframe_point",
    "largest_triangle",
    "mean_pixel_error",
    "normalize_homography",
    "normalize_pixels",
    "robot_velocity",
    "sort_points",
    "task_error",
    "virtual_plane_homography",
]

SELECT_4DOF: Array = np.array(
    [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    ]
)
"""Selection matrix of eq. (6): keep ``[vx, vy, vz, wz]`` of a 6-D twist."""


# ---------------------------------------------------------------------------------------------
# small helpers


def intrinsic_matrix(fx: float, fy: float, cx: float, cy: float) -> Array:
    """``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def normalize_pixels(points_px: ArrayLike, K: ArrayLike) -> Array:
    """Pixels ``(N, 2)`` → normalised image coordinates ``(N, 2)``, ``[x, y, 1]^T = K^-1 p``."""
    p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    k = np.asarray(K, dtype=np.float64)
    return np.column_stack(((p[:, 0] - k[0, 2]) / k[0, 0], (p[:, 1] - k[1, 2]) / k[1, 1]))


def homogeneous(points: ArrayLike) -> Array:
    a = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return np.column_stack((a, np.ones(len(a))))


# ---------------------------------------------------------------------------------------------
# eq. (2): the Euclidean homography


def normalize_homography(G: ArrayLike, K: ArrayLike, m: ArrayLike | None = None,
                         m_star: ArrayLike | None = None) -> Array:
    """Euclidean homography ``H = K^-1 G K`` scaled so its middle singular value is 1 (eq. 2).

    A Euclidean homography ``R + t n^T / d`` has middle singular value exactly 1, which fixes the
    scale; the sign is chosen so that the depth ratios are positive: with correspondences ``m`` (current)
    and ``m_star`` (keyframe), ``m_star_j^T H m_j > 0`` for most of them, else ``det H > 0``.
    """
    g = np.asarray(G, dtype=np.float64).reshape(3, 3)
    k = np.asarray(K, dtype=np.float64).reshape(3, 3)
    H: Array = np.linalg.solve(k, g) @ k
    s = np.linalg.svd(H, compute_uv=False)
    if not (np.all(np.isfinite(s)) and s[1] > 0.0):
        raise ValueError("degenerate homography: its middle singular value is not positive")
    H = H / s[1]
    if m is not None and m_star is not None:
        a, b = homogeneous(m), homogeneous(m_star)
        sign = np.sum(np.einsum("ij,ij->i", b, a @ H.T) > 0.0) * 2 >= len(a)
        return H if sign else -H
    return H if np.linalg.det(H) > 0.0 else -H


def euclidean_homography(current_px: ArrayLike, keyframe_px: ArrayLike, K: ArrayLike) -> Array:
    """``H`` with ``m* ∝ H m`` from ≥ 4 exact or least-squares correspondences (DLT, eq. 2).

    For noisy, outlier-laden matches use OpenCV's RANSAC (:mod:`taskflow_tasks.quad.perception`) and
    :func:`normalize_homography`; this plain DLT is the reference used by tests and the feed-forward.
    """
    m = normalize_pixels(current_px, K)
    ms = normalize_pixels(keyframe_px, K)
    if len(m) < 4 or len(m) != len(ms):
        raise ValueError(f"need >= 4 correspondences of equal count, got {len(m)} and {len(ms)}")
    x, y, u, v = m[:, 0], m[:, 1], ms[:, 0], ms[:, 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    A = np.empty((2 * len(m), 9))
    A[0::2] = np.column_stack((x, y, one, zero, zero, zero, -u * x, -u * y, -u))
    A[1::2] = np.column_stack((zero, zero, zero, x, y, one, -v * x, -v * y, -v))
    _, _, vt = np.linalg.svd(A, full_matrices=False)
    Hn = vt[-1].reshape(3, 3)
    k = np.asarray(K, dtype=np.float64)
    return normalize_homography(k @ Hn @ np.linalg.inv(k), k, m, ms)


def virtual_plane_homography(F: ArrayLike, m: ArrayLike, m_star: ArrayLike) -> Array:
    """Homography of the virtual plane through three points (Malis & Chaumette 2000; Alg. 1).

    ``F`` is the fundamental matrix in *normalised* coordinates with ``m*^T F m = 0`` (current →
    keyframe, i.e. the essential matrix up to scale); ``m``, ``m_star`` are the three points (3, 2) of
    the largest triangle in normalised coordinates.  Returns the (unnormalised) ``H`` with
    ``m*_i ∝ H m_i`` for the three points and consistent with the epipolar geometry
    (Hartley & Zisserman, Result 13.6: ``H = [e']x F - e' (M^-1 b)^T``).
    """
    f = np.asarray(F, dtype=np.float64).reshape(3, 3)
    x = homogeneous(m)
    xp = homogeneous(m_star)
    if len(x) != 3 or len(xp) != 3:
        raise ValueError("the virtual plane needs exactly three points")
    _, _, vt = np.linalg.svd(f.T)
    e = vt[-1]  # F^T e' = 0: epipole in the keyframe image
    A = skew(e) @ f
    b = np.empty(3)
    for i in range(3):
        c1 = np.cross(xp[i], A @ x[i])
        c2 = np.cross(xp[i], e)
        den = float(c2 @ c2)
        if den < 1e-18:
            raise ValueError("a virtual-plane point lies on the epipole")
        b[i] = float(c1 @ c2) / den
    M = x  # rows x_i^T
    if abs(np.linalg.det(M)) < 1e-12:
        raise ValueError("the three virtual-plane points are collinear")
    return A - np.outer(e, np.linalg.solve(M, b))


# ---------------------------------------------------------------------------------------------
# Alg. 1: three points of the largest triangle


def _hull_indices(p: Array) -> list[int]:
    """Indices of the convex hull of ``p`` (N, 2), monotone chain, counter-clockwise."""
    order = sorted(range(len(p)), key=lambda i: (p[i, 0], p[i, 1]))
    if len(order) <= 2:
        return order

    def cross(o: int, a: int, b: int) -> float:
        return float((p[a, 0] - p[o, 0]) * (p[b, 1] - p[o, 1]) - (p[a, 1] - p[o, 1]) * (p[b, 0] - p[o, 0]))

    lower: list[int] = []
    for i in order:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], i) <= 0.0:
            lower.pop()
        lower.append(i)
    upper: list[int] = []
    for i in reversed(order):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], i) <= 0.0:
            upper.pop()
        upper.append(i)
    return lower[:-1] + upper[:-1]


def largest_triangle(points: ArrayLike) -> tuple[int, int, int]:
    """Indices of the three points spanning the triangle of largest area (Alg. 1, ``sortPoints``).

    The maximum-area triangle has its vertices on the convex hull, so only hull points are searched
    (exhaustively: a hull of image features has a few dozen points at most).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) < 3:
        raise ValueError(f"need at least 3 points, got {len(p)}")
    hull = _hull_indices(p)
    if len(hull) < 3:
        raise ValueError("all points are collinear")
    h = p[hull]
    n = len(h)
    best, best_idx = -1.0, (0, 1, 2)
    for a in range(n - 2):
        for bb in range(a + 1, n - 1):
            c = np.arange(bb + 1, n)
            area = np.abs((h[bb, 0] - h[a, 0]) * (h[c, 1] - h[a, 1]) - (h[bb, 1] - h[a, 1]) * (h[c, 0] - h[a, 0]))
            m = int(np.argmax(area))
            if area[m] > best:
                best, best_idx = float(area[m]), (a, bb, int(c[m]))
    if best <= 0.0:
        raise ValueError("all points are collinear")
    i, j, k = best_idx
    return hull[i], hull[j], hull[k]


def sort_points(points: ArrayLike) -> Array:
    """Order of the matched points for Alg. 1: the largest triangle's vertices first, then the rest
    in the order they came from the matcher.  Returns the permutation (indices into ``points``)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    tri = list(largest_triangle(p))
    rest = [i for i in range(len(p)) if i not in tri]
    return np.asarray(tri + rest, dtype=np.intp)


# ---------------------------------------------------------------------------------------------
# eqs. (2)–(4): task error, gains, control law


def keyframe_point(m_star: ArrayLike) -> Array:
    """A normalised keyframe point ``(x, y)`` or ``(x, y, 1)`` as ``(x, y, 1)`` (3,)."""
    ms = np.asarray(m_star, dtype=np.float64).reshape(-1)
    if ms.shape == (2,):
        ms = np.array([ms[0], ms[1], 1.0])
    if ms.shape != (3,):
        raise ValueError(f"m_star must be (x, y) or (x, y, 1), got shape {ms.shape}")
    return ms


def task_error(H: ArrayLike, m_star: ArrayLike) -> Array:
    """Eq. (2): ``e_v = (H - I) m*``, ``[e_w]x = H - H^T``; returns ``e = [e_v, e_w]`` (6,).

    ``m_star`` is a keyframe point on the plane that defines ``H``, normalised: ``(x, y)`` or
    ``(x, y, 1)``.  ``e = 0`` iff ``H = I`` for a point off the plane's vanishing line.
    """
    h = np.asarray(H, dtype=np.float64).reshape(3, 3)
    ms = keyframe_point(m_star)
    e_v = (h - np.eye(3)) @ ms
    e_w = vee(h - h.T)
    return np.concatenate((e_v, e_w))


def adaptive_gain(norm_e: float | Array, lambda_0: float, lambda_inf: float, slope_0: float) -> float | Array:
    """Eq. (4): ``λ(‖e‖) = (λ0 − λ∞) exp(−λ0' ‖e‖ / (λ0 − λ∞)) + λ∞``.

    ``λ(0) = λ0``, ``λ(∞) = λ∞``, slope ``−λ0'`` at 0 (the paper's ``λ0'`` is the magnitude of the slope).
    With ``λ0 = λ∞`` the gain is constant.
    """
    d = lambda_0 - lambda_inf
    if d == 0.0:
        return lambda_inf + 0.0 * np.asarray(norm_e, dtype=np.float64) if np.ndim(norm_e) else float(lambda_inf)
    out = d * np.exp(-slope_0 * np.asarray(norm_e, dtype=np.float64) / d) + lambda_inf
    return float(out) if np.ndim(out) == 0 else out


class HomographyGains(NamedTuple):
    """How the scalar adaptive gain λ becomes the diagonal gain matrix of eq. (3).

    Paper §5.1: ``λ_vx = λ_vz = λ``, ``λ_vy = λ + 2.5``, ``λ_w = 0.5 λ`` (camera axes: y is vertical),
    i.e. ``v_scale = (1, 1, 1)``, ``v_offset = (0, 2.5, 0)``, ``w_scale = 0.5``.
    """

    v_scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    v_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    w_scale: float = 0.5
    w_offset: float = 0.0


def gain_matrix(lam: float, gains: HomographyGains | None = None) -> Array:
    """Diagonal of ``diag(λ_v I, λ_w I)`` in eq. (3) from the scalar gain ``λ`` (6,)."""
    gains = gains if gains is not None else HomographyGains()
    lv = np.asarray(gains.v_scale, dtype=np.float64) * lam + np.asarray(gains.v_offset, dtype=np.float64)
    lw = np.full(3, gains.w_scale * lam + gains.w_offset)
    return np.concatenate((lv, lw))


def homography_control(e: ArrayLike, gains: ArrayLike) -> Array:
    """Eq. (3): ``nu_c = -diag(λ_v I, λ_w I) e`` with ``gains`` the 6 diagonal entries (or a scalar).

    Sign as printed, valid with ``H`` mapping the current image to the keyframe (module docstring).
    """
    ev = np.asarray(e, dtype=np.float64).reshape(6)
    g = np.broadcast_to(np.asarray(gains, dtype=np.float64), (6,))
    return -g * ev


# ---------------------------------------------------------------------------------------------
# eqs. (5)–(7)


def robot_velocity(nu_c: ArrayLike, Ad_body_camera: ArrayLike) -> Array:
    """Eq. (6): ``nu_e = S eT_c nu_c = [vx, vy, vz, wz]`` in the body frame.

    ``Ad_body_camera`` is eq. (5)'s ``eT_c = [[eR_c, [et_c]x eR_c], [0, eR_c]]``, the 6x6 map of a
    camera twist to the body twist: ``taskflow.spatial.twist_adjoint(T_body_camera)``."""
    return SELECT_4DOF @ (np.asarray(Ad_body_camera, dtype=np.float64).reshape(6, 6) @ np.asarray(nu_c, dtype=np.float64).reshape(6))


def mean_pixel_error(p: ArrayLike, p_star: ArrayLike) -> float:
    """Eq. (7): ``ε = (1/l) Σ ‖p_j − p*_j‖`` over corresponding pixels (the paper calls it the mean
    square error; it is the mean Euclidean distance)."""
    a = np.asarray(p, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(p_star, dtype=np.float64).reshape(-1, 2)
    if len(a) != len(b) or len(a) == 0:
        raise ValueError(f"need equal, non-zero numbers of points, got {len(a)} and {len(b)}")
    return float(np.mean(np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])))


# ---------------------------------------------------------------------------------------------
# eqs. (31)–(32): feed-forward


def feedforward_velocity(e_segment: ArrayLike, gains: ArrayLike, gamma: float, Ad_body_camera: ArrayLike) -> Array:
    """Eq. (32): ``nu_p = S γ eT_c nu_c`` with ``nu_c`` the law (3) between consecutive keyframes.

    ``e_segment`` is the task error (2) of keyframe ``k+1`` seen from keyframe ``k`` (``H`` mapping
    keyframe ``k``'s image to keyframe ``k+1``'s); ``gains`` the diagonal of eq. (3) for it.
    """
    if not (0.0 <= gamma <= 1.0):
        raise ValueError(f"gamma must be in [0, 1], got {gamma}")
    return robot_velocity(gamma * homography_control(e_segment, gains), Ad_body_camera)


def feedforward_blend(nu_e: ArrayLike, nu_p: ArrayLike, p: float) -> Array:
    """Eq. (31): ``nu_ef = p nu_e + (1 − p) nu_p`` (both 4-D body velocities), ``p ∈ [0, 1]``."""
    if not (0.0 <= p <= 1.0):
        raise ValueError(f"p must be in [0, 1], got {p}")
    return p * np.asarray(nu_e, dtype=np.float64).reshape(4) + (1.0 - p) * np.asarray(nu_p, dtype=np.float64).reshape(4)
