"""Rigid-body transforms: one definition of each, named by the direction it maps.

Naming
------
* ``T_a_b`` is the 4x4 homogeneous transform that maps coordinates in frame ``b`` to frame ``a``,
  ``p_a = T_a_b @ [p_b; 1]``; equivalently the pose of frame ``b`` in frame ``a``.  ``R_a_b`` is its
  rotation (columns: ``b``'s axes in ``a``), ``t_a_b`` its translation (``b``'s origin in ``a``).
  Frames chain by their inner letters: ``T_a_c = T_a_b @ T_b_c``; ``inverse(T_a_b)`` is ``T_b_a``.
  (The papers' ``^aT_b``, ``H_ab``, ``eT_c`` are the same objects.)
* A **twist** is ``[v; w]``, linear part first (the order of the ViKi-HyCo laws, eqs. 20–24, of the
  homography laws, eqs. 5–6, of Corke's and Pinocchio's ``Motion``): ``w`` the angular velocity and
  ``v`` the velocity of the point at the frame's origin, both in that frame's axes.
  :func:`twist_adjoint` ``(T_a_b)`` maps a twist expressed in ``b`` to the same motion expressed in
  ``a``.  The screw-fastening paper writes ``[w; v]``; :data:`TWIST_SWAP` reorders either way.
* Rotations from angles: :func:`rotation_from_rpy` is URDF's fixed-axis roll–pitch–yaw,
  ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (also PyBullet's Euler convention); quaternions are
  ``(x, y, z, w)``, PyBullet's order.
* Camera frames: OpenCV optical (x right, y down, z along the view) on a robot body that is FLU
  (x forward, y left, z up); :data:`R_FLU_OPTICAL` and :func:`R_body_optical`.

Implementation
--------------
Plain numpy (and ``math`` on scalars) on the arrays the laws already hold: no SE3 object is built per
tick.  Each function is the one the paper code used before it was gathered here, operation for
operation, so every shipped mission's records (trace, transitions, summary; seed 0, every perception
mode) stayed the same to the bit.  Two consequences of that: :func:`rotation_from_unit_quaternion` (the
ViKi world's formula) stands beside :func:`rotation_from_quaternion` (Bullet's, equal to
``pybullet.getMatrixFromQuaternion`` to the bit), and the two worlds that invert a rigid transform with
``numpy.linalg.inv`` keep doing so (:func:`inverse`'s closed form differs in the last bits, which the
screw missions' traces showed).  ``tests/unit/framework/test_spatial.py`` checks the twist maps against
Pinocchio's ``SE3.action`` and finite differences of moving frames, the rotations against scipy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from taskflow.planar import as_planar
from taskflow.planar import planar_apply as planar_apply  # re-exported: the planar transforms are this module's too
from taskflow.planar import planar_apply_inverse as planar_apply_inverse
from taskflow.planar import planar_between as planar_between
from taskflow.planar import planar_compose as planar_compose
from taskflow.planar import planar_inverse as planar_inverse
from taskflow.planar import wrap_angle as wrap_angle

Array = NDArray[np.float64]
Floats = Sequence[float] | Array  # a short vector read element by element (PyBullet's tuples)

_EYE3 = np.eye(3)

R_FLU_OPTICAL: Array = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Rotation FLU body (x forward, y left, z up) ← OpenCV optical frame of a camera looking along the
body's x axis: its columns are the optical axes (right = −y, down = −z, view = +x) in the body frame."""

TWIST_SWAP = np.r_[3:6, 0:3]
"""Index that reorders a twist (or the rows of a Jacobian) ``[v; w]`` ↔ ``[w; v]``; its own inverse."""


# -- vectors -------------------------------------------------------------------------------------------


def skew(w: ArrayLike) -> Array:
    """``[w]x``, the skew-symmetric matrix with ``skew(w) @ u == w × u`` (ViKi-HyCo eq. 23)."""
    a = np.asarray(w, dtype=np.float64)
    if a.size != 3:
        raise ValueError(f"skew needs a 3-vector, got shape {a.shape}")
    x, y, z = a.reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def vee(S: ArrayLike) -> Array:
    """Inverse of :func:`skew` on a skew-symmetric matrix: ``(S32, S13, S21)``."""
    s = np.asarray(S, dtype=np.float64)
    return np.array([s[2, 1], s[0, 2], s[1, 0]])


