"""ViKi-HyCo geometry around the pure laws: object localisation (eq. 18), desired centre, kinematic target.

Pure numpy.  The control laws themselves live in :mod:`taskflow_tasks.car_visual_servo` (eq. 20–24),
:mod:`taskflow_tasks.bbox_target` (eq. 19), :mod:`taskflow_tasks.core.hybrid` (eq. 25–26) and :mod:`taskflow_tasks.ground.car_kinematics`
(eq. 1–5); :func:`viki_velocity` chains them for one control tick.

Frames: robot frame = rear-axle midpoint on the ground, x forward, y left, z up; camera frame = OpenCV
optical frame; ``T_robot_camera`` (4x4) = robot ← camera (``CameraMount.T_body_camera()``).  Odometry pose
``(x, y, theta)`` of the rear-axle midpoint.

Where the desired features come from (as meant, not printed in the paper)
---------------------------------------------------------------------------
The paper places the desired box centre ``(O_du, O_dv)`` by hand and reads ``Z_d`` in the depth image at
that pixel (eq. 19).  Here a mission gives the **desired object position in the robot frame** (the
manipulation zone, e.g. 0.9 m behind the rear axle) and the desired centre is derived from it with only
what the detection measures — the object's size stays unknown, as in ViKi-HyCo:

* eq. 18 gives the 3-D point ``P`` on the object's visible surface along the box-centre ray, at depth
  ``Z_o`` (eq. 17); its height ``z_c`` is measured;
* the object's half-width seen by the camera, ``r = w_o Z_o / (2 f_x)``, is the horizontal offset from
  that surface point to the object's vertical axis (exact for an upright cylinder, close for a box);
  the object's base centre is ``B = P_xy + r u`` with ``u`` the horizontal viewing direction;
* the desired centre is the projection of the point that ``P`` would be if ``B`` were at the goal
  ``G``: ``(G - r u_G, z_c)``.  At the equilibrium ``f = f_d`` the measured ``B`` equals ``G``.

``Z_d`` is still read every frame in the depth image at that pixel (eq. 19 as printed); until the
object covers the pixel it is the floor's depth there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_tasks.bbox_target import desired_bbox, static_desired_bbox
from taskflow_tasks.car_visual_servo import car_vs_velocity
from taskflow_tasks.core.hybrid import hybrid_velocity, smooth_velocity
from taskflow_tasks.ground.car_kinematics import car_command, kinematic_control
from taskflow_tasks.image_features import bbox_features, feature_error

FloatArray = NDArray[np.float64]

__all__ = [
    "object_point",
    "object_base",
    "desired_centre",
    "goal_heading",
    "kinematic_target",
    "mgbm_depth",
    "reverse_control",
    "saturate_twist",
    "ServoInputs",
    "ServoOutput",
    "viki_velocity",
]


def _T(T_robot_camera: ArrayLike) -> FloatArray:
    T = np.asarray(T_robot_camera, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"T_robot_camera must be a 4x4 transform, got shape {T.shape}")
    return T


def object_point(bbox: ArrayLike, Z_o: float, intrinsics: ArrayLike, T_robot_camera: ArrayLike) -> FloatArray:
    """Eq. 18 in the robot frame: ``T_robot_camera @ [(O_u - c_u) Z_o / f_x, (O_v - c_v) Z_o / f_y, Z_o]``."""
    fx, fy, cu, cv = (float(v) for v in np.asarray(intrinsics, dtype=float).reshape(4))
    b = np.asarray(bbox, dtype=float).reshape(4)
    if not Z_o > 0.0:
        raise ValueError(f"Z_o must be positive, got {Z_o}")
    ou, ov = 0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])
    Pc = np.array([(ou - cu) * Z_o / fx, (ov - cv) * Z_o / fy, Z_o])
    T = _T(T_robot_camera)
    return T[:3, :3] @ Pc + T[:3, 3]


def object_base(bbox: ArrayLike, Z_o: float, intrinsics: ArrayLike, T_robot_camera: ArrayLike) -> tuple[FloatArray, float, float]:
    """Object base centre ``B`` (robot frame, m), half-width ``r`` (m) and measured height ``z_c`` (m).

    ``B = P_xy + r u`` (module docstring): ``P`` from eq. 18, ``r = w_o Z_o / (2 f_x)``, ``u`` the unit
    horizontal direction from the camera to ``P``.
    """
    P = object_point(bbox, Z_o, intrinsics, T_robot_camera)
    b = np.asarray(bbox, dtype=float).reshape(4)
    fx = float(np.asarray(intrinsics, dtype=float).reshape(4)[0])
    r = 0.5 * (b[2] - b[0]) * Z_o / fx
    cam = _T(T_robot_camera)[:2, 3]
    u = P[:2] - cam
    n = float(np.hypot(u[0], u[1]))
    u = u / n if n > 1e-9 else np.zeros(2)
    return P[:2] + r * u, float(r), float(P[2])


def desired_centre(goal_xy: ArrayLike, r: float, z_c: float, intrinsics: ArrayLike, T_robot_camera: ArrayLike) -> FloatArray:
    """Pixel ``(u, v)`` where the box centre is when the object's base centre is at ``goal_xy``.

    Projection of ``(G - r u_G, z_c)`` (module docstring).  Raises ``ValueError`` when that point is
    behind the camera (a goal the camera cannot see).
    """
    G = np.asarray(goal_xy, dtype=float).reshape(2)
    T = _T(T_robot_camera)
    cam = T[:2, 3]
    u = G - cam
    n = float(np.hypot(u[0], u[1]))
    u = u / n if n > 1e-9 else np.zeros(2)
    P = np.array([*(G - r * u), z_c])
    Pc = T[:3, :3].T @ (P - T[:3, 3])
    if Pc[2] <= 1e-6:
        raise ValueError(f"goal {tuple(G)} is behind the camera")
    fx, fy, cu, cv = (float(v) for v in np.asarray(intrinsics, dtype=float).reshape(4))
    return np.array([fx * Pc[0] / Pc[2] + cu, fy * Pc[1] / Pc[2] + cv])


def goal_heading(pose: ArrayLike, object_xy: ArrayLike, goal_xy: ArrayLike) -> float:
    """Heading at which the object, seen from ``pose``'s position, lies in the goal's direction.

    ``atan2(O - p) - atan2(g_y, g_x)``: straight at the object for a goal ahead, facing away for a goal
    behind.  The heading the car ends with when it drives straight to the goal pose.
    """
    x, y, _ = (float(v) for v in np.asarray(pose, dtype=float).reshape(3))
    O = np.asarray(object_xy, dtype=float).reshape(2)
    g = np.asarray(goal_xy, dtype=float).reshape(2)
    return math.atan2(O[1] - y, O[0] - x) - math.atan2(g[1], g[0])


def kinematic_target(object_xy: ArrayLike, goal_xy: ArrayLike, theta_f: float, d: float) -> FloatArray:
    """Control-point target ``h_d`` of eq. 4 (odometry frame) for the goal pose.

    The robot pose with heading ``theta_f`` that puts the object (odometry ``object_xy``) at ``goal_xy``
    in the robot frame is ``p = O - R(theta_f) g``; its control point (eq. 1) is ``p + d [cos, sin]``.
    A negative ``d`` gives the point behind the rear axle that :func:`reverse_control` servoes.
    """
    O = np.asarray(object_xy, dtype=float).reshape(2)
    g = np.asarray(goal_xy, dtype=float).reshape(2)
    c, s = math.cos(theta_f), math.sin(theta_f)
    p = O - np.array([c * g[0] - s * g[1], s * g[0] + c * g[1]])
    return p + d * np.array([c, s])


def reverse_control(pose: ArrayLike, target: ArrayLike, k1: ArrayLike, d: float) -> tuple[float, float]:
    """Eq. 4 for a car driving backwards: eq. 4 on the car seen backwards (heading + pi), speed negated.

    The controlled point is then ``d`` *behind* the rear axle, the leading point when reversing.  With
    the point ``d`` ahead (plain eq. 4) a reversing car's heading is unstable — ``dtheta/dt = u sin(e)/d``
    grows the misalignment ``e`` — and the car jack-knifes; with the point behind it is stable.  This is
    the paper's "backward kinematic controller" (section III-A, ``k1 = [1, 2]``).
    """
    x, y, th = (float(v) for v in np.asarray(pose, dtype=float).reshape(3))
    v, w = kinematic_control(np.array([x, y, th + math.pi]), target, k1, d)
    return -v, w


def mgbm_depth(bbox: ArrayLike, desired: ArrayLike, Z_d: float) -> float:
    """MGBM-YOLO's depth from box areas: ``Z = Z_d sqrt(A_d / A)`` (the object's size known in advance)."""
    b = np.asarray(bbox, dtype=float).reshape(4)
    dd = np.asarray(desired, dtype=float).reshape(4)
    a = max((b[2] - b[0]) * (b[3] - b[1]), 1e-9)
    ad = max((dd[2] - dd[0]) * (dd[3] - dd[1]), 1e-9)
    return float(Z_d * math.sqrt(ad / a))


def saturate_twist(V: ArrayLike, v_max: float, w_max: float) -> FloatArray:
    """Scale ``[v, w]`` into ``|v| <= v_max``, ``|w| <= w_max`` keeping its direction (the path curvature).

    Section II-A saturates the controller's velocities to the robot's ranges; it is applied *before*
    eq. 26, whose damping factor ``1 - |V_n - V_{n-1}|`` only makes sense for velocities within them (an
    unsaturated eq. 24 output of 2.8 m/s at a far object would be held at 0 by eq. 26 forever).
    ``w_max = v_max tan(psi_max) / L``: the largest yaw rate the car reaches at full speed.
    """
    v, w = (float(x) for x in np.asarray(V, dtype=float).reshape(2))
    s = 1.0
    if abs(v) > v_max:
        s = v_max / abs(v)
    if abs(w) * s > w_max:
        s = w_max / abs(w)
    return np.array([v * s, w * s])


@dataclass
class ServoInputs:
    """One tick's inputs to :func:`viki_velocity` (everything already in arrays)."""

    pose: FloatArray  # odometry (x, y, theta)
    detected: bool
    bbox: FloatArray | None = None  # (u0, v0, u2, v2) px
    Z_o: float | None = None  # eq. 17
    Z_d: float | None = None  # eq. 19: depth at the desired centre (ViKi) or desired depth (MGBM)
    centre: FloatArray | None = None  # desired box centre (px)
    target: FloatArray | None = None  # kinematic control-point target h_d (odometry), eq. 4
    reverse: bool = False  # the fallback drives backwards (point d behind the rear axle, reverse_control)
    v_prev: FloatArray | None = None  # previous output for eq. 26


