"""Collision avoidance, visibility and the strict hierarchy (eqs. 8–20), and h_t (eqs. 28–29)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from taskflow_tasks.quad.hierarchy import (
    Activation,
    activation,
    collision_error,
    collision_jacobian,
    hierarchical_control,
    pinv,
    point_interaction,
    points_outside,
    transition_weight,
    visibility_error,
    visibility_jacobian,
)

from taskflow.execution.blends import blend_weight


def project(X, v, w, dt):
    """Normalised coordinates of camera-frame points X after the camera moves with twist (v, w)."""
    Xn = X - dt * (v + np.cross(w, X))  # X' = X - (v + w x X) dt
    return Xn[:, :2] / Xn[:, 2:3]


def test_point_interaction_matches_finite_differences():
    X = np.array([[0.3, -0.2, 2.0]])
    x, y = X[0, :2] / X[0, 2]
    L = point_interaction(x, y, X[0, 2])
    rng = np.random.default_rng(0)
    for _ in range(5):
        nu = rng.normal(size=6)
        dt = 1e-6
        xd = (project(X, nu[:3], nu[3:], dt)[0] - [x, y]) / dt
        assert np.allclose(L @ nu, xd, atol=1e-4)


def test_collision_error_and_jacobian_eq_8_9():
    # a 10 cm wide column 1 m ahead, edges at mid height
    X = np.array([[-0.05, 0.0, 1.0], [0.05, 0.0, 1.0]])
    p = X[:, :2] / X[:, 2:3]
    assert collision_error(p[0], p[1], 0.05) == pytest.approx(0.1 - 0.05)
    Ja = collision_jacobian(p[0], p[1], 1.0, 1.0)
    assert Ja.shape == (1, 6)
    rng = np.random.default_rng(1)
    for _ in range(5):
        nu = rng.normal(size=6)
        dt = 1e-6
        q = project(X, nu[:3], nu[3:], dt)
        de = (collision_error(q[0], q[1], 0.05) - collision_error(p[0], p[1], 0.05)) / dt
        assert (Ja @ nu).item() == pytest.approx(de, abs=1e-4)
    # moving backward (camera -z) shrinks the obstacle: e_a decreases
    assert (Ja @ [0, 0, -1.0, 0, 0, 0]).item() < 0
    with pytest.raises(ValueError):
        collision_jacobian(p[0], p[0], 1.0, 1.0)


def test_visibility_error_and_jacobian_eq_10_12():
    pts = np.array([[0.1, 0.2], [0.3, -0.1], [-0.1, 0.0]])
    e = visibility_error(pts, [0.0, 0.0])
    assert np.allclose(e, pts.mean(axis=0))
    assert np.allclose(visibility_jacobian(e, 2.0), point_interaction(e[0], e[1], 2.0))
    assert points_outside([[10, 10], [300, 100]], (20, 20, 300, 220))
    assert not points_outside([[30, 30], [290, 200]], (20, 20, 300, 220))


def _random_problem(seed):
    rng = np.random.default_rng(seed)
    Ja = rng.normal(size=(1, 6))
    Jm = rng.normal(size=(2, 6))
    Jv = np.eye(6) + 0.1 * rng.normal(size=(6, 6))
    return Ja, rng.normal(size=1), Jm, rng.normal(size=2), Jv, rng.normal(size=6)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), ha=st.floats(0, 1), hm=st.floats(0, 1))
def test_lower_tasks_leave_the_higher_error_rate_unchanged(seed, ha, hm):
    """Null-space property: the collision task's error rate Ĵ_a ν is ė_a^i whatever the lower
    tasks ask, and the visibility task's is ė_m^i whatever the visual task asks."""
    Ja, ea, Jm, em, Jv, ev = _random_problem(seed)
    r = hierarchical_control(Ja, ea, Jm, em, Jv, ev, 0.5, 0.2, 1.3, ha, hm)
    assert np.allclose(Ja @ r.nu, r.de_a, atol=1e-8)
    assert np.allclose(Jm @ r.nu, r.de_m, atol=1e-8)  # Ĵ_m N_a has full row rank here
    assert np.allclose(Ja @ (r.nu_m + r.nu_v), 0.0, atol=1e-8)
    assert np.allclose(Jm @ r.nu_v, 0.0, atol=1e-8)
    # a different visual error changes nothing the two upper tasks see ... when their own
    # intermediate values do not depend on it (h_a = h_m = 1)
    r1 = hierarchical_control(Ja, ea, Jm, em, Jv, ev, 0.5, 0.2, 1.3, 1.0, 1.0)
    r2 = hierarchical_control(Ja, ea, Jm, em, Jv, 10 * ev + 3, 0.5, 0.2, 1.3, 1.0, 1.0)
    assert np.allclose(Ja @ r1.nu, Ja @ r2.nu, atol=1e-8)
    assert np.allclose(Jm @ r1.nu, Jm @ r2.nu, atol=1e-8)
    assert np.allclose(Ja @ r1.nu, -0.5 * ea, atol=1e-8)
    assert np.allclose(Jm @ r1.nu, -0.2 * em, atol=1e-8)


