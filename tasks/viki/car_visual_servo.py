"""Image-based visual servoing of a car-like robot: ViKi-HyCo eq. 10 and eq. 20-24.

Conventions
-----------
* Robot frame: x forward, y left, z up, origin at the rear-axle centre on the ground. The robot
  command is ``V_r = [v, w]``: linear speed along robot x (m/s) and yaw rate about robot z (rad/s,
  positive = turning left).
* Camera frame: OpenCV (x right, y down, z optical axis). The camera mount is given as the
  camera pose in the robot frame, ``R_body_camera = ^rR_c`` (columns: camera axes in robot coordinates)
  and ``t_body_camera = ^rt_c`` (camera origin in robot coordinates, m).
* Twists are ``[linear; angular]`` (6-vectors). A *robot twist* is the body velocity of the car
  expressed in robot axes, linear part = velocity of the robot origin. A *camera twist* ``V_c``
  is the camera's own body velocity in camera axes, linear part = velocity of the camera origin:
  the ``V_c`` of eq. 6-10 (camera moving through a static scene).
* Features ``f`` are the four bounding-box corners (``taskflow_tasks.viki.image_features.bbox_features``) in
  absolute pixels; ``f_d`` the desired corners of eq. 19.

As-meant readings (see also /work/shared/REFERENCE.md section 1)
----------------------------------------------------------------
* Eq. 10 and 24 write the error as ``\\dot f``; it is ``f - f_d`` (the paper says so below eq. 9).
* Eq. 21 (``J_r``) is printed as a 3x3 matrix containing the world heading ``theta_r``, with
  "1"s padding it to the 6-D twist. As meant it maps ``[v, w]`` to the 6-D robot twist in the
  **robot** frame (the camera twist of eq. 20 does not depend on the world heading):
  ``J_r = [e_x, e_z-angular]`` i.e. ``[v, 0, 0, 0, 0, w]``. With a reference point ``d`` ahead
  of the rear axle (eq. 1 at ``theta = 0``) the linear part becomes ``[v, d w, 0]``; see
  :func:`car_jacobian_r`.
* Eq. 22 as printed, ``[[R, [t]x R], [0, R]]`` with ``(^rR_c, ^rt_c)``, is the adjoint that maps
  a *camera* twist to the *robot* twist (``^rW_c``). Eq. 20 needs the opposite direction
  (robot twist -> camera twist), ``^cW_r = (^rW_c)^-1 = [[R^T, -R^T [t]x], [0, R^T]]``, which
  is eq. 22's form evaluated with the inverse transform ``(^cR_r, ^ct_r) = (R^T, -R^T t)``.
  :func:`taskflow.spatial.twist_adjoint_inverse` ``(T_body_camera)`` returns that matrix (the
  framework's one twist map, named by its direction); the tests check it against the numerical
  derivative of the camera pose of a car driven with the unicycle model.
* The gains ``lambda`` (section III-A: front ``[0.85, 0.3, 1, 1, 1]``, rear
  ``[0.85, 1.05, 1, 1, 1]``): eq. 24 multiplies ``lambda`` with the 2-vector
  ``(L_f T J_r)^+ (f - f_d) = [v, w]``, so only two gains can act in it. We read the first two
  numbers as ``diag(lambda_v, lambda_w)`` on ``[v, w]`` and the remaining three (1.0 in both
  published sets) as having no counterpart in the 2-DoF law (they are accepted and ignored).
  This reading is not stated in the paper; it is the one under which the published sets make
  sense (same speed gain for both cameras, a higher yaw gain for the rear camera that looks at
  the ground close behind the car) and under which the law is a descent law: with
  ``A = L_f T J_r`` and ``y = A^+ e``, the ideal loop gives ``dy/dt = -diag(lambda_v,
  lambda_w) y``, each robot-velocity component decaying at its own rate.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.viki.image_features import (
    CameraIntrinsics,
    as_intrinsics,
    point_interaction_matrix,
)

__all__ = [
    "car_jacobian_r",
    "car_feature_jacobian",
    "car_vs_velocity",
    "camera_vs_velocity",
    "car_gains",
]


def _check_mount(
    R_body_camera: ArrayLike, t_body_camera: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    R = np.asarray(R_body_camera, dtype=float)
    t = np.asarray(t_body_camera, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"R_body_camera must be 3x3, got shape {R.shape}")
    if t.shape != (3,):
        raise ValueError(f"t_body_camera must be a 3-vector, got shape {t.shape}")
    return R, t


def car_jacobian_r(d: float = 0.0) -> NDArray[np.float64]:
    """6x2 ``J_r`` of eq. 21 (as meant): ``[v, w]`` -> 6-D robot twist in the robot frame.

    The twist's linear part is the velocity of the body point ``(d, 0, 0)`` (robot frame):
    ``[v, d w, 0]``, angular part ``[0, 0, w]``. This is eq. 1-2 at ``theta_r = 0`` extended to
    6-D. Use ``d = 0`` (default) with ``taskflow.spatial.twist_adjoint_inverse(T_body_camera)`` of a mount measured from the
    robot origin; for ``d != 0`` pass ``t_body_camera - [d, 0, 0]`` (the mount relative to the point),
    which gives the same camera twist.
    """
    J = np.zeros((6, 2))
    J[0, 0] = 1.0
    J[1, 1] = float(d)
    J[5, 1] = 1.0
    return J


def _gains(lam: float | ArrayLike) -> tuple[float, float]:
    if isinstance(lam, (float, int, np.floating, np.integer)):
        gv = gw = float(lam)
    else:
        a = np.asarray(lam, dtype=float)
        if a.ndim == 0:
            gv = gw = float(a)
        elif a.shape in ((2,), (5,)):
            gv, gw = float(a[0]), float(a[1])
        else:
            raise ValueError(
                f"lam must be a scalar, [lambda_v, lambda_w] or the paper's 5-vector, got {a.shape}"
            )
    if not (0.0 <= gv < np.inf and 0.0 <= gw < np.inf):
        raise ValueError(f"gains must be finite and non-negative, got {(gv, gw)}")
    return gv, gw


def car_gains(lam: float | ArrayLike) -> NDArray[np.float64]:
    """Gains ``[lambda_v, lambda_w]`` for eq. 24 from a scalar, a pair, or the paper's 5-vector.

    A 5-vector ``[lambda_v, lambda_w, *rest]`` is the paper's format (section III-A); ``rest``
    has no counterpart in the 2-DoF law and is ignored (module docstring).
    """
    return np.array(_gains(lam))


def _feature_points(f: ArrayLike, K: CameraIntrinsics) -> NDArray[np.float64]:
    p = np.asarray(f, dtype=float).reshape(-1, 2)
    return p - (K.cu, K.cv)


def car_feature_jacobian(
    f: ArrayLike,
    Z: float | ArrayLike,
    intrinsics: CameraIntrinsics | ArrayLike,
    R_body_camera: ArrayLike,
    t_body_camera: ArrayLike,
) -> NDArray[np.float64]:
    """``A = L_f T_r^c J_r`` of eq. 20: (2n, 2) map from ``[v, w]`` to feature velocities (px/s)."""
    K = as_intrinsics(intrinsics)
    R, t = _check_mount(R_body_camera, t_body_camera)
    L = point_interaction_matrix(_feature_points(f, K), Z, K.fx, K.fy)
    # T J_r, T = taskflow.spatial.twist_adjoint_inverse(T_body_camera) (robot twist -> camera twist),
    # keeps columns 0 (v along robot x) and 5 (w about robot z) of T; written out:
    # v -> camera twist [R^T e_x; 0], w -> [-R^T (t x e_z); R^T e_z].
    TJ = np.zeros((6, 2))
    TJ[:3, 0] = R[0]  # R^T e_x
    TJ[:3, 1] = t[0] * R[1] - t[1] * R[0]  # -R^T (t x e_z), t x e_z = (t_y, -t_x, 0)
    TJ[3:, 1] = R[2]  # R^T e_z
    return L @ TJ


def car_vs_velocity(
    f: ArrayLike,
    f_d: ArrayLike,
    Z: float | ArrayLike,
    intrinsics: CameraIntrinsics | ArrayLike,
    R_body_camera: ArrayLike,
    t_body_camera: ArrayLike,
    lam: float | ArrayLike,
) -> NDArray[np.float64]:
    """Car visual-servo law, eq. 24: ``V_r = -diag(lambda_v, lambda_w) (L_f T_r^c J_r)^+ (f-f_d)``.

    Parameters
    ----------
    f, f_d : (2n,) or (n, 2)
        Current and desired feature points in absolute pixels (the four box corners).
    Z : float or (n,)
        Depth of the features (m); the paper uses the object depth ``Z_o`` of eq. 17 for all.
    intrinsics : (fx, fy, cu, cv) or 3x3 K
    R_body_camera, t_body_camera :
        Pose of the camera in the robot frame (front camera for forward positioning, rear
        camera for backward positioning).
    lam :
        Scalar, ``[lambda_v, lambda_w]`` or the paper's 5-vector (see :func:`car_gains`).

    Returns
    -------
    ``[v, w]`` (m/s, rad/s). Not saturated: limits belong to the caller (eq. 5).

    The pseudo-inverse of the (2n x 2) matrix is computed by the normal equations (2x2 solve),
    with a minimum-norm least-squares fallback when the matrix is rank-deficient.
    """
    gv, gw = _gains(lam)
    fa = np.asarray(f, dtype=float).reshape(-1)
    fd = np.asarray(f_d, dtype=float).reshape(-1)
    if fa.shape != fd.shape:
        raise ValueError(f"f and f_d must have the same size, got {fa.size} and {fd.size}")
    e = fa - fd
    A = car_feature_jacobian(fa, Z, intrinsics, R_body_camera, t_body_camera)
    At = A.T
    (a, b), (_, c) = (At @ A).tolist()
    p, q = (At @ e).tolist()
    det = a * c - b * b
    if det > 1e-12 * a * c:
        return np.array([-gv * (c * p - b * q) / det, -gw * (a * q - b * p) / det])
    x = np.linalg.lstsq(A, e, rcond=None)[0]  # rank-deficient: minimum-norm solution
    return np.array([-gv * x[0], -gw * x[1]])


def camera_vs_velocity(
    f: ArrayLike,
    f_d: ArrayLike,
    Z: float | ArrayLike,
    intrinsics: CameraIntrinsics | ArrayLike,
    lam: float | ArrayLike,
) -> NDArray[np.float64]:
    """Classic IBVS law, eq. 10: camera twist ``V_c = -lambda L_f^+ (f - f_d)``.

    ``lam`` is a scalar or a 6-vector of per-component gains on ``V_c``. Returns the 6-D camera
    twist ``[v_x, v_y, v_z, w_x, w_y, w_z]`` in the camera frame (m/s, rad/s). ``L_f^+`` is the
    minimum-norm least-squares solution (equal to the pseudo-inverse).
    """
    K = as_intrinsics(intrinsics)
    fa = np.asarray(f, dtype=float).reshape(-1)
    fd = np.asarray(f_d, dtype=float).reshape(-1)
    if fa.shape != fd.shape:
        raise ValueError(f"f and f_d must have the same size, got {fa.size} and {fd.size}")
    e = fa - fd
    L = point_interaction_matrix(_feature_points(fa, K), Z, K.fx, K.fy)
    g = np.asarray(lam, dtype=float)
    if g.shape not in ((), (6,)):
        raise ValueError(f"lam must be a scalar or a 6-vector, got shape {g.shape}")
    if np.any(g < 0.0):
        raise ValueError("gains must be non-negative")
    twist: NDArray[np.float64] = -g * np.linalg.lstsq(L, e, rcond=None)[0]
    return twist
