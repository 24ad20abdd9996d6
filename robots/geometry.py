"""Rigid-body helpers shared by robot descriptions and control laws (pure numpy)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rpy_matrix(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """URDF / fixed-axis convention ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def skew(w: ArrayLike) -> NDArray[np.float64]:
    """``[w]x``, the skew-symmetric matrix with ``skew(w) @ u == w × u`` (ViKi-HyCo eq. 23)."""
    a = np.asarray(w, dtype=np.float64)
    if a.size != 3:
        raise ValueError(f"skew needs a 3-vector, got shape {a.shape}")
    x, y, z = a.reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
