"""Pure PBVS laws of the screw-fastening paper (eqs. 9-14, 25-37) against independent references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from taskflow_tasks.core import pbvs

from taskflow import spatial


def rand_pose(rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    return spatial.transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(0.0, scale, 3))


# -- angle-axis, eqs. 27-31 -----------------------------------------------------------------------------


def test_angle_axis_matches_scipy_rotvec_over_random_rotations():
    rng = np.random.default_rng(0)
    for _ in range(500):
        R = Rotation.random(random_state=rng)
        np.testing.assert_allclose(spatial.rotvec_from_rotation(R.as_matrix()), R.as_rotvec(), atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-7, 1e-5, 1e-3, 0.5, 3.0, math.pi - 1e-3, math.pi - 1e-5, math.pi - 1e-7])
def test_angle_axis_near_zero_and_pi(angle):
    rng = np.random.default_rng(1)
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        R = Rotation.from_rotvec(angle * axis)
        got = spatial.rotvec_from_rotation(R.as_matrix())
        assert np.linalg.norm(got) == pytest.approx(angle, abs=1e-6)
        # the same rotation (θ a and −θ a coincide at π)
        np.testing.assert_allclose(Rotation.from_rotvec(got).as_matrix(), R.as_matrix(), atol=1e-6)


def test_rotation_angle_is_eq_11_and_clips():
    R = Rotation.from_rotvec([0.0, 0.3, 0.0]).as_matrix()
    assert spatial.rotation_angle(R) == pytest.approx(0.3)
    assert spatial.rotation_angle(np.eye(3) * (1 + 1e-12)) == 0.0  # trace a hair above 3 is clipped


# -- transition tests, eqs. 9-14 ----------------------------------------------------------------------------


def test_eq_10_and_13_norms_do_not_depend_on_the_product_order():
    rng = np.random.default_rng(2)
    for _ in range(50):
        A, B = rand_pose(rng), rand_pose(rng)
        t1, r1 = pbvs.pose_error_norms(A @ spatial.inverse(B))  # as meant for the control law
        t2, r2 = pbvs.pose_error_norms(B @ spatial.inverse(A))  # as printed
        assert t1 == pytest.approx(t2) and r1 == pytest.approx(r2)


def test_within_is_strict_on_translation_and_inclusive_on_rotation():
    E = spatial.transform(Rotation.from_rotvec([0.0, 0.0, 0.01]).as_matrix(), np.array([0.002, 0.0, 0.0]))
    assert not pbvs.within(E, 0.002, 0.02)       # |p| < ε_t is strict (eq. 9)
    assert pbvs.within(E, 0.0021, 0.01 + 1e-12)  # |θ| ≤ ε_r is inclusive
    assert not pbvs.within(E, 0.0021, 0.0099)


# -- camera error and platform twist, eqs. 10, 25-33 ------------------------------------------------------------


def test_camera_error_points_the_camera_where_it_must_go():
    """Moving the camera by the error (its own frame) makes it see the object at H*_co."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        H_co, H_star = rand_pose(rng), rand_pose(rng)
        E = pbvs.camera_error(H_co, H_star)
        # the camera moves to E (pose of c* in c): then it sees the object at E^-1 H_co
        np.testing.assert_allclose(spatial.inverse(E) @ H_co, H_star, atol=1e-12)


def test_camera_error_vector_is_the_error_expressed_in_the_base_frame():
    rng = np.random.default_rng(4)
    for _ in range(50):
        R_bc = Rotation.random(random_state=rng).as_matrix()
        E = rand_pose(rng, 0.1)
        L = pbvs.camera_error_vector(E, R_bc)
        # conjugated rotation: same rotation seen from the base frame
        ref = Rotation.from_matrix(R_bc @ E[:3, :3] @ R_bc.T).as_rotvec()
        np.testing.assert_allclose(L[:3], ref, atol=1e-9)
        np.testing.assert_allclose(L[3:], R_bc @ E[:3, 3], atol=1e-12)


def test_platform_twist_controller_keeps_the_planar_part_and_saturates_speed():
    V = np.array([0.3, -0.2, 0.5, 3.0, 4.0, 7.0])
    cmd = pbvs.platform_twist_controller(V, v_max=1.0, w_max=0.4)
    np.testing.assert_allclose(cmd, [0.6, 0.8, 0.4])
    np.testing.assert_allclose(pbvs.planar_twist(cmd), [0, 0, 0.4, 0.6, 0.8, 0])
    np.testing.assert_allclose(pbvs.platform_twist_controller(np.array([0, 0, -0.1, 0.1, 0.2, 0]), 1.0, 1.0), [0.1, 0.2, -0.1])


