"""Yaw decoupling of the homography-based law (not in the paper): the robot's yaw estimated from
``H`` and eq. (2)'s error split into that yaw and the translation, so that turning toward a keyframe
does not slide the drone sideways (``VisualGains.yaw_decoupling``).

Conventions as in :mod:`taskflow_tasks.quad.homography` (``H`` maps the current image to the keyframe,
``m* ∝ H m``, scaled as :func:`~taskflow_tasks.quad.homography.normalize_homography` does).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.quad.homography import homogeneous, keyframe_point

from taskflow.spatial import skew

Array = NDArray[np.float64]

__all__ = ["axis_rotation", "homography_yaw", "rank_one_residual", "yaw_decoupled_error"]


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


def _residual_terms(H: Array, a: Array) -> Array:
    """``T`` (3, 9) with ``vec M(θ) = [1, −cos θ, −sin θ] T`` for ``M = H − R_a(θ)`` (row-major): by Rodrigues,
    ``R_a(θ) = P + cos θ (I − P) + sin θ A`` with ``P = a aᵀ`` and ``A = [a]x``, so the rows of ``T`` are
    ``H − P``, ``I − P`` and ``A``."""
    P = np.outer(a, a)
    terms: Array = np.stack((H - P, np.eye(3) - P, skew(a))).reshape(3, 9)
    return terms


def _gram_terms(H: Array, a: Array) -> Array:
    """``C`` (3, 6) with ``S(θ) = Mᵀ M = S0 + cos θ S1 + sin θ S2`` (upper entries ``S00 S11 S22 S01 S02 S12``
    of ``S0, S1, S2`` in the rows): with ``R = P + cos θ (I − P) + sin θ A`` and ``RᵀR = I``,
    ``S = HᵀH + I − sym(HᵀR)`` (``sym X = X + Xᵀ``), so ``S0 = HᵀH + I − sym(HᵀP)``, ``S1 = −sym(Hᵀ(I − P))``
    and ``S2 = −sym(HᵀA)``."""
    P = np.outer(a, a)
    X = np.stack((H.T @ P, H.T @ (np.eye(3) - P), H.T @ skew(a)))
    C = -(X + X.transpose(0, 2, 1))
    C[0] += H.T @ H + np.eye(3)
    gram: Array = C[:, _UPPER[0], _UPPER[1]]
    return gram


_UPPER = (np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2]))


def _largest_eigenvalue(s00: Array, s11: Array, s22: Array, s01: Array, s02: Array, s12: Array) -> Array:
    """Largest eigenvalue of symmetric 3x3 matrices from their upper entries, in closed form (the
    trigonometric solution of the characteristic cubic, Smith 1961: ``λ_max = q + 2 p cos(acos(r) / 3)``
    with ``q = tr S / 3``, ``6 p² = ‖S − q I‖²``, ``r = det(S − q I) / 2p³``)."""
    mean = (s00 + s11 + s22) / 3.0
    b0, b1, b2 = s00 - mean, s11 - mean, s22 - mean
    p = np.sqrt((b0 * b0 + b1 * b1 + b2 * b2 + 2.0 * (s01 * s01 + s02 * s02 + s12 * s12)) / 6.0)
    det = b0 * b1 * b2 + 2.0 * s01 * s02 * s12 - b0 * s12 * s12 - b1 * s02 * s02 - b2 * s01 * s01
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(p > 0.0, det / (2.0 * p ** 3), 0.0)
    lam: Array = mean + 2.0 * p * np.cos(np.arccos(np.clip(r, -1.0, 1.0)) / 3.0)
    return lam


def _scan_residuals(C: Array, trig: Array) -> Array:
    """``σ2² + σ3² = tr S − λ_max(S)`` at the angles of ``trig`` (``[1, cos θ, sin θ]`` rows) from
    :func:`_gram_terms`: one product for all of them.  ``S``'s entries are sums of terms of order one,
    so where ``S`` is small (a view near its keyframe) they keep an absolute, not a relative,
    precision of about 1e-16: enough to tell which scan points are local minima, not to refine one
    (:func:`_residual_at` does that from ``M`` itself)."""
    e = trig @ C
    s00, s11, s22 = e[:, 0], e[:, 1], e[:, 2]
    res: Array = s00 + s11 + s22 - _largest_eigenvalue(s00, s11, s22, e[:, 3], e[:, 4], e[:, 5])
    return res


@functools.lru_cache(maxsize=4)
def _scan(max_angle: float, n: int) -> tuple[Array, Array]:
    """The scan's angles and their ``[1, cos θ, sin θ]``."""
    angles = np.linspace(-max_angle, max_angle, n)
    trig = np.column_stack((np.ones(n), np.cos(angles), np.sin(angles)))
    angles.setflags(write=False)
    trig.setflags(write=False)  # shared by every call (cached)
    return angles, trig


