"""Position-based visual servoing of a mobile manipulator — the pure laws of the screw-fastening paper
(González Huarte & Iburguren 2024, ``papers/002_60116b0236aed3a6.txt``).

Frames (paper section 4): ``b`` platform base, ``a`` arm base, ``c`` camera (OpenCV optical frame),
``e`` end effector (screwdriver tip), ``o`` object (the ArUco marker), ``t`` operation pose on the
object.  ``T_xy`` (the paper's ``H_xy``, :mod:`taskflow.spatial`'s ``T_a_b``) is the 4x4 pose of frame ``y``
in frame ``x``; the camera mount ``T_bc`` is the robot's ``T_body_camera``.  A twist or error vector is
``[ω; v]`` (angular first, section 4), expressed in the platform base frame unless said otherwise.

Functions take and return numpy arrays; nothing here keeps state or imports a simulator.

Equations and how they are read where the paper is ambiguous or misprinted (REFERENCE.md §2):

* (9)–(14) transition tests: translation norm ``< ε_t`` and angle ``arccos((tr R − 1)/2) ≤ ε_r``
  (:func:`pose_error_norms`).  Eq. (10) ``T_cc* = T*_co T_co⁻¹`` and eq. (13) ``T_be* = T*_be T_be⁻¹``:
  the norms of a transform and of its inverse agree, so the tests do not depend on the order.
* (10) as used by the control law: the camera must move to where it sees the object at ``T*_co``;
  the desired camera pose in the current camera frame is ``T_cc* = T_co T*_co⁻¹`` (the printed
  product is its inverse, which would drive the platform away).
* (13) as used by the control law: the error of the tool point is ``p*_be − p_be`` and its rotation
  ``log(R*_be R_beᵀ)``, both in the base frame — the printed product's translation would also
  contain the rotation error times the tool's lever arm.
* (25) ``T_bEo = diag(R_bc, 1) · E_co`` as printed multiplies the error's rotation by ``R_bc``, which
  changes its angle; as meant the error is *expressed* in the base frame: the rotation vector and
  the translation are each rotated by ``R_bc`` (= conjugating the rotation, ``R_bc R_E R_bcᵀ``).
* (27)–(31) angle-axis; implemented robustly near 0 and π (the printed formulas divide by sin θ).
* (34) ``V_be = [ω_b; v_b + r × ω_b]``: the velocity the platform twist gives the tool point, with
  ``r`` pointing from the tool to the base (``r = −p_be``), i.e. ``v_b + ω_b × p_be``
  (:func:`platform_induced_twist`; checked against a finite difference in the tests).
* (35) ``E' = E − V_be dt`` in vector form (:func:`compensate_error`).  It assumes the target stands
  still in the world: on a part moving at ``v`` the arm's PI settles where ``E − V_be dt = 0``, i.e.
  with the tool ``v dt`` behind the bolt (0.8 mm at 80 mm/s and 100 Hz, 2 mm at the paper's 40 Hz).
  With the part's motion estimated (prediction), the compensation subtracts the platform's motion
  *relative to the target*, ``E' = E − (V_be − V_t) dt`` (``V_t`` from :func:`target_twist`).
* (37), (40): ``J⁺`` is a damped least-squares inverse ``Jᵀ (J Jᵀ + λ² I)⁻¹`` (:func:`dls_solve`),
  cheaper than ``numpy.linalg.pinv`` and bounded near singularities.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg.lapack import dposv as _dposv

from taskflow.spatial import cross, inverse, rotation_angle, rotvec_from_rotation

Array = NDArray[np.float64]

_EYE6 = np.eye(6)


# The SE(3) helpers of eqs. (1), (11), (14), (27)–(31) are :mod:`taskflow.spatial`'s: ``transform``
# (eq. 1), ``inverse``, ``rotation_angle`` (eqs. 11/14/27: θ = arccos((tr R − 1)/2)), ``rotvec_from_rotation``
# (eqs. 27–31), ``rotation_from_rotvec``, ``cross``.


def pose_error_norms(E: Array) -> tuple[float, float]:
    """Eqs. (9)–(14): translation norm ``|p|`` (m) and rotation angle ``|θ|`` (rad) of an error transform."""
    p = E[:3, 3]
    return math.sqrt(float(p @ p)), rotation_angle(E[:3, :3])


def within(E: Array, eps_t: float, eps_r: float) -> bool:
    """Eqs. (9)/(12): advance when ``|p| < ε_t`` and ``|θ| ≤ ε_r``."""
    t, r = pose_error_norms(E)
    return t < eps_t and r <= eps_r


# -- camera error and platform twist, eqs. (10), (25)–(33) ---------------------------------------------------


def camera_error(T_co: Array, T_co_star: Array) -> Array:
    """Eq. (10) as meant: ``E_co = T_cc* = T_co · T*_co⁻¹`` — the desired camera pose in the current
    camera frame (its translation is where the camera must go, its rotation how it must turn)."""
    return T_co @ inverse(T_co_star)


def camera_error_vector(E_co: Array, R_body_camera: Array) -> Array:
    """Eqs. (25)–(32): ``L_Eo = [ω; v]`` of the camera error expressed in the base frame.

    ``ω = R_bc · θa(R_E)`` (eqs. 27–31) and ``v = R_bc p_E`` (eq. 32), ``R_bc`` the rotation of the
    camera mount: eq. (25) read as a change of frame (see the module docstring).
    """
    out = np.empty(6)
    out[:3] = R_body_camera @ rotvec_from_rotation(E_co[:3, :3])
    out[3:] = R_body_camera @ E_co[:3, 3]
    return out


def platform_twist_controller(V_b: Array, v_max: float, w_max: float) -> Array:
    """Section 7.3 for an omnidirectional platform: keep the planar part ``(v_x, v_y, ω_z)`` of the
    6-D twist and saturate it (speed norm ≤ ``v_max``, |ω_z| ≤ ``w_max``) keeping its direction."""
    vx, vy, wz = float(V_b[3]), float(V_b[4]), float(V_b[2])
    s = math.hypot(vx, vy)
    if s > v_max:
        vx, vy = vx * v_max / s, vy * v_max / s
    wz = max(-w_max, min(w_max, wz))
    return np.array([vx, vy, wz])


def planar_twist(cmd: Array) -> Array:
    """A platform command ``(v_x, v_y, ω_z)`` as a 6-D twist ``[ω; v]`` in the base frame."""
    return np.array([0.0, 0.0, float(cmd[2]), float(cmd[0]), float(cmd[1]), 0.0])


# -- end-effector error, compensation and arm twist, eqs. (13), (21)–(23), (34)–(37), (40) ----------------------


def ee_setpoint(T_body_camera: Array, T_co: Array, T_ot: Array, T_tp: Array | None = None) -> Array:
    """Eqs. (21)–(23): ``T*_be = T_bc · T_co · T*_ot_i [· T_tp]`` (``T_bc`` = ``T_body_camera``)."""
    T = T_body_camera @ T_co @ T_ot
    return T @ T_tp if T_tp is not None else T


def ee_error_vector(T_be: Array, T_be_star: Array) -> Array:
    """Eq. (13) as meant: ``L_Ee = [log(R* Rᵀ); p* − p]`` in the base frame (the tool point's error)."""
    out = np.empty(6)
    out[:3] = rotvec_from_rotation(T_be_star[:3, :3] @ T_be[:3, :3].T)
    out[3:] = T_be_star[:3, 3] - T_be[:3, 3]
    return out


def error_norms(L: Array) -> tuple[float, float]:
    """Translation norm and rotation angle of an error vector ``[θa; p]`` (eqs. 12–14)."""
    return math.sqrt(float(L[3] ** 2 + L[4] ** 2 + L[5] ** 2)), math.sqrt(float(L[0] ** 2 + L[1] ** 2 + L[2] ** 2))


def platform_induced_twist(V_b: Array, p_be: Array) -> Array:
    """Eq. (34): the twist the platform's motion ``V_b = [ω_b; v_b]`` gives the tool point at ``p_be``:
    ``V_be = [ω_b; v_b + ω_b × p_be]`` (the paper's ``r × ω_b`` with ``r = −p_be``)."""
    w = V_b[:3]
    out = np.empty(6)
    out[:3] = w
    out[3:] = V_b[3:] + cross(w, p_be)
    return out


def compensate_error(L_E: Array, V_be: Array, dt: float, V_t: Array | None = None) -> Array:
    """Eq. (35): ``E' = E − V_be dt`` — the part of the tool error the platform removes this tick.

    ``V_t`` (beyond the paper): the target point's own twist (base-frame axes, world motion), when
    the part's motion is estimated; the platform then removes only ``(V_be − V_t) dt`` of the error,
    and a target moving with the platform leaves no steady ``V_be dt`` offset."""
    if V_t is None:
        return L_E - V_be * dt
    return L_E - (V_be - V_t) * dt


def dls_solve(J: Array, V: Array, damping: float) -> Array:
    """``J⁺ V`` with the damped least-squares inverse ``Jᵀ (J Jᵀ + λ² I)⁻¹`` (λ = ``damping``)."""
    A = J @ J.T
    if damping > 0.0:
        A = A + (damping * damping) * _EYE6
    x: Array
    _, x, info = _dposv(A, V)  # Cholesky solve: J Jᵀ + λ² I is symmetric positive definite
    if info != 0:  # singular without damping: fall back to least squares
        y = np.linalg.lstsq(A, V, rcond=None)[0]
        return J.T @ y.astype(np.float64, copy=False)  # already float64: no copy
    return J.T @ x


def arm_twist_step(q: Array, J: Array, V_a: Array, dt: float, damping: float) -> Array:
    """Eq. (37): ``q* = q + J⁺(q) V_a dt`` (``J`` in the same ``[ω; v]`` order as ``V_a``)."""
    return q + dls_solve(J, V_a * dt, damping)


def impedance_joint_offset(J_star: Array, dX: Array, damping: float) -> Array:
    """Eq. (40) without the nominal: ``J⁺(q*) ΔX`` (``ΔX`` a 6-D displacement ``[δθ; δp]``)."""
    return dls_solve(J_star, dX, damping)


# -- velocity feed-forward (beyond the paper) ------------------------------------------------------------------


def fit_velocity(t: Array, x: Array, order: int = 1) -> tuple[Array, Array]:
    """Least-squares polynomial of ``order`` (1: a line, 2: a parabola — constant acceleration) through
    samples ``x[k]`` (rows) at times ``t[k]``: ``(value at t[-1], slope at t[-1])``.  A line's slope is
    the mean velocity over the samples (the velocity at their mean time, so it lags a changing one by
    half the window); the parabola's slope at ``t[-1]`` does not lag, at the cost of more noise.  With
    fewer than ``order + 1`` distinct samples the order drops.

    The paper names prediction as the fix for its irregular-motion failures; the part's velocity
    estimated this way is fed forward into both twists when the ``prediction`` profile enables it.
    """
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if len(t) < 2:
        return (x[-1].copy() if len(x) else np.zeros(x.shape[1:])), np.zeros(x.shape[1:])
    tc = t - t.mean()
    den = float(tc @ tc)
    if den <= 0.0:
        return x[-1].copy(), np.zeros(x.shape[1:])
    if order >= 2 and len(t) >= 4:
        A = np.stack([np.ones_like(tc), tc, tc * tc], axis=1)
        coef, _, rank, _ = np.linalg.lstsq(A, x, rcond=None)
        if rank == 3:
            u = tc[-1]
            return coef[0] + coef[1] * u + coef[2] * u * u, coef[1] + 2.0 * coef[2] * u
    slope = tc @ (x - x.mean(axis=0)) / den
    return x.mean(axis=0) + slope * (t[-1] - t.mean()), slope


def platform_feedforward(v_o: Array, w_o: Array, p_bo: Array) -> Array:
    """The platform twist that moves the base rigidly with the part (world velocity ``v_o`` of its
    origin and angular velocity ``w_o``, both in the base frame; ``p_bo`` its origin in the base
    frame): ``[w_o; v_o − w_o × p_bo]``."""
    ff = np.empty(6)
    ff[:3] = w_o
    ff[3:] = v_o - cross(w_o, p_bo)
    return ff


def target_twist(v_o: Array, w_o: Array, p_bo: Array, p_bt: Array) -> Array:
    """The world twist of the target point ``p_bt`` riding on the part (part origin ``p_bo`` moving at
    ``v_o``, turning at ``w_o``; base-frame axes): ``[w_o; v_o + w_o × (p_bt − p_bo)]``."""
    v_t = np.empty(6)
    v_t[:3] = w_o
    v_t[3:] = v_o + cross(w_o, p_bt - p_bo)
    return v_t


def arm_feedforward(v_o: Array, w_o: Array, p_bo: Array, p_bt: Array, V_b: Array) -> Array:
    """The extra arm twist for the target's motion relative to the moving base: the target point's
    twist (:func:`target_twist`) minus what the platform twist ``V_b`` already gives it (eq. 34)."""
    return target_twist(v_o, w_o, p_bo, p_bt) - platform_induced_twist(V_b, p_bt)


def object_feedforward(v_o: Array, w_o: Array, p_bo: Array, p_bt: Array, V_b: Array) -> tuple[Array, Array]:
    """Both feed-forward twists: ``(platform_feedforward, arm_feedforward)`` (beyond the paper: the
    prediction it names as the fix for its irregular-motion failures)."""
    return platform_feedforward(v_o, w_o, p_bo), arm_feedforward(v_o, w_o, p_bo, p_bt, V_b)