# -- compensation, eqs. 34-35 -----------------------------------------------------------------------------------


def planar_motion(cmd: np.ndarray, dt: float) -> np.ndarray:
    """The base's displacement (exact, constant planar twist for dt) as a transform b(t) → b(t+dt)."""
    vx, vy, wz = cmd
    th = wz * dt
    if abs(wz) < 1e-12:
        dx, dy = vx * dt, vy * dt
    else:
        s, c = math.sin(th), math.cos(th)
        dx = (vx * s - vy * (1 - c)) / wz
        dy = (vx * (1 - c) + vy * s) / wz
    return spatial.transform(Rotation.from_rotvec([0, 0, th]).as_matrix(), np.array([dx, dy, 0.0]))


def test_compensation_matches_a_finite_difference_of_the_tool_pose_under_platform_motion():
    rng = np.random.default_rng(5)
    dt = 1e-5
    for _ in range(30):
        cmd = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)])
        V_b = pbvs.planar_twist(cmd)
        H_be = rand_pose(rng, 0.6)  # arm frozen: the tool is fixed in the base frame
        H_wb0 = rand_pose(rng, 2.0)
        H_wb1 = H_wb0 @ planar_motion(cmd, dt)
        H_we0, H_we1 = H_wb0 @ H_be, H_wb1 @ H_be
        # the tool's displacement in the world, expressed in the initial base frame
        R_bw = H_wb0[:3, :3].T
        dp = R_bw @ (H_we1[:3, 3] - H_we0[:3, 3]) / dt
        dw = R_bw @ Rotation.from_matrix(H_we1[:3, :3] @ H_we0[:3, :3].T).as_rotvec() / dt
        V_be = pbvs.platform_induced_twist(V_b, H_be[:3, 3])
        np.testing.assert_allclose(V_be[:3], dw, atol=1e-6)
        np.testing.assert_allclose(V_be[3:], dp, atol=1e-4)
        # eq. 35: the compensated error is the error left once the platform has moved for dt
        target = rand_pose(rng, 0.6)  # a world-fixed target, in the initial base frame
        target1 = spatial.inverse(planar_motion(cmd, dt)) @ target  # the same target in the moved base frame
        L0 = pbvs.ee_error_vector(H_be, target)
        L1 = pbvs.ee_error_vector(H_be, target1)
        V_bt = pbvs.platform_induced_twist(V_b, target[:3, 3])
        np.testing.assert_allclose(pbvs.compensate_error(L0, V_bt, dt)[3:], L1[3:], atol=1e-9)


def test_ee_setpoints_eq_21_to_23():
    rng = np.random.default_rng(6)
    H_bc, H_co, H_ot, H_tp = (rand_pose(rng) for _ in range(4))
    np.testing.assert_allclose(pbvs.ee_setpoint(H_bc, H_co, H_ot), H_bc @ H_co @ H_ot)
    np.testing.assert_allclose(pbvs.ee_setpoint(H_bc, H_co, H_ot, H_tp), H_bc @ H_co @ H_ot @ H_tp)


def test_ee_error_vector_drives_the_tool_onto_the_target():
    rng = np.random.default_rng(7)
    for _ in range(30):
        H, H_star = rand_pose(rng), rand_pose(rng)
        L = pbvs.ee_error_vector(H, H_star)
        moved = spatial.transform(spatial.rotation_from_rotvec(L[:3]) @ H[:3, :3], H[:3, 3] + L[3:])
        np.testing.assert_allclose(moved, H_star, atol=1e-9)
        t, r = pbvs.error_norms(L)
        assert t == pytest.approx(np.linalg.norm(H_star[:3, 3] - H[:3, 3]))
        assert r == pytest.approx(spatial.rotation_angle(H_star[:3, :3] @ H[:3, :3].T), abs=1e-9)


# -- damped least squares, eq. 37 -----------------------------------------------------------------------


def test_dls_is_the_pseudo_inverse_when_undamped_and_bounded_when_singular():
    rng = np.random.default_rng(8)
    J = rng.normal(size=(6, 7))
    V = rng.normal(size=6)
    np.testing.assert_allclose(pbvs.dls_solve(J, V, 1e-9), np.linalg.pinv(J) @ V, atol=1e-6)
    Js = J.copy()
    Js[5] = Js[4]  # rank-deficient
    dq = pbvs.dls_solve(Js, np.array([0, 0, 0, 0, 1.0, -1.0]), 0.05)
    assert np.all(np.isfinite(dq)) and np.linalg.norm(dq) < 100.0
    q = rng.normal(size=7)
    np.testing.assert_allclose(pbvs.arm_twist_step(q, J, V, 0.01, 1e-9), q + 0.01 * np.linalg.pinv(J) @ V, atol=1e-8)


