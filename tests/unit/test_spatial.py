"""``taskflow.spatial`` against independent oracles: Pinocchio's ``SE3.action`` and finite differences
for the twist maps, scipy's ``Rotation`` for the rotations, PyBullet for the quaternion formula."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from taskflow import spatial as sp


def _random_T(rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    return sp.transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(0.0, scale, 3))


def _moving_frame(T0: np.ndarray, V_body: np.ndarray, s: float) -> np.ndarray:
    """``T_world_frame`` after moving for ``s`` seconds with the constant body twist ``V_body = [v; w]``
    (the exact exponential, computed with Pinocchio)."""
    return T0 @ pin.exp6(pin.Motion(V_body[:3] * s, V_body[3:] * s)).homogeneous


def _body_twist_fd(T_of_s, h: float = 1e-6) -> np.ndarray:
    """Body twist ``[v; w]`` of a moving frame ``T_world_frame(s)`` at ``s = 0`` by central differences:
    ``T⁻¹ dT/ds = [[w]x, v]``."""
    dT = (T_of_s(h) - T_of_s(-h)) / (2 * h)
    X = sp.inverse(T_of_s(0.0)) @ dT
    return np.r_[X[:3, 3], sp.vee(X[:3, :3])]


# -- twists -------------------------------------------------------------------------------------------


def test_twist_adjoint_is_pinocchio_se3_action():
    rng = np.random.default_rng(1)
    for _ in range(20):
        T = _random_T(rng)
        np.testing.assert_allclose(sp.twist_adjoint(T), pin.SE3(T[:3, :3], T[:3, 3]).action, atol=1e-14)
        np.testing.assert_allclose(sp.twist_adjoint_inverse(T), pin.SE3(T[:3, :3], T[:3, 3]).inverse().action,
                                   atol=1e-12)
        np.testing.assert_allclose(sp.twist_adjoint_inverse(T), sp.twist_adjoint(sp.inverse(T)), atol=1e-12)
        np.testing.assert_allclose(sp.twist_adjoint(T) @ sp.twist_adjoint_inverse(T), np.eye(6), atol=1e-12)


def test_twist_adjoint_maps_a_rigidly_attached_frames_twist_finite_differences():
    """A camera ``c`` rigidly mounted on a body ``b`` (``T_body_camera`` fixed): the body moves with the
    twist ``V_b``; the camera's own body twist, differentiated numerically, is
    ``twist_adjoint_inverse(T_body_camera) @ V_b``, and ``twist_adjoint(T_body_camera)`` maps it back."""
    rng = np.random.default_rng(2)
    for _ in range(10):
        T_world_body0, T_body_camera = _random_T(rng), _random_T(rng, 0.5)
        V_body = rng.normal(0.0, 1.0, 6)

        def T_world_camera(s: float) -> np.ndarray:
            return _moving_frame(T_world_body0, V_body, s) @ T_body_camera  # noqa: B023 - used in this iteration

        V_camera = _body_twist_fd(T_world_camera)
        np.testing.assert_allclose(sp.twist_adjoint_inverse(T_body_camera) @ V_body, V_camera, atol=1e-7)
        np.testing.assert_allclose(sp.twist_adjoint(T_body_camera) @ V_camera, V_body, atol=1e-7)


def test_twist_adjoint_direction_would_catch_a_flip():
    """The two maps differ whenever the mount is not trivial: using one for the other is caught."""
    T_body_camera = sp.transform(sp.R_body_optical(pitch=0.3), [0.4, 0.0, 0.55])
    V_body = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.5])  # a car: forward speed and yaw rate

    def T_world_camera(s: float) -> np.ndarray:
        return _moving_frame(np.eye(4), V_body, s) @ T_body_camera

    V_camera = _body_twist_fd(T_world_camera)
    assert np.allclose(sp.twist_adjoint_inverse(T_body_camera) @ V_body, V_camera, atol=1e-7)
    assert not np.allclose(sp.twist_adjoint(T_body_camera) @ V_body, V_camera, atol=1e-3)


def test_a_point_fixed_in_a_moving_frame_moves_at_v_plus_w_cross_r():
    """The twist's linear part is the velocity of the frame's origin: a point at ``r`` in the frame
    moves at ``v + w × r`` (frame axes), checked by differencing its world position."""
    rng = np.random.default_rng(3)
    T0 = _random_T(rng)
    V = rng.normal(0.0, 1.0, 6)
    r = rng.normal(0.0, 1.0, 3)
    h = 1e-6
    x = [(_moving_frame(T0, V, s) @ np.r_[r, 1.0])[:3] for s in (-h, h)]
    v_world = (x[1] - x[0]) / (2 * h)
    np.testing.assert_allclose(T0[:3, :3].T @ v_world, V[:3] + sp.cross(V[3:], r), atol=1e-7)
    # the same velocity is the linear part of the twist moved to a frame at r (no rotation)
    np.testing.assert_allclose((sp.twist_adjoint_inverse(sp.transform(np.eye(3), r)) @ V)[:3],
                               V[:3] + sp.cross(V[3:], r), atol=1e-12)


# -- transforms ---------------------------------------------------------------------------------------


def test_inverse_and_composition():
    rng = np.random.default_rng(4)
    for _ in range(20):
        T_a_b, T_b_c = _random_T(rng), _random_T(rng)
        np.testing.assert_allclose(sp.inverse(T_a_b), np.linalg.inv(T_a_b), atol=1e-12)
        np.testing.assert_allclose(sp.inverse(T_a_b) @ T_a_b, np.eye(4), atol=1e-12)
        T_a_c = T_a_b @ T_b_c
        pt_c = rng.normal(size=3)
        np.testing.assert_allclose((T_a_c @ np.r_[pt_c, 1])[:3],
                                   T_a_b[:3, :3] @ (T_b_c[:3, :3] @ pt_c + T_b_c[:3, 3]) + T_a_b[:3, 3], atol=1e-12)
        np.testing.assert_allclose(sp.twist_adjoint(T_a_c), sp.twist_adjoint(T_a_b) @ sp.twist_adjoint(T_b_c),
                                   atol=1e-12)


def test_transform_builders():
    T = sp.transform_xyz_yaw(1.0, -2.0, 0.5, 0.7)
    np.testing.assert_allclose(T, sp.transform(Rotation.from_euler("z", 0.7).as_matrix(), [1.0, -2.0, 0.5]),
                               atol=1e-15)
    T = sp.transform_from_xyz_rpy([1, 2, 3], [0.1, -0.2, 0.3])
    np.testing.assert_allclose(T[:3, :3], Rotation.from_euler("xyz", [0.1, -0.2, 0.3]).as_matrix(), atol=1e-15)
    np.testing.assert_array_equal(T[:3, 3], [1, 2, 3])
    with pytest.raises(ValueError):
        sp.twist_adjoint(np.eye(3))


# -- rotations ----------------------------------------------------------------------------------------


def test_rotations_match_scipy():
    rng = np.random.default_rng(5)
    for _ in range(20):
        r, pt, y = rng.uniform(-math.pi, math.pi), rng.uniform(-1.5, 1.5), rng.uniform(-math.pi, math.pi)
        ref = Rotation.from_euler("xyz", [r, pt, y])  # extrinsic x, y, z = Rz Ry Rx
        np.testing.assert_allclose(sp.rotation_from_rpy(r, pt, y), ref.as_matrix(), atol=1e-14)
        np.testing.assert_allclose(sp.rpy_from_rotation(ref.as_matrix()), (r, pt, y), atol=1e-9)
        np.testing.assert_allclose(sp.rotation_z(y), Rotation.from_euler("z", y).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(sp.rotation_y(pt), Rotation.from_euler("y", pt).as_matrix(), atol=1e-15)


def test_rpy_at_gimbal_lock_round_trips_the_rotation():
    R = sp.rotation_from_rpy(0.3, math.pi / 2, -0.2)
    np.testing.assert_allclose(sp.rotation_from_rpy(*sp.rpy_from_rotation(R)), R, atol=1e-12)


def test_rotvec_round_trips_and_matches_scipy():
    rng = np.random.default_rng(6)
    for _ in range(50):
        R = Rotation.random(random_state=rng)
        np.testing.assert_allclose(sp.rotvec_from_rotation(R.as_matrix()), R.as_rotvec(), atol=1e-9)
        np.testing.assert_allclose(sp.rotation_from_rotvec(R.as_rotvec()), R.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(sp.rotation_from_rotvec(np.zeros(3)), np.eye(3))


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-7, 1e-5, 1e-3, math.pi - 1e-3, math.pi - 1e-5, math.pi - 1e-7,
                                   math.pi])
def test_rotation_angle_and_rotvec_near_zero_and_pi(angle):
    rng = np.random.default_rng(7)
    for _ in range(5):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        R = Rotation.from_rotvec(angle * axis).as_matrix()
        assert sp.rotation_angle(R) == pytest.approx(angle, abs=2e-8)
        w = sp.rotvec_from_rotation(R)
        if angle > math.pi - 1e-3:  # at π the axis sign is either: compare the rotations
            np.testing.assert_allclose(sp.rotation_from_rotvec(w), R, atol=1e-7)
            assert np.linalg.norm(w) == pytest.approx(angle, abs=2e-8)
        else:
            np.testing.assert_allclose(w, angle * axis, atol=2e-8)


def test_rotation_angle_clips_and_is_between_frames():
    assert sp.rotation_angle(np.eye(3) * (1 + 1e-12)) == 0.0
    assert sp.rotation_angle(np.diag([-1.0 - 1e-12, -1.0, 1.0])) == pytest.approx(math.pi)
    R_a_b, R_a_c = sp.rotation_z(0.2), sp.rotation_z(0.5)
    assert sp.rotation_angle(R_a_b.T @ R_a_c) == pytest.approx(0.3)


def test_skew_and_vee():
    rng = np.random.default_rng(8)
    a, b = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(sp.skew(a) @ b, np.cross(a, b), atol=1e-15)
    np.testing.assert_allclose(sp.cross(a, b), np.cross(a, b), atol=1e-15)
    np.testing.assert_array_equal(sp.vee(sp.skew(a)), a)
    np.testing.assert_array_equal(sp.skew(a), -sp.skew(a).T)
    with pytest.raises(ValueError):
        sp.skew([1.0, 2.0])


# -- quaternions --------------------------------------------------------------------------------------


def test_quaternion_formula_is_pybullets_to_the_bit():
    rng = np.random.default_rng(9)
    for _ in range(200):
        q = rng.normal(size=4) * rng.uniform(0.5, 2.0)  # not normalised: both normalise
        ref = np.array(p.getMatrixFromQuaternion(q.tolist())).reshape(3, 3)
        np.testing.assert_array_equal(sp.rotation_from_quaternion(q), ref)


def test_quaternions_match_scipy_and_round_trip():
    rng = np.random.default_rng(10)
    for _ in range(50):
        R = Rotation.random(random_state=rng)
        q = R.as_quat()  # scipy is (x, y, z, w) too
        np.testing.assert_allclose(sp.rotation_from_quaternion(q), R.as_matrix(), atol=1e-14)
        np.testing.assert_allclose(sp.rotation_from_unit_quaternion(q), R.as_matrix(), atol=1e-14)
        q2 = np.array(sp.quaternion_from_rotation(R.as_matrix()))
        assert abs(float(q2 @ q)) == pytest.approx(1.0, abs=1e-12)  # q and −q are one rotation
    for yaw in (-3.0, -0.4, 0.0, 1.2, 3.1):
        q = sp.quaternion_from_yaw(yaw)
        np.testing.assert_allclose(sp.rotation_from_quaternion(q), sp.rotation_z(yaw), atol=1e-15)
        assert sp.yaw_from_quaternion(q) == pytest.approx(yaw)
        np.testing.assert_allclose(q, p.getQuaternionFromEuler([0.0, 0.0, yaw]), atol=1e-15)
    T = sp.transform_from_pose([1, 2, 3], sp.quaternion_from_yaw(0.5))
    np.testing.assert_allclose(T, sp.transform_xyz_yaw(1, 2, 3, 0.5), atol=1e-15)


# -- cameras ------------------------------------------------------------------------------------------


def test_optical_frame_axes_on_an_flu_body():
    # looking forward: optical x (right) = −y, y (down) = −z, z (view) = +x of the body
    np.testing.assert_array_equal(sp.R_FLU_OPTICAL @ [1, 0, 0], [0, -1, 0])
    np.testing.assert_array_equal(sp.R_FLU_OPTICAL @ [0, 1, 0], [0, 0, -1])
    np.testing.assert_array_equal(sp.R_FLU_OPTICAL @ [0, 0, 1], [1, 0, 0])
    # pitched down by 0.3: the view axis points below the horizon; yawed by π it looks backward
    view = sp.R_body_optical(pitch=0.3)[:, 2]
    np.testing.assert_allclose(view, [math.cos(0.3), 0.0, -math.sin(0.3)], atol=1e-15)
    np.testing.assert_allclose(sp.R_body_optical(yaw=math.pi)[:, 2], [-1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(sp.rotation_y(0.3) @ sp.R_FLU_OPTICAL, sp.R_body_optical(pitch=0.3), atol=1e-16)


def test_wrap_angle_keeps_the_angle_modulo_a_turn_within_pi():
    for a in (0.0, 3.0, -3.0, 7.0, -7.0, 100.0, math.pi + 1e-9):
        w = sp.wrap_angle(a)
        assert -math.pi <= w <= math.pi and math.isclose(math.cos(w), math.cos(a), abs_tol=1e-12) \
            and math.isclose(math.sin(w), math.sin(a), abs_tol=1e-9)
    assert sp.wrap_angle(2.0 * math.pi + 0.5) == pytest.approx(0.5)


# -- planar transforms -----------------------------------------------------------------------------------


def test_planar_hand_values():
    T_a_b = np.array([1.0, 2.0, math.pi / 2])
    np.testing.assert_allclose(sp.planar_apply(T_a_b, [1.0, 0.0]), [1.0, 3.0], atol=1e-15)
    np.testing.assert_allclose(sp.planar_apply(T_a_b, [[1.0, 0.0], [0.0, 1.0]]), [[1.0, 3.0], [0.0, 2.0]], atol=1e-15)
    np.testing.assert_allclose(sp.planar_apply_inverse(T_a_b, [1.0, 3.0]), [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(sp.planar_inverse(T_a_b), [-2.0, 1.0, -math.pi / 2], atol=1e-15)
    np.testing.assert_allclose(sp.planar_compose(T_a_b, [1.0, 0.0, math.pi / 2]), [1.0, 3.0, math.pi], atol=1e-15)
    np.testing.assert_allclose(sp.planar_between([1.0, 2.0, math.pi / 2], [1.0, 3.0, math.pi]), [1.0, 0.0, math.pi / 2],
                               atol=1e-15)
    # yaw wrapped by IEEE remainder, unless asked not to
    assert sp.planar_compose([0.0, 0.0, 3.0], [0.0, 0.0, 1.0])[2] == math.remainder(4.0, 2 * math.pi)
    assert sp.planar_compose([0.0, 0.0, 3.0], [0.0, 0.0, 1.0], wrap=False)[2] == 4.0
    T = sp.T_from_planar(T_a_b, z=0.5)
    np.testing.assert_allclose(T @ [1.0, 0.0, 0.0, 1.0], [1.0, 3.0, 0.5, 1.0], atol=1e-15)


def test_planar_round_trips_and_agree_with_the_4x4_forms():
    rng = np.random.default_rng(3)
    for _ in range(50):
        A, B = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3)
        pts = rng.normal(0.0, 2.0, (7, 2))
        np.testing.assert_allclose(sp.planar_compose(A, sp.planar_inverse(A))[:2], 0.0, atol=1e-12)
        assert abs(sp.planar_compose(A, sp.planar_inverse(A))[2]) < 1e-12
        np.testing.assert_allclose(sp.planar_apply_inverse(A, sp.planar_apply(A, pts)), pts, atol=1e-12)
        np.testing.assert_allclose(sp.planar_between(A, B), sp.planar_compose(sp.planar_inverse(A), B), atol=1e-12)
        AB = sp.planar_compose(A, B)
        np.testing.assert_allclose(sp.T_from_planar(AB), sp.T_from_planar(A) @ sp.T_from_planar(B), atol=1e-12)
        np.testing.assert_allclose(sp.planar_from_T(sp.T_from_planar(AB)), AB, atol=1e-12)
        np.testing.assert_allclose(sp.planar_apply(A, pts), (sp.T_from_planar(A) @ np.c_[pts, np.zeros(7), np.ones(7)].T)[:2].T,
                                   atol=1e-12)
        np.testing.assert_allclose(sp.inverse(sp.T_from_planar(A)), sp.T_from_planar(sp.planar_inverse(A)), atol=1e-12)


def test_planar_functions_are_the_inline_forms_to_the_bit():
    """The expressions the paper code wrote inline (tasks/viki_hyco.py, tasks/viki_evidence.py, sim/viki_world.py,
    tasks/screw_tasks.py): the same operations in the same order, so a site switching keeps its records."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        x, y, th = (float(v) for v in rng.uniform(-4, 4, 3))
        px, py = (float(v) for v in rng.normal(0.0, 3.0, 2))
        c, s = math.cos(th), math.sin(th)
        assert sp.planar_apply((x, y, th), (px, py)).tolist() == [x + c * px - s * py, y + s * px + c * py]
        dx, dy = px - x, py - y
        assert sp.planar_apply_inverse((x, y, th), (px, py)).tolist() == [c * dx + s * dy, -s * dx + c * dy]
        assert sp.planar_inverse((x, y, th))[:2].tolist() == [-c * x - s * y, s * x - c * y]
        u, v, ph = (float(w) for w in rng.uniform(-4, 4, 3))
        du, dv = u - x, v - y
        assert sp.planar_between((x, y, th), (u, v, ph)).tolist() == [c * du + s * dv, -s * du + c * dv,
                                                                      math.remainder(ph - th, 2 * math.pi)]
    P = rng.uniform(-4, 4, (9, 3))
    g = rng.normal(0.0, 1.0, 2)
    cv, sv = np.cos(P[:, 2]), np.sin(P[:, 2])
    inline = np.stack([P[:, 0] + cv * g[0] - sv * g[1], P[:, 1] + sv * g[0] + cv * g[1]], axis=1)
    assert np.array_equal(sp.planar_apply(P, g), inline)


def test_planar_shapes_are_checked():
    with pytest.raises(ValueError):
        sp.planar_compose([0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        sp.planar_apply([0.0, 0.0, 0.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError):
        sp.planar_from_T(np.eye(3))