def test_projectors_are_orthogonal_projectors():
    Ja, ea, Jm, em, Jv, ev = _random_problem(7)
    r = hierarchical_control(Ja, ea, Jm, em, Jv, ev, 0.5, 0.2, 1.0, 1.0, 1.0)
    for N in (r.N_a, r.N_m):
        assert np.allclose(N @ N, N, atol=1e-10) and np.allclose(N, N.T, atol=1e-10)
    assert np.allclose(Ja @ r.N_a, 0.0, atol=1e-10)
    assert np.allclose(Jm @ r.N_m, 0.0, atol=1e-10) and np.allclose(Ja @ r.N_m, 0.0, atol=1e-10)
    assert np.linalg.matrix_rank(r.N_m) == 3


def test_inactive_upper_tasks_reduce_to_the_visual_law():
    """h_a = h_m = 0: the intermediate values make the sum exactly the visual task's own law."""
    Ja, ea, Jm, em, _, ev = _random_problem(3)
    lam = np.array([2.0, 4.5, 2.0, 1.0, 1.0, 1.0])
    r = hierarchical_control(Ja, ea, Jm, em, np.eye(6), ev, 0.5, 0.2, lam, 0.0, 0.0)
    assert np.allclose(r.nu, -lam * ev, atol=1e-10)


def test_hierarchy_is_continuous_in_the_activations():
    Ja, ea, Jm, em, Jv, ev = _random_problem(5)
    hs = np.linspace(0, 1, 201)
    nus = np.array([hierarchical_control(Ja, ea, Jm, em, Jv, ev, 0.5, 0.2, 1.0, h, 0.3).nu for h in hs])
    assert np.max(np.abs(np.diff(nus, axis=0))) < 0.05 * np.max(np.abs(nus))


def test_activation_is_eq_20_and_the_executor_blend():
    for tau in np.linspace(-0.5, 2.5, 61):
        assert activation(tau, 2.0) == blend_weight(tau, 2.0)
    assert activation(0.0, 3.0) == 0.0 and activation(3.0, 3.0) == 1.0
    assert activation(1.5, 3.0) == pytest.approx(0.5)


def test_transition_weight_eq_29_is_continuous_with_its_end_values():
    h0, T = 0.2, 1.6
    assert transition_weight(0.0, T, h0) == pytest.approx(h0)
    assert transition_weight(T, T, h0) == 1.0 and transition_weight(5.0, T, h0) == 1.0
    ts = np.linspace(0.0, 3.0, 3001)
    h = np.array([transition_weight(t, T, h0) for t in ts])
    assert np.max(np.abs(np.diff(h))) < 2e-3  # no jump (max slope π(1-h0)/(2T) ≈ 0.79 /s)
    assert np.all(np.diff(h) >= -1e-15) and h.min() >= h0 and h.max() <= 1.0
    # formula as printed
    t = 0.7
    assert transition_weight(t, T, h0) == pytest.approx(h0 + 0.5 * (1 - h0) * (1 - math.cos(math.pi * t / T)))
    with pytest.raises(ValueError):
        transition_weight(0.1, T, 1.5)


def test_activation_state_is_continuous_across_switches():
    a = Activation(3.0)
    ts = np.arange(0.0, 12.0, 0.01)
    cond = (ts > 1.0) & (ts < 2.5) | (ts > 5.0)  # switch off half way through the rise
    h = np.array([a.update(c, t) for c, t in zip(cond, ts)])
    assert h[0] == 0.0 and h[-1] == pytest.approx(1.0)
    assert np.max(np.abs(np.diff(h))) < 0.01
    assert 0.0 < h.max() <= 1.0 and h.min() >= 0.0
    # full rise takes 3 s: from 5.0 s the weight is 1 by 8 s
    assert h[np.searchsorted(ts, 8.05)] == pytest.approx(1.0)


def test_pinv_of_one_or_two_rows_is_numpys():
    """The closed-form pseudo-inverse of one or two rows (``Jᵀ (J Jᵀ)⁻¹``) is numpy's SVD one to 1e-9
    relative, for well-conditioned, nearly parallel (handed to the SVD) and zero rows."""
    rng = np.random.default_rng(7)
    for k in range(300):
        J = rng.normal(size=(1 + k % 2, 6)) * 10.0 ** rng.uniform(-4, 2)
        if k % 6 == 1:
            J[1] = 2.0 * J[0] + rng.normal(size=6) * 10.0 ** rng.uniform(-12, -1) * np.linalg.norm(J[0])
        ref = np.linalg.pinv(J, rcond=1e-9)
        assert np.max(np.abs(pinv(J) - ref)) <= 1e-9 * np.max(np.abs(ref))
    assert np.array_equal(pinv(np.zeros((1, 6))), np.zeros((6, 1)))
    assert np.array_equal(pinv(np.zeros((2, 6))), np.zeros((6, 2)))