def rank_one_residual(H: ArrayLike, yaw_axis: ArrayLike, angles: ArrayLike) -> Array:
    """``σ2² + σ3²`` of ``H − R_a(θ)`` for each angle (N,): how far ``H − R`` is from the rank-one
    ``t nᵀ/d`` of eq. (2) (:func:`_residual_at`, from ``M = H − R`` itself)."""
    h = np.asarray(H, dtype=np.float64).reshape(3, 3)
    f = _residual_at(_residual_terms(h, _unit_axis(yaw_axis)))
    return np.array([f(t) for t in np.atleast_1d(np.asarray(angles, dtype=np.float64)).tolist()])


def _residual_at(T: Array) -> Callable[[float], float]:
    """``f(θ) = σ2² + σ3²`` of ``M(θ)`` (:func:`_residual_terms`) for one angle, in plain floats: ``M``,
    ``S = Mᵀ M`` and ``tr S − λ_max(S)`` as in :func:`_largest_eigenvalue`.  ``M`` is formed first, so
    ``f`` keeps its precision where ``M`` is small (a view near its keyframe).  Plain floats because the
    refinement evaluates a few dozen single angles, where numpy's cost per call on 3x3 arrays would
    dominate."""
    rows: list[list[float]] = T.tolist()
    (h0, h1, h2, h3, h4, h5, h6, h7, h8), (q0, q1, q2, q3, q4, q5, q6, q7, q8), (k0, k1, k2, k3, k4, k5, k6, k7, k8) = rows

    def f(theta: float) -> float:
        c, s = math.cos(theta), math.sin(theta)
        m0, m1, m2 = h0 - c * q0 - s * k0, h1 - c * q1 - s * k1, h2 - c * q2 - s * k2
        m3, m4, m5 = h3 - c * q3 - s * k3, h4 - c * q4 - s * k4, h5 - c * q5 - s * k5
        m6, m7, m8 = h6 - c * q6 - s * k6, h7 - c * q7 - s * k7, h8 - c * q8 - s * k8
        s00 = m0 * m0 + m3 * m3 + m6 * m6
        s11 = m1 * m1 + m4 * m4 + m7 * m7
        s22 = m2 * m2 + m5 * m5 + m8 * m8
        s01 = m0 * m1 + m3 * m4 + m6 * m7
        s02 = m0 * m2 + m3 * m5 + m6 * m8
        s12 = m1 * m2 + m4 * m5 + m7 * m8
        tr = s00 + s11 + s22
        mean = tr / 3.0
        b0, b1, b2 = s00 - mean, s11 - mean, s22 - mean
        p = math.sqrt((b0 * b0 + b1 * b1 + b2 * b2 + 2.0 * (s01 * s01 + s02 * s02 + s12 * s12)) / 6.0)
        if p == 0.0:
            return tr - mean
        det = b0 * b1 * b2 + 2.0 * s01 * s02 * s12 - b0 * s12 * s12 - b1 * s02 * s02 - b2 * s01 * s01
        r = min(1.0, max(-1.0, det / (2.0 * p * p * p)))
        return tr - (mean + 2.0 * p * math.cos(math.acos(r) / 3.0))

    return f


_GOLDEN = 0.3819660112501051  # (3 − √5) / 2
_ZOOM = tuple(np.linspace(-1.0, 1.0, 9).tolist())  # the first refinement of a scan minimum, in scan steps


def _bracketed_minimum(f: Callable[[float], float], lo: float, hi: float, x: float, w: float, fw: float,
                       v: float, fv: float, xtol: float = 1e-9) -> float:
    """Brent's minimisation of ``f`` in ``[lo, hi]`` (parabolic interpolation through the best three
    points, golden sections where it would leave the bracket or not shrink it; Brent 1973, ch. 5),
    started from the scan's point ``x`` and its neighbours ``w``, ``v`` (``f(w) = fw``, ``f(v) = fv``),
    to ``xtol`` rad."""
    a, b = lo, hi
    fx = f(x)
    d = e = b - a
    for _ in range(100):
        mid = 0.5 * (a + b)
        if abs(x - mid) <= 2.0 * xtol - 0.5 * (b - a):
            break
        golden = True
        if abs(e) > xtol:  # try the parabola through x, w, v
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            if abs(p) < abs(0.5 * q * e) and q * (a - x) < p < q * (b - x):
                e, d = d, p / q
                golden = False
                if (x + d) - a < 2.0 * xtol or b - (x + d) < 2.0 * xtol:
                    d = xtol if mid >= x else -xtol
        if golden:
            e = (a - x) if x >= mid else (b - x)
            d = _GOLDEN * e
        u = x + (d if abs(d) >= xtol else math.copysign(xtol, d))
        fu = f(u)
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v in (x, w):
                v, fv = u, fu
    return x


