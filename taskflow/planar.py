"""Planar rigid transforms ``T_a_b = (x, y, yaw)``: frame b's origin and heading in frame a (odometry is
``T_odom_base``), named by direction like :mod:`taskflow.spatial`, which re-exports them.

The expressions are the paper code's inline ones, in its order (so a caller that switched to them kept its
records to the bit); one pose turns by ``math.cos``/``math.sin``, an ``(N, 3)`` stack by numpy's.  One pose
and one point (the common case, once per physics step in the wheeled bodies) take a float path that does
the same operations without numpy's stacking.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def wrap_angle(a: float) -> float:
    """An angle (rad) wrapped to ``[-pi, pi]`` by IEEE remainder (``pi`` and ``-pi`` both possible at the edge)."""
    return math.remainder(a, 2.0 * math.pi)


def _one_pose_one_point(T: ArrayLike, p: ArrayLike) -> tuple[float, float, float, float, float, float] | None:
    """``(x, y, cos yaw, sin yaw, px, py)`` in floats when ``T`` is one pose and ``p`` one point, else None."""
    t, q = np.asarray(T, dtype=np.float64), np.asarray(p, dtype=np.float64)
    if t.shape != (3,) or q.shape != (2,):
        return None
    x, y, th = t.tolist()
    px, py = q.tolist()
    return x, y, math.cos(th), math.sin(th), px, py


def as_planar(T_a_b: ArrayLike) -> tuple[float, float, float]:
    """One planar pose ``(x, y, yaw)`` as floats (a ValueError for any other shape)."""
    a = np.asarray(T_a_b, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"a planar pose is (x, y, yaw), got shape {a.shape}")
    return float(a[0]), float(a[1]), float(a[2])


def _planar_turn(T_a_b: ArrayLike) -> tuple[float | Array, float | Array, float | Array, float | Array]:
    """``(x, y, cos yaw, sin yaw)`` of one pose ``(3,)`` (floats) or of a stack ``(N, 3)`` (columns)."""
    a = np.asarray(T_a_b, dtype=np.float64)
    if a.ndim == 1:
        x, y, th = as_planar(a)
        return x, y, math.cos(th), math.sin(th)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"planar poses are (x, y, yaw) rows, got shape {a.shape}")
    return a[:, 0], a[:, 1], np.cos(a[:, 2]), np.sin(a[:, 2])


def _points(p: ArrayLike) -> tuple[Array, Array]:
    a = np.asarray(p, dtype=np.float64)
    if a.shape[-1:] != (2,) or a.ndim > 2:
        raise ValueError(f"planar points are (x, y) or (N, 2) rows, got shape {a.shape}")
    return a[..., 0], a[..., 1]


def planar_apply(T_a_b: ArrayLike, p_b: ArrayLike) -> Array:
    """``p_a``: points ``p_b`` (``(2,)`` or ``(N, 2)``) expressed in ``a``,
    ``(x + c px - s py, y + s px + c py)``; ``T_a_b`` one pose or ``(N, 3)`` poses (broadcast)."""
    one = _one_pose_one_point(T_a_b, p_b)
    if one is not None:
        fx, fy, fc, fs, fpx, fpy = one
        return np.array([fx + fc * fpx - fs * fpy, fy + fs * fpx + fc * fpy])
    x, y, c, s = _planar_turn(T_a_b)
    px, py = _points(p_b)
    return np.stack([x + c * px - s * py, y + s * px + c * py], axis=-1)


def planar_apply_inverse(T_a_b: ArrayLike, p_a: ArrayLike) -> Array:
    """``p_b``: points ``p_a`` expressed in ``b`` (``planar_apply(planar_inverse(T_a_b), p_a)`` without
    inverting), ``(c dx + s dy, -s dx + c dy)`` with ``(dx, dy) = p_a - (x, y)``."""
    one = _one_pose_one_point(T_a_b, p_a)
    if one is not None:
        fx, fy, fc, fs, fpx, fpy = one
        fdx, fdy = fpx - fx, fpy - fy
        return np.array([fc * fdx + fs * fdy, -fs * fdx + fc * fdy])
    x, y, c, s = _planar_turn(T_a_b)
    px, py = _points(p_a)
    dx, dy = px - x, py - y
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def planar_compose(T_a_b: ArrayLike, T_b_c: ArrayLike, *, wrap: bool = True) -> Array:
    """``T_a_c = T_a_b ∘ T_b_c``; the yaw ``yaw_a_b + yaw_b_c`` wrapped by :func:`wrap_angle` unless
    ``wrap=False`` (for a caller that integrates an unwrapped heading)."""
    x, y, th = as_planar(T_a_b)
    u, v, ph = as_planar(T_b_c)
    c, s = math.cos(th), math.sin(th)
    yaw = th + ph
    return np.array([x + c * u - s * v, y + s * u + c * v, wrap_angle(yaw) if wrap else yaw])


def planar_inverse(T_a_b: ArrayLike) -> Array:
    """``T_b_a``: ``(-c x - s y, s x - c y, -yaw)``."""
    x, y, th = as_planar(T_a_b)
    c, s = math.cos(th), math.sin(th)
    return np.array([-c * x - s * y, s * x - c * y, wrap_angle(-th)])


def planar_between(T_w_a: ArrayLike, T_w_b: ArrayLike) -> Array:
    """``T_a_b`` from two poses in one frame ``w`` (``planar_inverse(T_w_a) ∘ T_w_b`` without
    inverting): ``b``'s offset turned into ``a``'s axes, the yaw difference wrapped."""
    x, y, th = as_planar(T_w_a)
    u, v, ph = as_planar(T_w_b)
    c, s = math.cos(th), math.sin(th)
    dx, dy = u - x, v - y
    return np.array([c * dx + s * dy, -s * dx + c * dy, wrap_angle(ph - th)])
