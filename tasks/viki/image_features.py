"""Image features of a detected bounding box and their interaction matrix.

ViKi-HyCo (Velasco-Sanchez et al., IEEE Access), section II-B, eq. 6-9, and the feature choice of
section II-E.

Conventions
-----------
* Camera frame: OpenCV (x right, y down, z forward along the optical axis).
* Image coordinates ``(u, v)`` in pixels, ``u`` to the right, ``v`` down. A camera is described
  by :class:`CameraIntrinsics` ``(fx, fy, cu, cv)`` (focal lengths and principal point, px). Every
  function that takes ``intrinsics`` also accepts a plain 4-sequence or a 3x3 matrix ``K``.
* Camera twist ``V_c = [v_x, v_y, v_z, w_x, w_y, w_z]``: linear velocity of the camera origin
  and angular velocity of the camera, both expressed in the camera frame, for a camera moving
  through a static scene (the convention of eq. 6 and of Chaumette & Hutchinson).
* A bounding box is ``(u0, v0, u2, v2) = (left, top, right, bottom)`` in pixels.

Features (section II-E)
-----------------------
The paper servoes on the **four corners** of the bounding box, each treated as an image point
(eq. 9 with n = 4), all at the same depth ``Z_o`` (the object depth of eq. 17). The corner names
follow eq. 16, ``bb = {(u1,v1) (u2,v2); (u0,v0) (u3,v3)}`` with ``(u0, v0)`` the minimum and
``(u2, v2)`` the maximum corner, so in image coordinates (v down)::

    p0 = (left, top)     p3 = (right, top)
    p1 = (left, bottom)  p2 = (right, bottom)

and the feature vector is ``f = [u0, v0, u1, v1, u2, v2, u3, v3]`` (absolute pixels).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "CameraIntrinsics",
    "as_bbox",
    "as_intrinsics",
    "point_interaction_matrix",
    "bbox_corners",
    "bbox_features",
    "feature_error",
]


class CameraIntrinsics(NamedTuple):
    """Pinhole intrinsics in pixels: focal lengths ``fx, fy`` and principal point ``(cu, cv)``."""

    fx: float
    fy: float
    cu: float
    cv: float


def as_intrinsics(intrinsics: CameraIntrinsics | ArrayLike) -> CameraIntrinsics:
    """Normalise ``(fx, fy, cu, cv)`` or a 3x3 ``K`` matrix to :class:`CameraIntrinsics`."""
    if isinstance(intrinsics, CameraIntrinsics):
        return intrinsics
    a = np.asarray(intrinsics, dtype=float)
    if a.shape == (3, 3):
        out = CameraIntrinsics(float(a[0, 0]), float(a[1, 1]), float(a[0, 2]), float(a[1, 2]))
    elif a.shape == (4,):
        out = CameraIntrinsics(float(a[0]), float(a[1]), float(a[2]), float(a[3]))
    else:
        raise ValueError(
            f"intrinsics must be (fx, fy, cu, cv) or a 3x3 K matrix, got shape {a.shape}"
        )
    if not (out.fx > 0.0 and out.fy > 0.0):
        raise ValueError(f"focal lengths must be positive, got fx={out.fx}, fy={out.fy}")
    return out


def point_interaction_matrix(
    uv: ArrayLike, Z: float | ArrayLike, fx: float, fy: float | None = None
) -> NDArray[np.float64]:
    """Interaction matrix of image points in pixels, eq. 7 (one point) and eq. 9 (n points).

    ``d/dt [u_i, v_i] = L_i V_c`` with, for ``(u, v)`` measured **relative to the principal
    point** and the camera twist ``V_c`` of the module docstring::

        L_i = [[-fx/Z, 0,     u/Z, u v/fy,       -(fx + u^2/fx),  fx v/fy],
               [0,     -fy/Z, v/Z, fy + v^2/fy,  -u v/fx,         -fy u/fx]]

    With ``fx = fy = l`` this is exactly the paper's eq. 7 (``l`` the focal length in px). It is
    the normalised-coordinate matrix of Chaumette & Hutchinson scaled by ``diag(fx, fy)``.

    Parameters
    ----------
    uv : (n, 2) or (2,) array
        Image points in pixels relative to the principal point.
    Z : float or (n,) array
        Depth of each point along the optical axis (m, > 0). The paper uses the single object
        depth ``Z_o`` of eq. 17 for all four corners.
    fx, fy : float
        Focal lengths in pixels (``fy`` defaults to ``fx``).

    Returns
    -------
    (2n, 6) array: rows ``u_0, v_0, u_1, v_1, ...``.
    """
    if fy is None:
        fy = fx
    if not (fx > 0.0 and fy > 0.0):
        raise ValueError(f"focal lengths must be positive, got fx={fx}, fy={fy}")
    p = np.asarray(uv, dtype=float).reshape(-1, 2)
    u = p[:, 0]
    v = p[:, 1]
    iz: float | NDArray[np.float64]
    if isinstance(Z, (float, int, np.floating, np.integer)):
        if not Z > 0.0:
            raise ValueError(f"depth Z must be positive, got {Z}")
        iz = 1.0 / float(Z)
    else:
        z = np.asarray(Z, dtype=float)
        if not (z > 0.0).all():
            raise ValueError("depth Z must be positive")
        iz = 1.0 / z
    n = p.shape[0]
    uv_ = u * v
    L = np.zeros((n, 2, 6))
    L[:, 0, 0] = -fx * iz
    L[:, 0, 2] = u * iz
    L[:, 0, 3] = uv_ / fy
    L[:, 0, 4] = -fx - u * u / fx
    L[:, 0, 5] = (fx / fy) * v
    L[:, 1, 1] = -fy * iz
    L[:, 1, 2] = v * iz
    L[:, 1, 3] = fy + v * v / fy
    L[:, 1, 4] = -uv_ / fx
    L[:, 1, 5] = (-fy / fx) * u
    return L.reshape(2 * n, 6)


def bbox_corners(bbox: ArrayLike) -> NDArray[np.float64]:
    """The four corner points of a box ``(u0, v0, u2, v2)`` as a (4, 2) array, order of eq. 16.

    ``p0 = (left, top)``, ``p1 = (left, bottom)``, ``p2 = (right, bottom)``, ``p3 = (right, top)``.
    """
    u0, v0, u2, v2 = as_bbox(bbox)
    return np.array([[u0, v0], [u0, v2], [u2, v2], [u2, v0]])


def as_bbox(bbox: ArrayLike, name: str = "bbox") -> tuple[float, float, float, float]:
    """``bbox`` as the floats ``(u0, v0, u2, v2)``, checked: four edges with ``u0 <= u2`` and ``v0 <= v2``
    (``name`` is the argument the error message names)."""
    b = np.asarray(bbox, dtype=float)
    if b.shape != (4,):
        raise ValueError(f"{name} must be (u0, v0, u2, v2), got shape {b.shape}")
    u0, v0, u2, v2 = b.tolist()
    if not (u0 <= u2 and v0 <= v2):
        raise ValueError(f"{name} must satisfy u0 <= u2 and v0 <= v2, got {(u0, v0, u2, v2)}")
    return u0, v0, u2, v2


def bbox_features(bbox: ArrayLike) -> NDArray[np.float64]:
    """Feature vector ``f = [u0, v0, u1, v1, u2, v2, u3, v3]`` (px) of section II-E: the corners."""
    u0, v0, u2, v2 = as_bbox(bbox)
    return np.array([u0, v0, u0, v2, u2, v2, u2, v0])


def feature_error(f: ArrayLike, f_d: ArrayLike) -> float:
    """Feature error used by the mission's transition test, in pixels.

    Section III-E ends a visual-servo state when ``-2 < (f - f_d) < 2`` px, i.e. every component
    of the error is within the band. We therefore define the scalar error as the **max absolute
    component** ``max_i |f_i - f_d,i|`` (infinity norm), so ``feature_error(f, f_d) < 2`` is the
    paper's test exactly.
    """
    a = np.asarray(f, dtype=float)
    b = np.asarray(f_d, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"f and f_d must have the same shape, got {a.shape} and {b.shape}")
    if a.size == 0:
        raise ValueError("empty feature vector")
    return float(np.max(np.abs(a - b)))
