"""Tests for taskflow_tasks.core.hybrid (ViKi-HyCo eq. 25 as meant, eq. 26 as meant)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from taskflow_tasks.core.hybrid import hybrid_velocity, smooth_velocity


def test_hybrid_uses_visual_servo_when_detected():
    vs, kin = [0.3, -0.1], [0.1, 0.2]
    np.testing.assert_array_equal(hybrid_velocity(vs, kin, detected=True), vs)
    np.testing.assert_array_equal(hybrid_velocity(vs, kin, detected=False), kin)
    np.testing.assert_array_equal(hybrid_velocity(None, kin, detected=False), kin)
    np.testing.assert_array_equal(hybrid_velocity(vs, None, detected=True), vs)


def test_hybrid_needs_the_selected_branch():
    with pytest.raises(ValueError):
        hybrid_velocity(None, [0.1, 0.2], detected=True)
    with pytest.raises(ValueError):
        hybrid_velocity([0.1, 0.2], None, detected=False)


def test_smooth_by_hand():
    np.testing.assert_allclose(smooth_velocity([0.3, -0.2], [0.3, -0.2]), [0.3, -0.2])  # steady
    np.testing.assert_allclose(smooth_velocity([0.4, 0.5], [0.2, 0.0]), [0.8 * 0.4, 0.5 * 0.5])
    np.testing.assert_allclose(smooth_velocity([0.5, -0.6], [-0.5, 0.6]), [0.0, 0.0])  # jump >= 1


def test_smooth_does_not_amplify_where_the_printed_eq26_does():
    v_new, v_prev = np.array([0.2]), np.array([0.5])
    printed = (1.0 - (v_new - v_prev)) * v_new  # factor 1.3
    assert printed[0] > v_new[0]
    assert smooth_velocity(v_new, v_prev)[0] == pytest.approx(0.7 * 0.2)


def test_smooth_settles_on_a_constant_command():
    v = np.zeros(2)
    for _ in range(200):
        v = smooth_velocity([0.45, -0.3], v)
    np.testing.assert_allclose(v, [0.45, -0.3], atol=1e-6)


vel = st.floats(-5.0, 5.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(vel, vel), min_size=1, max_size=6))
def test_smooth_never_amplifies_and_never_flips_sign(pairs):
    v_new = np.array([p[0] for p in pairs])
    v_prev = np.array([p[1] for p in pairs])
    out = smooth_velocity(v_new, v_prev)
    assert np.all(np.abs(out) <= np.abs(v_new))
    assert np.all(out * v_new >= 0.0)


def test_smooth_rejects_mismatched_shapes():
    with pytest.raises(ValueError):
        smooth_velocity([0.1, 0.2], [0.1])