@dataclass
class ServoOutput:
    V: FloatArray  # [v, w] after eq. 25–26
    v_cmd: float  # eq. 5 + limits
    psi: float
    f: FloatArray | None
    f_d: FloatArray | None
    feature_error: float | None
    used_vs: bool


def viki_velocity(inp: ServoInputs, *, intrinsics: ArrayLike, T_robot_camera: ArrayLike, lam: ArrayLike, k1: ArrayLike,
                  d: float, wheelbase: float, v_max: float, psi_max: float, mode: str = "hybrid",
                  object_size: ArrayLike | None = None, smoothing: bool = True, direction: float = 0.0) -> ServoOutput:
    """One ViKi-HyCo control tick, eq. 19–26 then eq. 5.

    * ``mode="hybrid"``: eq. 19 desired box (size ``k = Z_o / Z_d`` times the current one), eq. 24 on the
      four corners with depth ``Z_o``; eq. 25: that law when detected, else the kinematic controller of
      eq. 4 toward ``inp.target`` (zero when there is no target yet) — driving forward with the point
      ``d`` ahead, or with ``inp.reverse`` backward with the point ``d`` behind (:func:`reverse_control`);
    * ``mode="vs_only"``: the same visual law, zero velocity without a detection (the paper's VS-only
      baseline, section III-B);
    * ``mode="mgbm"``: MGBM-YOLO baseline — static desired box of the known ``object_size`` (W, H) at
      depth ``Z_d`` (:func:`taskflow_tasks.bbox_target.static_desired_bbox`), interaction-matrix depth from the
      box areas (:func:`mgbm_depth`), zero velocity without a detection.

    Eq. 26 (as meant, :func:`taskflow_tasks.core.hybrid.smooth_velocity`) damps the change from ``inp.v_prev``.
    """
    T = _T(T_robot_camera)
    R_rc, t_rc = T[:3, :3], T[:3, 3]
    f = f_d = None
    err = None
    V_vs = None
    bbox, Z_o, Z_d, centre = inp.bbox, inp.Z_o, inp.Z_d, inp.centre
    use_vs = False
    if inp.detected and bbox is not None and Z_o is not None and Z_d is not None and centre is not None:
        use_vs = True
        if mode == "mgbm":
            if object_size is None:
                raise ValueError("mode 'mgbm' needs object_size (W, H)")
            box_d = static_desired_bbox(object_size, Z_d, intrinsics, centre)
            Z = mgbm_depth(bbox, box_d, Z_d)
        else:
            box_d = desired_bbox(bbox, Z_o, Z_d, centre)  # eq. 19
            Z = Z_o
        f = bbox_features(bbox)
        f_d = bbox_features(box_d)
        err = feature_error(f, f_d)
        V_vs = car_vs_velocity(f, f_d, Z, intrinsics, R_rc, t_rc, lam)  # eq. 24
    if mode == "hybrid":
        V_kin = None
        if inp.target is not None and not use_vs:  # eq. 25 selects one law: compute only that one
            law = reverse_control if inp.reverse else kinematic_control
            V_kin = np.array(law(inp.pose, inp.target, k1, d))  # eq. 4 (forward or backward)
        if use_vs or V_kin is not None:
            V = hybrid_velocity(V_vs, V_kin, use_vs)  # eq. 25 (as meant)
        else:
            V = np.zeros(2)
    elif mode in ("vs_only", "mgbm"):
        V = V_vs if V_vs is not None else np.zeros(2)
    else:
        raise ValueError(f"mode must be 'hybrid', 'vs_only' or 'mgbm', got {mode!r}")
    V = saturate_twist(V, v_max, v_max * math.tan(psi_max) / wheelbase)
    if smoothing:
        prev = np.zeros(2) if inp.v_prev is None else np.asarray(inp.v_prev, dtype=float)
        V = smooth_velocity(V, prev)  # eq. 26 (as meant)
    v_cmd, psi = car_command(float(V[0]), float(V[1]), wheelbase, v_max, psi_max, direction)  # eq. 5
    return ServoOutput(np.asarray(V, dtype=float), v_cmd, psi, f, f_d, err, use_vs)
