"""Pinhole intrinsics of the simulated cameras (PyBullet's TinyRenderer), one definition for every robot.

TinyRenderer renders with a vertical field of view ``fovy``: ``fx = fy = H / (2 tan(fovy / 2))``, and puts
the principal point at ``(W / 2, H / 2 − 1)`` (measured, SIMULATOR_NOTES.md).  The robots' camera
parameter classes (``racecar.CameraMount``, ``quadcopter.QuadCamera``, ``mobile_iiwa.CameraParams``) keep
their own fields (their YAML names and defaults differ) and take their intrinsics from here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray


def focal_px(height: int, fovy: float) -> float:
    """Focal length in pixels of an image ``height`` px tall with vertical field of view ``fovy`` (rad)."""
    return height / (2.0 * math.tan(0.5 * fovy))


def tinyrenderer_intrinsics(width: int, height: int, fovy: float) -> tuple[float, float, float, float]:
    """``(fx, fy, cu, cv)`` of a ``width x height`` TinyRenderer image with vertical field of view ``fovy``."""
    f = focal_px(height, fovy)
    return (f, f, 0.5 * width, 0.5 * height - 1.0)


def tinyrenderer_K(width: int, height: int, fovy: float) -> NDArray[np.float64]:
    """The 3x3 intrinsic matrix of :func:`tinyrenderer_intrinsics`."""
    f, _, cu, cv = tinyrenderer_intrinsics(width, height, fovy)
    return np.array([[f, 0.0, cu], [0.0, f, cv], [0.0, 0.0, 1.0]])
