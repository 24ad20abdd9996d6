"""Car kinematics (ViKi-HyCo eqs. 1–5): Jacobian vs finite differences, steering, Ackermann, differential."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from taskflow_robots.racecar import Racecar
from taskflow_robots.racecar_kinematics import (
    ackermann_wheel_angles,
    bicycle_from_wheel_angles,
    differential_wheel_speeds,
)
from taskflow_tasks.ground.car_goto import CarGains, CarGoto
from taskflow_tasks.ground.car_kinematics import (
    car_command,
    car_jacobian_b,
    car_jacobian_b_inv,
    control_point,
    kinematic_control,
    saturate,
    steering_from_twist,
)

from taskflow.api import Observation
from taskflow.testing import task_context

L, TRACK, R = 0.325, 0.2, 0.05
V_MAX, PSI_MAX = 0.5, 0.44

angles = st.floats(-math.pi, math.pi)
speeds = st.floats(-1.0, 1.0)


def unicycle(pose: np.ndarray, v: float, w: float) -> np.ndarray:
    return np.array([v * math.cos(pose[2]), v * math.sin(pose[2]), w])


@settings(max_examples=50, deadline=None)
@given(theta=angles, v=speeds, w=speeds, d=st.floats(0.05, 1.0))
def test_jacobian_matches_finite_difference_of_control_point(theta, v, w, d):
    pose = np.array([0.3, -1.2, theta])
    eps = 1e-6
    xdot = unicycle(pose, v, w)
    fd = (control_point(pose + eps * xdot, d) - control_point(pose - eps * xdot, d)) / (2 * eps)
    np.testing.assert_allclose(car_jacobian_b(theta, d) @ [v, w], fd, atol=1e-7)
    np.testing.assert_allclose(car_jacobian_b_inv(theta, d) @ car_jacobian_b(theta, d), np.eye(2), atol=1e-12)


def test_control_point_is_d_ahead_along_heading():
    np.testing.assert_allclose(control_point([1.0, 2.0, math.pi / 2], 0.5), [1.0, 2.5], atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(theta=angles, tx=st.floats(-3, 3), ty=st.floats(-3, 3))
def test_kinematic_control_moves_control_point_toward_target(theta, tx, ty):
    pose = np.array([0.0, 0.0, theta])
    k1 = np.array([2.0, 1.0])
    v, w = kinematic_control(pose, [tx, ty], k1, L)
    h_dot = car_jacobian_b(theta, L) @ [v, w]
    err = np.array([tx, ty]) - control_point(pose, L)
    np.testing.assert_allclose(h_dot, k1 * np.tanh(err), atol=1e-12)  # eq. 4 inverts eq. 1 exactly
    assert float(err @ h_dot) >= 0.0


def test_kinematic_control_rejects_bad_input():
    with pytest.raises(ValueError, match="k1"):
        kinematic_control([0, 0, 0], [1, 0], [1.0, -1.0], L)
    with pytest.raises(ValueError, match="d must"):
        kinematic_control([0, 0, 0], [1, 0], [1.0, 1.0], 0.0)
    with pytest.raises(ValueError, match="pose"):
        kinematic_control([0, 0], [1, 0], [1.0, 1.0], L)


def test_steering_eq5_unsaturated_is_bicycle_model():
    for v, psi in [(0.3, 0.2), (-0.3, 0.2), (0.1, -0.4), (-0.2, -0.1)]:
        w = v * math.tan(psi) / L
        assert steering_from_twist(v, w, L, PSI_MAX) == pytest.approx(psi, abs=1e-12)


def test_steering_saturates_and_handles_zero_speed():
    assert steering_from_twist(0.1, 5.0, L, PSI_MAX) == PSI_MAX
    assert steering_from_twist(0.1, -5.0, L, PSI_MAX) == -PSI_MAX
    assert steering_from_twist(-0.1, 5.0, L, PSI_MAX) == -PSI_MAX  # reversing flips the steering
    assert steering_from_twist(0.0, 0.3, L, PSI_MAX) == PSI_MAX
    assert steering_from_twist(0.0, -0.3, L, PSI_MAX) == -PSI_MAX
    assert steering_from_twist(0.0, 0.0, L, PSI_MAX) == 0.0
    assert saturate(0.9, -0.6, V_MAX, PSI_MAX) == (V_MAX, -PSI_MAX)
    assert saturate(-0.2, 0.1, V_MAX, PSI_MAX) == (-0.2, 0.1)


def test_car_command_realises_yaw_rate_and_keeps_curvature():
    # Target straight to the side: v = 0, w != 0 must still move the car, at full lock.
    v, psi = car_command(0.0, 1.0, L, V_MAX, PSI_MAX)
    assert v > 0.0 and psi == PSI_MAX
    # Within the limits eq. 5 is exact.
    v, psi = car_command(0.3, 0.3 * math.tan(0.2) / L, L, V_MAX, PSI_MAX)
    assert (v, psi) == pytest.approx((0.3, 0.2))
    # Speed saturation keeps the curvature tan(psi) / L = w / v.
    v, psi = car_command(2.0, 2.0 * math.tan(0.3) / L, L, V_MAX, PSI_MAX)
    assert v == V_MAX and psi == pytest.approx(0.3)
    # Vanishes with the twist, reverses with v.
    assert car_command(0.0, 0.0, L, V_MAX, PSI_MAX) == (0.0, 0.0)
    v, psi = car_command(-1e-3, 0.5, L, V_MAX, PSI_MAX)
    assert v < 0.0 and psi == -PSI_MAX and abs(v) < 0.5


@pytest.mark.parametrize("psi", [0.05, 0.2, 0.44, -0.3])
def test_ackermann_wheel_axes_meet_at_bicycle_turn_centre(psi):
    left, right = ackermann_wheel_angles(psi, L, TRACK)
    radius = L / math.tan(psi)  # turn centre at (0, radius) on the rear-axle line
    for angle, y in ((left, TRACK / 2), (right, -TRACK / 2)):
        # The wheel axis through (L, y) has direction (-sin a, cos a); it must pass through (0, radius).
        s = -L / -math.sin(angle)
        assert y + s * math.cos(angle) == pytest.approx(radius, rel=1e-9)
    inner, outer = (left, right) if psi > 0 else (right, left)
    assert abs(inner) > abs(psi) > abs(outer)
    assert bicycle_from_wheel_angles(left, right, L, TRACK) == pytest.approx(psi, abs=1e-12)


def test_ackermann_straight_is_zero():
    assert ackermann_wheel_angles(0.0, L, TRACK) == (0.0, 0.0)
    assert bicycle_from_wheel_angles(0.0, 0.0, L, TRACK) == 0.0


@pytest.mark.parametrize("v, psi", [(0.4, 0.3), (0.4, -0.44), (-0.2, 0.2), (0.3, 0.0)])
def test_differential_speeds_follow_turn_radius(v, psi):
    wl, wr = differential_wheel_speeds(v, psi, L, TRACK, R)
    assert (wl + wr) / 2 * R == pytest.approx(v)
    yaw_rate = (wr - wl) * R / TRACK
    assert yaw_rate == pytest.approx(v * math.tan(psi) / L, abs=1e-12)


def test_car_command_keeps_direction_while_speed_is_raised():
    # Target beside the control point, slightly behind: the law asks v < 0, but while the yaw rate
    # needs a raised speed the current direction of travel (forward) is kept.
    v, psi = car_command(-0.01, 0.5, L, V_MAX, PSI_MAX, direction=1.0)
    assert v > 0.0 and psi == PSI_MAX
    v, psi = car_command(-0.01, 0.5, L, V_MAX, PSI_MAX, direction=-1.0)
    assert v < 0.0 and psi == -PSI_MAX
    # Once the law's own speed exceeds the raised one, its sign wins.
    v, _ = car_command(-0.4, 0.1, L, V_MAX, PSI_MAX, direction=1.0)
    assert v == pytest.approx(-0.4)


def bicycle_observations(task, start, seconds: float, dt: float = 0.05):
    """Drive a task on the ideal kinematic bicycle at 1 / dt Hz; return the final pose."""
    x = np.array(start, dtype=float)
    for k in range(round(seconds / dt)):
        result = task.step(Observation(t=k * dt, state={"pose": x.copy(), "v": 0.0, "steer": 0.0}))
        v, psi = float(result.command["v"][0]), float(result.command["steer"][0])
        for _ in range(5):
            x = x + dt / 5 * np.array([v * math.cos(x[2]), v * math.sin(x[2]), v * math.tan(psi) / L])
    return x, result


def test_car_goto_on_ideal_bicycle_converges_in_every_direction():
    """The control point reaches targets 1–3 m away, in any direction, within 1 cm in 15 s."""
    rng = np.random.default_rng(3)
    robot = Racecar(Racecar.Params())
    for k1 in ((2.0, 1.0), (1.0, 2.0)):
        for ang in np.linspace(-math.pi, math.pi, 8, endpoint=False):
            target = control_point([0, 0, 0], L) + rng.uniform(1.0, 3.0) * np.array(
                [math.cos(ang), math.sin(ang)]
            )
            ctx = task_context(CarGoto, CarGoto.Params(target=list(target)), robot, {"gains": CarGains(k1=k1)})
            x, result = bicycle_observations(CarGoto(ctx), (0.0, 0.0, 0.0), 15.0)
            assert np.linalg.norm(control_point(x, L) - target) < 0.01, (k1, ang)
            assert result.metrics["pos_error"] < 0.01


def test_car_goto_validates_its_inputs():
    with pytest.raises(ValidationError):
        CarGains(k1=(1.0, -1.0))
    with pytest.raises(ValidationError):
        CarGains(d=0.0)
    with pytest.raises(ValidationError):
        CarGoto.Params(target=[1.0])
