"""Car-like robot kinematics and the ViKi-HyCo kinematic controller (pure numpy).

Source: ViKi-HyCo, ``papers/000_bd93f38cafd5740d.txt`` section II-A, eqs. (1)–(5).

Conventions used throughout:

* world frame: x, y on the ground, z up; yaw ``theta`` counter-clockwise from +x (right-handed);
* robot pose ``(x, y, theta)`` is the **rear-axle midpoint** on the ground, heading along the body x;
* ``v`` is the signed forward speed of the rear-axle midpoint (m/s, ``> 0`` forward),
  ``w`` the yaw rate (rad/s, ``> 0`` counter-clockwise = turning left);
* ``psi`` is the bicycle-model steering angle (rad, ``> 0`` steers left), related to the twist by the
  kinematic bicycle model ``w = v tan(psi) / L`` with ``L`` the wheelbase.

The paper writes one symbol ``d`` both for the control-point distance of eqs. (1)–(4) and for the
wheel base of eq. (5).  Here they are separate: ``d`` is a controller parameter, ``wheelbase`` the
robot's geometry.  With ``d = wheelbase`` (the paper's choice, our default) the control point is the
front-axle midpoint, whose velocity direction is exactly the steering direction ``theta + psi``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from taskflow_robots.racecar_kinematics import require_positive as _positive

from taskflow.spatial import planar_apply

FloatArray = NDArray[np.float64]

# The vehicle's own model (Ackermann hinge angles, electronic differential) is the robot's: it lives in
# taskflow_robots.racecar_kinematics, which the simulated body uses too (sim/ must not import tasks/).


def _pose(pose: ArrayLike) -> FloatArray:
    arr = np.asarray(pose, dtype=np.float64).reshape(-1)
    if arr.shape != (3,):
        raise ValueError(f"pose must be (x, y, theta), got shape {np.shape(pose)}")
    return arr


def wrap_angle(a: float) -> float:
    """Wrap an angle to ``[-pi, pi)``."""
    return float((a + math.pi) % (2.0 * math.pi) - math.pi)


def control_point(pose: ArrayLike, d: float) -> FloatArray:
    """Eq. (1)'s position ``h = [x + d cos(theta), y + d sin(theta)]``.

    The point at distance ``d`` ahead of the rear-axle midpoint along the heading.  Its velocity under
    the unicycle model ``(x_dot, y_dot, theta_dot) = (v cos, v sin, w)`` is eq. (1): ``h_dot = J_b V``.
    """
    return planar_apply(_pose(pose), (_positive("d", d), 0.0))  # h = T_world_body (d, 0)


def car_jacobian_b(theta: float, d: float) -> FloatArray:
    """Eq. (2): ``J_b = [[cos th, -d sin th], [sin th, d cos th]]`` maps ``[v, w]`` to ``h_dot``."""
    d = _positive("d", d)
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -d * s], [s, d * c]])


def car_jacobian_b_inv(theta: float, d: float) -> FloatArray:
    """Inverse of eq. (2): ``J_b^-1 = [[cos th, sin th], [-sin th / d, cos th / d]]`` (``det J_b = d``)."""
    d = _positive("d", d)
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s], [-s / d, c / d]])


def kinematic_control(pose: ArrayLike, target_xy: ArrayLike, k1: ArrayLike, d: float) -> tuple[float, float]:
    """Eq. (4), as meant: ``V_r = J_b^-1 (k1 * tanh(h_d - h))`` → ``(v, w)``.

    ``h`` is the control point of eq. (1) (``d`` ahead of the rear axle) and ``h_d = target_xy``.  The
    paper prints the error as ``h - h_d`` in one place; the sign that drives the robot *toward* the
    target is ``h_err = h_d - h`` (REFERENCE.md §1).  ``k1`` is the paper's diagonal gain ``[k_x, k_y]``
    applied per world-frame component (forward positioning ``[2, 1]``, backward ``[1, 2]``); a scalar
    means the same gain on both axes.  The result is the unconstrained unicycle twist: convert it with
    :func:`car_command` (eq. 5 + limits) before sending it to the car.
    """
    x, y, th = _pose(pose)
    d = _positive("d", d)
    hd = np.asarray(target_xy, dtype=np.float64).reshape(-1)
    if hd.shape != (2,):
        raise ValueError(f"target_xy must be (x, y), got shape {np.shape(target_xy)}")
    gains = np.asarray(k1, dtype=np.float64).reshape(-1)
    if gains.shape == (1,):
        gains = np.repeat(gains, 2)
    if gains.shape != (2,) or not (math.isfinite(gains[0]) and math.isfinite(gains[1])) or min(gains) <= 0:
        raise ValueError(f"k1 must be a positive scalar or pair, got {k1!r}")
    c, s = math.cos(th), math.sin(th)
    h = control_point((x, y, th), d)  # eq. (1)
    hx = float(gains[0]) * math.tanh(float(hd[0]) - float(h[0]))  # eq. (4): k1 tanh(h_d - h)
    hy = float(gains[1]) * math.tanh(float(hd[1]) - float(h[1]))
    v = c * hx + s * hy  # J_b^-1 of eq. (2)
    w = (-s * hx + c * hy) / d
    return float(v), float(w)


def steering_from_twist(v: float, w: float, wheelbase: float, psi_max: float, v_eps: float = 1e-9) -> float:
    """Eq. (5): steering ``psi = atan(L w / v)``, saturated to ``|psi| <= psi_max``.

    ``L`` is the wheelbase.  The sign of ``v`` is kept inside the arctangent so reversing flips the
    steering as the bicycle model requires (``w = v tan(psi) / L``).  For ``|v| < v_eps`` the ratio is
    undefined: a non-zero ``w`` asks for full lock toward it (as if driving forward), ``w = 0`` gives 0.
    """
    wheelbase = _positive("wheelbase", wheelbase)
    psi_max = _positive("psi_max", psi_max)
    if abs(v) < v_eps:
        return float(math.copysign(psi_max, w)) if w != 0.0 else 0.0
    psi = math.atan(wheelbase * w / v)
    return float(min(max(psi, -psi_max), psi_max))


def saturate(v: float, psi: float, v_max: float, psi_max: float) -> tuple[float, float]:
    """Clip ``|v| <= v_max`` and ``|psi| <= psi_max`` independently.

    Clipping the speed at a fixed steering angle keeps the path curvature ``tan(psi)/L``: the car
    follows the same arc, only slower.
    """
    v_max = _positive("v_max", v_max)
    psi_max = _positive("psi_max", psi_max)
    return float(min(max(v, -v_max), v_max)), float(min(max(psi, -psi_max), psi_max))


def car_command(
    v: float, w: float, wheelbase: float, v_max: float, psi_max: float, direction: float = 0.0
) -> tuple[float, float]:
    """Unicycle twist ``(v, w)`` → car command ``(v, psi)``: eq. (5) plus the robot's limits.

    A car cannot turn on the spot: the largest yaw rate at speed ``v`` is ``|v| tan(psi_max) / L``.
    When the twist asks for more (e.g. a target straight to the side gives ``v ≈ 0, w ≠ 0``, where a
    plain eq. (5) would steer to full lock and never move), the speed is raised to the smallest one
    that realises ``w`` at full lock.  Its sign is ``direction`` (the current direction of travel,
    ``±1``) when given, else the sign of ``v`` (forward when ``v = 0``): keeping the direction while
    the speed is raised avoids flipping between forward and reverse every tick when the target is
    beside the control point — the car then makes parallel-parking-like legs, each reversing only once
    the law's own ``v`` exceeds the raised speed.  Then eq. (5) gives ``psi`` and :func:`saturate`
    applies ``v_max`` at constant curvature.  The command vanishes with the twist.
    """
    wheelbase = _positive("wheelbase", wheelbase)
    psi_max = _positive("psi_max", psi_max)
    v_min = abs(w) * wheelbase / math.tan(psi_max)
    if abs(v) < v_min:
        sign = direction if direction != 0.0 else (v if v != 0.0 else 1.0)
        v = math.copysign(v_min, sign)
    psi = steering_from_twist(v, w, wheelbase, psi_max)
    return saturate(v, psi, v_max, psi_max)