# -- velocity feed-forward ------------------------------------------------------------------------------


def test_fit_velocity_recovers_a_line_and_object_feedforward_is_a_rigid_motion():
    t = np.linspace(0.0, 0.3, 13)
    x = np.stack([0.05 * t + 1.0, -0.02 * t, 0 * t], axis=1)
    last, slope = pbvs.fit_velocity(t, x)
    np.testing.assert_allclose(slope, [0.05, -0.02, 0.0], atol=1e-12)
    np.testing.assert_allclose(last, x[-1], atol=1e-12)
    # a base that moves with the platform ff twist keeps the part fixed in its frame
    v_o, w_o = np.array([0.05, 0.01, 0.0]), np.array([0.0, 0.0, 0.2])
    p_bo, p_bt = np.array([0.8, 0.1, 0.85]), np.array([0.75, -0.05, 0.86])
    ff_b, ff_a = pbvs.object_feedforward(v_o, w_o, p_bo, p_bt, np.zeros(6))
    np.testing.assert_allclose(ff_b[3:] + np.cross(ff_b[:3], p_bo), v_o, atol=1e-12)
    # with that platform twist the target does not move relative to the base: no arm feed-forward
    _, ff_a2 = pbvs.object_feedforward(v_o, w_o, p_bo, p_bt, ff_b)
    np.testing.assert_allclose(ff_a2, 0.0, atol=1e-12)


def test_a_parabola_fit_gives_the_velocity_at_the_last_sample_where_a_line_lags_it():
    """x = 0.05 t + 0.5 · 0.2 t² (accelerating at 0.2 m/s²) over 0.3 s: the line's slope is the velocity at
    the window's mean time (0.05 + 0.2 · 0.15 = 0.08 m/s, 0.03 m/s behind), the parabola's the one at its
    end (0.05 + 0.2 · 0.3 = 0.11 m/s); a line through three points stays a line (order drops below 4 samples)."""
    t = np.linspace(0.0, 0.3, 13)
    x = np.stack([0.05 * t + 0.1 * t * t, 0 * t], axis=1)
    _, line = pbvs.fit_velocity(t, x)
    last, slope = pbvs.fit_velocity(t, x, order=2)
    assert line[0] == pytest.approx(0.08, abs=1e-12)
    assert slope[0] == pytest.approx(0.11, abs=1e-12) and slope[1] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(last, x[-1], atol=1e-12)
    _, three = pbvs.fit_velocity(t[:3], x[:3], order=2)
    _, three_line = pbvs.fit_velocity(t[:3], x[:3])
    np.testing.assert_allclose(three, three_line, atol=1e-12)


def test_eq_35_against_a_moving_target_leaves_no_v_dt_offset_with_the_target_twist():
    """Hand-computed: the platform and the target both move at 0.08 m/s along x (base axes), dt = 0.01 s,
    the tool sits exactly on the target (E = 0).  The paper's E − V_be dt reads −0.8 mm along x, so an
    integrating arm law settles with the tool 0.8 mm behind; relative to the target nothing moves."""
    V_be = np.array([0.0, 0.0, 0.0, 0.08, 0.0, 0.0])
    E = np.zeros(6)
    np.testing.assert_allclose(pbvs.compensate_error(E, V_be, 0.01), [0, 0, 0, -0.0008, 0, 0], atol=1e-15)
    np.testing.assert_allclose(pbvs.compensate_error(E, V_be, 0.01, V_be.copy()), 0.0, atol=1e-15)
    # a target moving at half the platform's speed: the platform removes only the other half of its motion
    V_t = np.array([0.0, 0.0, 0.0, 0.04, 0.0, 0.0])
    np.testing.assert_allclose(pbvs.compensate_error(E, V_be, 0.01, V_t), [0, 0, 0, -0.0004, 0, 0], atol=1e-15)


def test_target_twist_is_the_rigid_motion_of_a_point_on_the_part():
    """Hand-computed: part origin at (1, 0, 0) moving at (0.05, 0, 0) and turning at 0.2 rad/s about z; a
    point 0.1 m further along y moves at 0.05 − 0.2 · 0.1 = 0.03 m/s along x."""
    V = pbvs.target_twist(np.array([0.05, 0.0, 0.0]), np.array([0.0, 0.0, 0.2]), np.array([1.0, 0.0, 0.0]),
                          np.array([1.0, 0.1, 0.3]))
    np.testing.assert_allclose(V, [0.0, 0.0, 0.2, 0.03, 0.0, 0.0], atol=1e-15)
