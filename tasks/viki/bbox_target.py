"""Desired bounding box: ViKi-HyCo eq. 19 and the MGBM-YOLO static baseline.

Boxes are ``(u0, v0, u2, v2) = (left, top, right, bottom)`` in pixels; the desired centre
``(O_du, O_dv)`` is in absolute pixels. Turn a box into the servo features with
``taskflow_tasks.viki.image_features.bbox_features``.

Eq. 19 (section II-E)::

    u_d = O_du -/+ w_d / 2,   v_d = O_dv -/+ h_d / 2,   w_d = w_o k,   h_d = h_o k,
    k = Z_o / Z_d

``w_o, h_o`` are the width and height of the *current* detected box, ``Z_o`` the current object
depth (eq. 17) and ``Z_d`` the depth read each iteration in the depth image at the desired centre
pixel. A fronto-parallel object of size ``W`` at depth ``Z_o`` projects to ``w_o = fx W / Z_o``;
at depth ``Z_d`` it would project to ``fx W / Z_d = w_o Z_o / Z_d``, so eq. 19 is the box the
object would have at the desired depth, without knowing ``W``. Recomputed every frame, the
desired box follows the current box's shape (the difference from MGBM-YOLO, whose desired box is
fixed from a known object size: :func:`static_desired_bbox`).

Quantisation: ``w_o`` carries the detector's pixel rounding, scaled by ``k`` (SIMULATOR_NOTES,
Vision): an object 8 px wide leaves ~1/8 relative size error, i.e. a depth error of ~Z/8 px.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.viki.image_features import CameraIntrinsics, as_bbox, as_intrinsics

__all__ = ["desired_bbox", "static_desired_bbox"]


def _centre(desired_centre: ArrayLike) -> tuple[float, float]:
    c = np.asarray(desired_centre, dtype=float)
    if c.shape != (2,):
        raise ValueError(f"desired_centre must be (u, v), got shape {c.shape}")
    cu, cv = c.tolist()
    return cu, cv


def desired_bbox(
    current_bbox: ArrayLike, Z_o: float, Z_d: float, desired_centre: ArrayLike
) -> NDArray[np.float64]:
    """Eq. 19: desired box ``(u0, v0, u2, v2)`` of size ``k (w_o, h_o)``, ``k = Z_o / Z_d``,
    centred at ``desired_centre``. Call it every frame with the current box and depths."""
    if not (Z_o > 0.0 and Z_d > 0.0):
        raise ValueError(f"depths must be positive, got Z_o={Z_o}, Z_d={Z_d}")
    u0, v0, u2, v2 = as_bbox(current_bbox, "current_bbox")
    k = Z_o / Z_d
    hw = 0.5 * k * (u2 - u0)
    hh = 0.5 * k * (v2 - v0)
    cu, cv = _centre(desired_centre)
    return np.array([cu - hw, cv - hh, cu + hw, cv + hh])


def static_desired_bbox(
    object_size_m: ArrayLike,
    Z_d: float,
    intrinsics: CameraIntrinsics | ArrayLike,
    desired_centre: ArrayLike,
) -> NDArray[np.float64]:
    """MGBM-YOLO baseline: fixed desired box of an object of known size at the desired depth.

    ``object_size_m = (W, H)`` is the object's extent (m) facing the camera; the box is
    ``(fx W / Z_d) x (fy H / Z_d)`` px centred at ``desired_centre``. It does not follow the
    detected box's shape, which is why the baseline never settles when the apparent shape differs
    (section III-D).
    """
    s = np.asarray(object_size_m, dtype=float)
    if s.shape != (2,) or np.any(s <= 0.0):
        raise ValueError(f"object_size_m must be a positive (W, H), got {object_size_m!r}")
    if not Z_d > 0.0:
        raise ValueError(f"Z_d must be positive, got {Z_d}")
    K = as_intrinsics(intrinsics)
    hw = 0.5 * K.fx * s[0] / Z_d
    hh = 0.5 * K.fy * s[1] / Z_d
    cu, cv = _centre(desired_centre)
    return np.array([cu - hw, cv - hh, cu + hw, cv + hh])
