"""Six-axis PID with anti-windup (eqs. 15-18, 33, 36) and its profile model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_tasks.core.pid import PidGains, PidProfile, PidState, pid_step


def test_proportional_integral_derivative_terms():
    g = PidGains.of(kp=2.0, ki=0.5, kd=0.1)
    e = np.array([0.1, 0, 0, 1.0, -1.0, 0])
    u, s = pid_step(e, PidState(), g, 0.01)
    np.testing.assert_allclose(u, 2.0 * e + 0.5 * e * 0.01)  # no derivative on the first tick
    u2, s2 = pid_step(e * 2, s, g, 0.01)
    assert np.all(np.abs(u2[e != 0]) > np.abs(u[e != 0]))
    np.testing.assert_allclose(s2.integral, 3 * e * 0.01)


def test_state_is_not_mutated():
    s = PidState()
    pid_step(np.ones(6), s, PidGains.of(1, 1, 1), 0.1)
    assert np.all(s.integral == 0) and s.last_error is None


def test_anti_windup_stops_integrating_while_saturated_and_recovers_fast():
    g = PidGains.of(kp=1.0, ki=5.0, u_max=0.5)
    s = PidState()
    for _ in range(1000):  # 10 s of a large error that saturates the output
        u, s = pid_step(np.full(6, 2.0), s, g, 0.01)
    assert np.all(u == 0.5)
    assert np.all(np.abs(s.integral) < 0.05)  # without anti-windup it would be 20
    # error flips: the output leaves saturation within a few ticks
    for _ in range(5):
        u, s = pid_step(np.full(6, -0.2), s, g, 0.01)
    assert np.all(u < 0)


def test_integral_clamp():
    g = PidGains.of(kp=0.0, ki=1.0, i_limit=0.3)
    s = PidState()
    for _ in range(100):
        _, s = pid_step(np.ones(6), s, g, 0.1)
    np.testing.assert_allclose(s.integral, 0.3)


def test_pi_tracks_a_ramp_without_steady_state_error():
    """A target moving at constant speed (the conveyor): the integral removes the lag."""
    g = PidGains.of(kp=2.0, ki=1.0)
    s, x, dt = PidState(), 0.0, 0.01
    for k in range(3000):
        target = 0.05 * k * dt
        u, s = pid_step(np.full(6, target - x), s, g, dt)
        x += u[3] * dt
    assert abs(0.05 * 3000 * dt - x) < 1e-4


@pytest.mark.parametrize("bad", [{"kp": [1, 2, 3]}, {"kp": 1.0}, {"kp": [1] * 7}, {"kp": [1] * 5 + [-1]},
                                 {"kp": [1] * 6, "u_max": [0] * 6}, {"kp": [1] * 6, "ki": [1, 1]},
                                 {"kp": [1] * 5 + [math.nan]}, {"kp": [1] * 6, "d_tau": -1}])
def test_profile_rejects_wrong_gain_counts_and_signs(bad):
    with pytest.raises(ValidationError) as exc:
        PidProfile.model_validate(bad)
    assert "6" in str(exc.value) or ">" in str(exc.value) or "finite" in str(exc.value)


def test_profile_is_kind_pid_and_converts():
    p = PidProfile.model_validate({"kp": [1, 2, 3, 4, 5, 6], "u_max": [1, 1, 1, 0.5, 0.5, 0.5]})
    assert PidProfile.kind == "pid"
    g = p.arrays()
    np.testing.assert_allclose(g.kp, [1, 2, 3, 4, 5, 6])
    assert np.all(np.isinf(g.i_limit)) and np.all(g.ki == 0)
