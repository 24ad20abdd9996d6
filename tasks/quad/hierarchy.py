"""Hierarchical visual servoing of a quadcopter: collision avoidance > visibility > visual task.

Toro-Arcila, Becerra, Arechavaleta (Control Engineering Practice), section 3, eqs. (8)–(20), and the
keyframe transition of section 4, eqs. (28)–(29).  Pure functions; arrays in, arrays out.

Conventions as in :mod:`taskflow_tasks.quad.homography`: normalised image coordinates ``(x, y) = K^-1 p``, camera
twists ``[v, w]`` in the camera frame (OpenCV axes).  The hierarchy works on any velocity space of
dimension ``n`` (6 for the camera twist of the paper); the Jacobians' columns define it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from taskflow.shaping import activation  # eq. (20), shared with the mission `blend:`

Array = NDArray[np.float64]

__all__ = [
    "Activation",
    "HierarchyResult",
    "activation",
    "collision_error",
    "collision_jacobian",
    "hierarchical_control",
    "pinv",
    "point_interaction",
    "points_outside",
    "transition_weight",
    "visibility_error",
    "visibility_jacobian",
]


def point_interaction(x: float, y: float, z: float) -> Array:
    """Interaction matrix (2x6) of a normalised image point at depth ``z`` (eq. 9's ``J_2`` rows,
    eq. 12's ``J_m``): ``[[-1/z, 0, x/z, xy, -(1+x²), y], [0, -1/z, y/z, 1+y², -xy, -x]]``."""
    if not (math.isfinite(z) and z > 0.0):
        raise ValueError(f"depth estimate must be finite and > 0, got {z}")
    return np.array(
        [
            [-1.0 / z, 0.0, x / z, x * y, -(1.0 + x * x), y],
            [0.0, -1.0 / z, y / z, 1.0 + y * y, -x * y, -x],
        ]
    )


# ---------------------------------------------------------------------------------------------
# eqs. (8)–(9): collision avoidance


def collision_error(p1: ArrayLike, p2: ArrayLike, sigma: float) -> float:
    """Eq. (8): ``e_a = ‖p1 − p2‖ − σ`` for the obstacle's two edge points (normalised coordinates).

    Positive when the obstacle looks wider than ``σ`` (too close): the task is then activated.
    """
    a = np.asarray(p1, dtype=np.float64).reshape(2)
    b = np.asarray(p2, dtype=np.float64).reshape(2)
    return float(math.hypot(a[0] - b[0], a[1] - b[1]) - sigma)


def collision_jacobian(p1: ArrayLike, p2: ArrayLike, z1: float, z2: float) -> Array:
    """Eq. (9): ``J_a = (1/d) J_1 J_2`` (1x6), ``d = ‖p1 − p2‖``, with depth estimates ``z1, z2``."""
    x1, y1 = np.asarray(p1, dtype=np.float64).reshape(2)
    x2, y2 = np.asarray(p2, dtype=np.float64).reshape(2)
    d = math.hypot(x1 - x2, y1 - y2)
    if d <= 0.0:
        raise ValueError("the two obstacle edge points coincide")
    J1 = np.array([[x1 - x2, y1 - y2, x2 - x1, y2 - y1]])
    J2 = np.vstack((point_interaction(x1, y1, z1), point_interaction(x2, y2, z2)))
    return (J1 @ J2) / d


# ---------------------------------------------------------------------------------------------
# eqs. (10)–(12): visibility


def visibility_error(points: ArrayLike, c_star: ArrayLike) -> Array:
    """Eqs. (10)–(11): ``e_m = c_m − c*_m`` with ``c_m`` the mean of the current normalised points."""
    m = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(m) == 0:
        raise ValueError("visibility error of an empty point set")
    e_m: Array = m.mean(axis=0) - np.asarray(c_star, dtype=np.float64).reshape(2)
    return e_m


def visibility_jacobian(c: ArrayLike, z: float) -> Array:
    """Eq. (12): ``J_m`` — the interaction matrix (2x6) of the centroid ``c`` at estimated depth ``z``."""
    x, y = np.asarray(c, dtype=np.float64).reshape(2)
    return point_interaction(x, y, z)


def points_outside(points_px: ArrayLike, rect: ArrayLike) -> bool:
    """``checkPoints`` of Alg. 1: does any point lie outside the safety rectangle
    ``(u_min, v_min, u_max, v_max)`` (pixels)?"""
    p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    u0, v0, u1, v1 = np.asarray(rect, dtype=np.float64).reshape(4)
    if len(p) == 0:
        return False
    return bool(np.any((p[:, 0] < u0) | (p[:, 0] > u1) | (p[:, 1] < v0) | (p[:, 1] > v1)))


# ---------------------------------------------------------------------------------------------
# eqs. (13)–(19): the strict hierarchy with intermediate values


def pinv(J: ArrayLike, rcond: float = 1e-9) -> Array:
    """Moore–Penrose pseudo-inverse (singular values below ``rcond·σ_max`` treated as zero).

    A matrix of one or two rows (the collision task's ``Ĵ_a``, the visibility task's ``Ĵ_m`` and
    ``Ĵ_m N_a``) of full row rank is inverted as ``Jᵀ (J Jᵀ)⁻¹`` with the 1x1 or 2x2 inverse in closed
    form — the same matrix to about 1e-10 relative, without an SVD; a zero row, or two rows nearly
    parallel (``det(J Jᵀ) ≤ 1e-6 tr(J Jᵀ)²``, where the Gram matrix would square an ill condition and
    the rank decision belongs to the SVD's ``rcond``), go to numpy's SVD."""
    a = np.asarray(J, dtype=np.float64)
    if a.ndim == 2 and a.shape[0] <= 2 <= a.shape[1]:
        if a.shape[0] == 1:
            g = float(a[0] @ a[0])
            if g > 0.0:
                out: Array = a.T / g
                return out
        else:
            g00, g01, g11 = float(a[0] @ a[0]), float(a[0] @ a[1]), float(a[1] @ a[1])
            det = g00 * g11 - g01 * g01
            if det > 1e-6 * (g00 + g11) ** 2:
                out = a.T @ (np.array([[g11, -g01], [-g01, g00]]) / det)
                return out
    svd: Array = np.linalg.pinv(a, rcond=rcond).astype(np.float64, copy=False)
    return svd


@dataclass(frozen=True)
class HierarchyResult:
    """Output of :func:`hierarchical_control`: the total and each level's velocity (eq. 13–16), the
    null-space projectors and the intermediate desired error rates (eq. 17–19)."""

    nu: Array
    nu_a: Array
    nu_m: Array
    nu_v: Array
    N_a: Array
    N_m: Array
    de_a: Array
    de_m: Array
    de_v: Array


def hierarchical_control(
    J_a: ArrayLike,
    e_a: ArrayLike,
    J_m: ArrayLike,
    e_m: ArrayLike,
    J_v: ArrayLike,
    e_v: ArrayLike,
    lambda_a: ArrayLike,
    lambda_m: ArrayLike,
    lambda_v: ArrayLike,
    h_a: float,
    h_m: float,
    h_v: float = 1.0,
) -> HierarchyResult:
    """Eqs. (13)–(19): ``nu = nu_a + nu_m + nu_v`` with

    * ``nu_a = Ĵ_a⁺ ė_a^i`` (14), ``nu_m = (Ĵ_m N_a)⁺ (ė_m^i − Ĵ_m nu_a)`` (15),
      ``nu_v = (Ĵ_v N_m)⁺ (ė_v^i − Ĵ_v (nu_a + nu_m))`` (16);
    * ``N_a = I − Ĵ_a⁺ Ĵ_a``, ``N_m = N_a − (Ĵ_m N_a)⁺ (Ĵ_m N_a)``;
    * intermediate values (17)–(19), e.g.
      ``ė_a^i = −h_a λ_a e_a + (1 − h_a) Ĵ_a (−h_m λ_m Ĵ_m⁺ e_m − h_v λ_v Ĵ_v⁺ e_v)``.

    ``lambda_*`` are scalars or per-row gains (a vector, e.g. the 6 gains of eq. 3 for the visual
    task, applied as ``diag(λ) e``).  With ``h_a = h_m = 0`` and ``h_v = 1`` the law reduces to the
    visual task alone, ``nu = −Ĵ_v⁺ λ_v e_v``.  The level-1 error rate ``Ĵ_a nu`` equals ``ė_a^i`` whatever
    the lower levels ask (strict priority; tested numerically).
    """
    Ja = np.atleast_2d(np.asarray(J_a, dtype=np.float64))
    Jm = np.atleast_2d(np.asarray(J_m, dtype=np.float64))
    Jv = np.atleast_2d(np.asarray(J_v, dtype=np.float64))
    n = Ja.shape[1]
    if Jm.shape[1] != n or Jv.shape[1] != n:
        raise ValueError(f"Jacobians must share their column count, got {Ja.shape}, {Jm.shape}, {Jv.shape}")
    ea = np.asarray(e_a, dtype=np.float64).reshape(Ja.shape[0])
    em = np.asarray(e_m, dtype=np.float64).reshape(Jm.shape[0])
    ev = np.asarray(e_v, dtype=np.float64).reshape(Jv.shape[0])
    la = np.asarray(lambda_a, dtype=np.float64)
    lm = np.asarray(lambda_m, dtype=np.float64)
    lv = np.asarray(lambda_v, dtype=np.float64)
    Ja_p, Jm_p, Jv_p = pinv(Ja), pinv(Jm), pinv(Jv)
    # each task's own velocity: −h λ Ĵ⁺ e
    ua = -h_a * (Ja_p @ (la * ea))
    um = -h_m * (Jm_p @ (lm * em))
    uv = -h_v * (Jv_p @ (lv * ev))
    de_a = -h_a * la * ea + (1.0 - h_a) * (Ja @ (um + uv))  # (17)
    de_m = -h_m * lm * em + (1.0 - h_m) * (Jm @ (ua + uv))  # (18)
    de_v = -h_v * lv * ev + (1.0 - h_v) * (Jv @ (ua + um))  # (19)
    I = np.eye(n)
    N_a = I - Ja_p @ Ja
    JmNa = Jm @ N_a
    JmNa_p = pinv(JmNa)
    N_m = N_a - JmNa_p @ JmNa
    nu_a = Ja_p @ de_a  # (14)
    nu_m = JmNa_p @ (de_m - Jm @ nu_a)  # (15)
    nu_v = pinv(Jv @ N_m) @ (de_v - Jv @ (nu_a + nu_m))  # (16)
    return HierarchyResult(nu_a + nu_m + nu_v, nu_a, nu_m, nu_v, N_a, N_m, de_a, de_m, de_v)


# ---------------------------------------------------------------------------------------------
# eqs. (20), (28)–(29): activation and keyframe transition


def transition_weight(tau: float, duration: float, h0: float) -> float:
    """Eq. (29): ``h_t = h0 + ½ (1 − h0)(1 − cos(π τ / (t_f − t_0)))``, 1 after ``t_f``: rises
    smoothly from ``h0`` at the keyframe switch to 1 (so ``h_t = h0 + (1 − h0) h(τ)``)."""
    if not (0.0 <= h0 <= 1.0):
        raise ValueError(f"h0 must be in [0, 1], got {h0}")
    return h0 + (1.0 - h0) * activation(tau, duration)


class Activation:
    """``h_a(t)`` / ``h_m(t)`` of Alg. 1: rises with eq. (20) while the task's condition holds and
    falls with ``1 − h`` when it stops holding.

    A switch in the middle of a rise (or fall) continues from the current value (``h`` rescaled over
    the remaining span), so the weight is continuous at every switch; a full rise or fall takes
    ``duration`` seconds.
    """

    def __init__(self, duration: float, active: bool = False, t: float = 0.0) -> None:
        if not (math.isfinite(duration) and duration >= 0.0):
            raise ValueError(f"activation duration must be finite and >= 0, got {duration}")
        self.duration = float(duration)
        self.active = bool(active)
        self._t0 = t
        self._start = 1.0 if active else 0.0

    def value(self, t: float) -> float:
        target = 1.0 if self.active else 0.0
        return self._start + (target - self._start) * activation(t - self._t0, self.duration)

    def update(self, condition: bool, t: float) -> float:
        """Feed the condition (``e_a > 0``, or a point outside the safety area) at time ``t``;
        returns the weight."""
        if bool(condition) != self.active:
            self._start = self.value(t)
            self._t0 = t
            self.active = bool(condition)
        return self.value(t)