def cross(a: Array, b: Array) -> Array:
    """``a × b`` of two 3-vectors (``numpy.cross`` costs ~10x more for one pair)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


# -- rotations -----------------------------------------------------------------------------------------


def rotation_z(yaw: float) -> Array:
    """``Rz(yaw)``: ``R_parent_child`` of a frame turned by ``yaw`` (rad) about the parent's z axis."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_y(pitch: float) -> Array:
    """``Ry(pitch)``: ``R_parent_child`` of a frame turned by ``pitch`` (rad) about the parent's y axis
    (on an FLU body a positive pitch tilts the child's x axis **down**)."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> Array:
    """URDF's fixed-axis ``rpy``: ``R_parent_child = Rz(yaw) Ry(pitch) Rx(roll)`` (rad)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def rpy_from_rotation(R: Array) -> tuple[float, float, float]:
    """Inverse of :func:`rotation_from_rpy`: ``(roll, pitch, yaw)`` with pitch in [−π/2, π/2]; at
    gimbal lock (|pitch| = π/2) roll is 0 and the rotation about z goes into yaw."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
        yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    else:
        roll = 0.0
        yaw = math.atan2(-float(R[0, 1]), float(R[1, 1]))
    return (roll, pitch, yaw)


def rotation_angle(R: Array) -> float:
    """Angle of a rotation, ``θ = arccos((tr R − 1) / 2)`` in [0, π], the argument clipped to [−1, 1]
    (screw-fastening paper eqs. 11/14/27).  For the angle between two frames pass ``R_a_b.T @ R_a_c``."""
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    return math.acos(min(1.0, max(-1.0, c)))


def rotvec_from_rotation(R: Array) -> Array:
    """The rotation vector ``θ a`` of ``R`` (log map; screw-fastening paper eqs. 27–31).

    ``a = (r32 − r23, r13 − r31, r21 − r12) / (2 sin θ)``; near θ = 0 the ratio ``θ / (2 sin θ)``
    tends to ½, and near θ = π (where the antisymmetric part vanishes) the axis is taken from the
    symmetric part ``(R + Rᵀ)/2 = cos θ I + (1 − cos θ) a aᵀ`` with its sign from the antisymmetric part.
    """
    th = rotation_angle(R)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-6:
        return 0.5 * v  # θ/(2 sin θ) → 1/2
    if th < math.pi - 1e-4:
        return (th / (2.0 * math.sin(th))) * v
    c = math.cos(th)
    S = (0.5 * (R + R.T) - c * _EYE3) / (1.0 - c)
    i = int(np.argmax(np.diag(S)))
    a = S[:, i] / math.sqrt(max(S[i, i], 1e-300))
    a /= np.linalg.norm(a)
    if float(a @ v) < 0.0:
        a = -a
    return th * a


def rotation_from_rotvec(w: Array) -> Array:
    """Rodrigues (exp map): the rotation of the rotation vector ``w`` (angle ``|w|`` about ``w``),
    ``I + (sin θ / θ) [w]x + ((1 − cos θ) / θ²) [w]x²``; below θ = 1e-9 its first order ``I + [w]x``."""
    th = math.sqrt(float(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]))
    K = skew(w)
    if th < 1e-9:
        return _EYE3 + K
    return _EYE3 + (math.sin(th) / th) * K + ((1.0 - math.cos(th)) / (th * th)) * (K @ K)


# -- quaternions (x, y, z, w) --------------------------------------------------------------------------


def rotation_from_quaternion(q: Floats) -> Array:
    """Rotation of a quaternion ``(x, y, z, w)``, normalised on the way (Bullet's ``btMatrix3x3``
    formula: equal to ``pybullet.getMatrixFromQuaternion`` to the bit)."""
    x, y, z, w = (float(v) for v in q)
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return np.array([[1.0 - (yy + zz), xy - wz, xz + wy],
                     [xy + wz, 1.0 - (xx + zz), yz - wx],
                     [xz - wy, yz + wx, 1.0 - (xx + yy)]])


def rotation_from_unit_quaternion(q: Floats) -> Array:
    """Rotation of a quaternion ``(x, y, z, w)`` assumed of unit norm (not normalised):
    ``[[1 − 2(y² + z²), 2(xy − zw), 2(xz + yw)], …]``.  The ViKi world's perception uses this form;
    :func:`rotation_from_quaternion` (Bullet's) differs from it in the last bits, so it is kept to keep
    those runs' records."""
    x, y, z, w = (float(v) for v in q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def quaternion_from_rotation(R: Array) -> list[float]:
    """Quaternion ``[x, y, z, w]`` of a rotation matrix (Shepperd's method: no division by a small
    number whatever the rotation)."""
    m = np.asarray(R, dtype=np.float64)
    tr = np.trace(m)
    if tr > 0.0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    i = int(np.argmax(np.diag(m)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    return q


def quaternion_from_yaw(yaw: float) -> list[float]:
    """Quaternion ``[0, 0, sin(yaw/2), cos(yaw/2)]`` of :func:`rotation_z` ``(yaw)``."""
    return [0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)]


def yaw_from_quaternion(q: Floats) -> float:
    """Heading of the frame's x axis projected on the parent's xy plane, ``atan2(R10, R00)`` — the
    yaw of :func:`rotation_from_rpy`, robust to small roll and pitch."""
    x, y, z, w = (float(v) for v in q)
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + z * w)
    return math.atan2(r10, r00)


# -- homogeneous transforms ----------------------------------------------------------------------------


def transform(R: ArrayLike, t: ArrayLike) -> Array:
    """``T_a_b`` (4x4) from ``R_a_b`` and ``t_a_b`` (screw-fastening paper eq. 1)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def inverse(T_a_b: Array) -> Array:
    """``T_b_a``: the inverse of a rigid transform, ``[Rᵀ, −Rᵀ t]`` (no general matrix inverse)."""
    Rt = T_a_b[:3, :3].T
    out = np.empty((4, 4))
    out[:3, :3] = Rt
    out[:3, 3] = -(Rt @ T_a_b[:3, 3])
    out[3] = (0.0, 0.0, 0.0, 1.0)
    return out


def transform_from_pose(position: ArrayLike, quaternion: Floats) -> Array:
    """``T_parent_frame`` from a PyBullet pose: ``position`` and quaternion ``(x, y, z, w)``."""
    return transform(rotation_from_quaternion(quaternion), position)


def transform_from_xyz_rpy(xyz: ArrayLike, rpy: Floats) -> Array:
    """``T_parent_child`` of a URDF origin: translation ``xyz`` (m), fixed-axis ``rpy`` (rad)."""
    r, p, y = (float(v) for v in rpy)
    return transform(rotation_from_rpy(r, p, y), np.asarray(xyz, dtype=np.float64))


def transform_xyz_yaw(x: float, y: float, z: float, yaw: float) -> Array:
    """``T_parent_body`` of a body at ``(x, y, z)`` turned by ``yaw`` about the parent's z axis (a
    ground robot's ``(x, y, yaw)`` pose, a quadcopter's ``(x, y, z, yaw)``)."""
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = (x, y, z)
    return T


# -- planar poses as 4x4 transforms (the planar maths itself: taskflow.planar) ---------------------------


def T_from_planar(T_a_b: ArrayLike, z: float = 0.0) -> Array:
    """The 4x4 ``T_a_b`` of a planar pose, at height ``z`` (:func:`transform_xyz_yaw`)."""
    x, y, th = as_planar(T_a_b)
    return transform_xyz_yaw(x, y, z, th)


def planar_from_T(T_a_b: ArrayLike) -> Array:
    """The planar pose ``(x, y, yaw)`` of a 4x4 ``T_a_b`` (its z translation, roll and pitch dropped)."""
    R, t = _rt(T_a_b)
    return np.array([float(t[0]), float(t[1]), math.atan2(float(R[1, 0]), float(R[0, 0]))])


# -- twists --------------------------------------------------------------------------------------------


def _rt(T: ArrayLike) -> tuple[Array, Array]:
    a = np.asarray(T, dtype=np.float64)
    if a.shape != (4, 4):
        raise ValueError(f"a rigid transform is a 4x4 matrix, got shape {a.shape}")
    return a[:3, :3], a[:3, 3]


def twist_adjoint(T_a_b: ArrayLike) -> Array:
    """``Ad_a_b`` (6x6): a twist ``[v; w]`` expressed in ``b`` → the same motion expressed in ``a``,
    ``[[R, [t]x R], [0, R]]`` with ``(R, t) = (R_a_b, t_a_b)``: ``w_a = R w_b`` and
    ``v_a = R v_b + t × w_a`` (the velocity of ``a``'s origin, ``−t`` away from ``b``'s)."""
    R, t = _rt(T_a_b)
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[:3, 3:] = skew(t) @ R
    A[3:, 3:] = R
    return A


def twist_adjoint_inverse(T_a_b: ArrayLike) -> Array:
    """``Ad_b_a = twist_adjoint(inverse(T_a_b))`` (6x6) without inverting: a twist ``[v; w]``
    expressed in ``a`` → expressed in ``b``, ``[[Rᵀ, −Rᵀ [t]x], [0, Rᵀ]]``: ``w_b = Rᵀ w_a`` and
    ``v_b = Rᵀ (v_a + w_a × t)`` (the velocity of ``b``'s origin at ``t``)."""
    R, t = _rt(T_a_b)
    Rt = R.T
    A = np.zeros((6, 6))
    A[:3, :3] = Rt
    A[:3, 3:] = -Rt @ skew(t)
    A[3:, 3:] = Rt
    return A


# -- cameras -------------------------------------------------------------------------------------------


def R_body_optical(yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> Array:
    """``R_body_optical`` of an OpenCV camera (x right, y down, z along the view) on an FLU body whose
    camera frame (x along the view, y left, z up) is mounted with URDF ``rpy = (roll, pitch, yaw)``:
    ``rotation_from_rpy(roll, pitch, yaw) @ R_FLU_OPTICAL``.  ``yaw`` turns the view about the body's
    z (π looks backward), a positive ``pitch`` tilts it **down**."""
    return rotation_from_rpy(roll, pitch, yaw) @ R_FLU_OPTICAL