def homography_yaw(H: ArrayLike, yaw_axis: ArrayLike, m: ArrayLike, max_angle: float = math.pi / 2,
                   grid: int = 181) -> float:
    """The rotation of ``H = R + t nᵀ / d`` (eq. 2) for a robot that only yaws: the angle θ (rad) about
    ``yaw_axis`` for which ``H − R_a(θ)`` is closest to rank one (least ``σ2² + σ3²``).  Not in the paper.

    A planar homography has two decompositions (Faugeras & Lustman 1988); for a level camera moving
    level in front of a vertical plane both have a yaw-only ``R``: the true one and one turned by about
    the translation over the plane's distance.  The local minima of a ``grid``-point scan of the
    residual (:func:`rank_one_residual`) over ``±max_angle`` are the candidates; each is refined by the
    best of 9 points over ± one scan step (the two decompositions can share a step), then by Brent's
    bracketed 1-D minimisation between that point's neighbours, to 1e-9 rad.  Kept are those whose
    plane puts the most current points ``m`` (normalised, (N, 2) or (N, 3)) on one side (``nᵀ m_j`` of
    one sign: positive depths, the visibility constraint), and of these the one of least residual.
    The visibility test rejects the other decomposition when the translation is mostly sideways (its
    normal then lies nearly in the image plane, with points on both sides); when it is mostly along
    the optical axis both may pass and the choice is the residual's (with noise, either): the two yaws
    then differ by up to about ‖t‖/d (they coincide as the translation vanishes).  Tracking the plane's
    normal from frame to frame to choose instead was tried and is worse (it can lock on the other
    branch: geometric oval seed 1, 40 cm off).  ``H`` must map the current image to the keyframe
    (``m* ∝ H m``) and be scaled as :func:`normalize_homography` does.
    """
    h = np.asarray(H, dtype=np.float64).reshape(3, 3)
    a = _unit_axis(yaw_axis)
    pts = np.asarray(m, dtype=np.float64)
    pts = homogeneous(pts) if pts.shape[-1] == 2 else pts.reshape(-1, 3)
    angles, trig = _scan(float(max_angle), int(grid))
    f = _scan_residuals(_gram_terms(h, a), trig)
    step = float(angles[1] - angles[0])
    interior = np.flatnonzero((f[1:-1] <= f[:-2]) & (f[1:-1] <= f[2:])) + 1
    T = _residual_terms(h, a)
    f_at = _residual_at(T)
    cand = []
    for c in (angles[interior] if len(interior) else angles[[int(np.argmin(f))]]).tolist():
        x = [c + step * z for z in _ZOOM]  # 9 points over ±step …
        fx = [f_at(t) for t in x]
        j = min(range(9), key=fx.__getitem__)  # … the best of them, bracketed by its neighbours
        if j == 0:  # at an end: one more point beyond it
            x.insert(0, c - 1.25 * step)
            fx.insert(0, f_at(x[0]))
            j = 1
        elif j == 8:
            x.append(c + 1.25 * step)
            fx.append(f_at(x[-1]))
        w, v = (j - 1, j + 1) if fx[j - 1] <= fx[j + 1] else (j + 1, j - 1)
        cand.append(_bracketed_minimum(f_at, x[j - 1], x[j + 1], x[j], x[w], fx[w], x[v], fx[v]))
    th = np.asarray(cand)
    M = (np.column_stack((np.ones(len(th)), -np.cos(th), -np.sin(th))) @ T).reshape(-1, 3, 3)
    w2, vec = np.linalg.eigh(M.transpose(0, 2, 1) @ M)  # ascending: σ3², σ2², σ1²; right singular vectors
    # the rank-one part's row direction is the plane normal (current frame); points on its side (all of
    # them when H − R vanishes: no translation, any plane), then the residual
    side = np.where(w2[:, 2] > 1e-24, np.abs(np.sum(np.sign(pts @ vec[:, :, 2].T), axis=0)), len(pts))
    ok = np.flatnonzero(side == side.max())
    return float(th[int(ok[np.argmin(w2[ok, 0] + w2[ok, 1])])])


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
