"""The racecar's kinematic model: Ackermann steering and the electronic differential of its rear wheels.

The bicycle model (ViKi-HyCo section II-A) seen from the vehicle: a bicycle steering angle ``psi`` is
realised by two hinge angles whose wheel axes meet at one centre of rotation, and the rear wheels turn
at the speeds that centre implies.  The simulated body (``taskflow_sim.ground.racecar_body``) drives its joints
with these functions; the control laws (``taskflow_tasks.ground.car_kinematics``) use the same bicycle model
from the other side (twist → steering).  Pure ``math``; robot geometry in, angles and speeds out.
"""

from __future__ import annotations

import math


def require_positive(name: str, value: float) -> float:
    """``value`` as a float, refused (``ValueError``) unless finite and > 0."""
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return value


_positive = require_positive


def ackermann_wheel_angles(psi: float, wheelbase: float, track: float) -> tuple[float, float]:
    """Left and right steering-hinge angles ``(psi_left, psi_right)`` for the bicycle angle ``psi``.

    Ackermann geometry: every wheel axis passes through the instantaneous centre of rotation on the
    rear-axle line at ``R = L / tan(psi)`` (left of the car when ``psi > 0``).  A hinge at lateral
    offset ``y = ±track/2`` steers ``atan(L / (R - y))``, i.e.
    ``tan(psi_i) = L tan(psi) / (L - y tan(psi))``.  For ``psi > 0`` the left wheel is the inner
    (larger) angle; both are 0 for ``psi = 0``.
    """
    wheelbase = _positive("wheelbase", wheelbase)
    track = _positive("track", track)
    t = math.tan(psi)
    half = 0.5 * track
    left = math.atan2(wheelbase * t, wheelbase - half * t)
    right = math.atan2(wheelbase * t, wheelbase + half * t)
    return float(left), float(right)


def bicycle_from_wheel_angles(psi_left: float, psi_right: float, wheelbase: float, track: float) -> float:
    """Inverse of :func:`ackermann_wheel_angles`: ``cot(psi) = (cot(psi_l) + cot(psi_r)) / 2``."""
    _positive("wheelbase", wheelbase)
    _positive("track", track)
    tl, tr = math.tan(psi_left), math.tan(psi_right)
    if tl + tr == 0.0:
        return 0.0
    return float(math.atan(2.0 * tl * tr / (tl + tr)))


def differential_wheel_speeds(
    v: float, psi: float, wheelbase: float, track: float, radius: float
) -> tuple[float, float]:
    """Rear wheel angular speeds ``(omega_left, omega_right)`` in rad/s (electronic differential).

    Rear wheels at ``y = ±track/2`` move at ``v (1 ∓ track tan(psi) / (2 L))`` around the centre of
    rotation, so the yaw rate is ``v tan(psi) / L`` without the wheels fighting each other; divided by
    the wheel radius.  Positive is rolling forward.
    """
    wheelbase = _positive("wheelbase", wheelbase)
    track = _positive("track", track)
    radius = _positive("radius", radius)
    k = 0.5 * track * math.tan(psi) / wheelbase
    return float(v * (1.0 - k) / radius), float(v * (1.0 + k) / radius)
