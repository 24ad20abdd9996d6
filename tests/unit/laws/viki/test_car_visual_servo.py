"""Tests for taskflow_tasks.viki.car_visual_servo (ViKi-HyCo eq. 10, 20-24) and the ideal feature-space loop."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from taskflow_tasks.viki.bbox_target import desired_bbox
from taskflow_tasks.viki.car_visual_servo import (
    camera_vs_velocity,
    car_feature_jacobian,
    car_gains,
    car_jacobian_r,
    car_vs_velocity,
)
from taskflow_tasks.viki.image_features import (
    CameraIntrinsics,
    bbox_features,
    feature_error,
    point_interaction_matrix,
)

from taskflow.spatial import R_body_optical, skew, transform, twist_adjoint, twist_adjoint_inverse

K = CameraIntrinsics(500.0, 500.0, 320.0, 240.0)


def camera_mount_rotation(yaw: float, pitch: float) -> np.ndarray:
    """``R_robot_camera`` of an optical frame looking at heading ``yaw``, tilted down by ``pitch``."""
    return R_body_optical(yaw=yaw, pitch=pitch)


def robot_to_camera(R_body_camera, t_body_camera) -> np.ndarray:
    """Eq. 22 as meant: the 6x6 map robot twist → camera twist for the mount ``T_body_camera``."""
    return twist_adjoint_inverse(transform(R_body_camera, t_body_camera))
FRONT = [0.85, 0.3, 1.0, 1.0, 1.0]
REAR = [0.85, 1.05, 1.0, 1.0, 1.0]

MOUNTS = [
    (
        camera_mount_rotation(0.0, np.deg2rad(20.0)),
        np.array([0.3, 0.0, 0.8]),
    ),  # front, tilted down
    (
        camera_mount_rotation(np.pi, np.deg2rad(35.0)),
        np.array([-0.2, 0.05, 0.6]),
    ),  # rear
    (
        Rotation.from_rotvec([0.3, -0.7, 1.1]).as_matrix(),
        np.array([0.4, -0.2, 1.1]),
    ),  # arbitrary
]


# ----------------------------------------------------------------------------- kinematics helpers
def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def unicycle_step(q, V, dt):
    """Exact unicycle motion of the rear-axle origin for constant [v, w] over dt."""
    x, y, th = q
    v, w = V
    if abs(w) < 1e-12:
        return np.array([x + v * dt * np.cos(th), y + v * dt * np.sin(th), th])
    th2 = th + w * dt
    return np.array(
        [
            x + v / w * (np.sin(th2) - np.sin(th)),
            y - v / w * (np.cos(th2) - np.cos(th)),
            th2,
        ]
    )


def camera_pose(q, R_body_camera, t_body_camera):
    R = rz(q[2])
    return R @ R_body_camera, np.array([q[0], q[1], 0.0]) + R @ t_body_camera


# ----------------------------------------------------------------------------- small pieces
def test_skew_is_the_cross_product():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(skew(a) @ b, np.cross(a, b))
    np.testing.assert_allclose(skew(a), -skew(a).T)


def test_camera_mount_rotation():
    front = camera_mount_rotation(0.0, 0.0)
    np.testing.assert_allclose(front[:, 2], [1, 0, 0], atol=1e-15)  # optical axis forward
    np.testing.assert_allclose(front[:, 0], [0, -1, 0], atol=1e-15)  # image right = robot right
    np.testing.assert_allclose(front[:, 1], [0, 0, -1], atol=1e-15)  # image down = robot down
    for yaw, pitch in [(0.0, 0.3), (np.pi, 0.6), (0.4, -0.2)]:
        R = camera_mount_rotation(yaw, pitch)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert R[2, 2] == pytest.approx(-np.sin(pitch))  # tilted down by pitch
    rear = camera_mount_rotation(np.pi, 0.0)
    np.testing.assert_allclose(rear[:, 2], [-1, 0, 0], atol=1e-15)


@pytest.mark.parametrize("R_body_camera, t_body_camera", MOUNTS)
def test_robot_to_camera_twist_and_jr_match_the_camera_pose_derivative(R_body_camera, t_body_camera):
    """Drive the car with [v, w] (unicycle), take the camera's displacement in its own frame."""
    dt = 1e-6
    T = robot_to_camera(R_body_camera, t_body_camera)
    J = car_jacobian_r()
    for V in ([0.4, 0.0], [0.0, 0.7], [-0.3, 0.5], [0.25, -1.2]):
        q1 = unicycle_step(np.zeros(3), V, dt)
        R0, p0 = camera_pose(np.zeros(3), R_body_camera, t_body_camera)
        R1, p1 = camera_pose(q1, R_body_camera, t_body_camera)
        dR = R0.T @ R1
        dp = R0.T @ (p1 - p0)
        numeric = np.concatenate([dp, Rotation.from_matrix(dR).as_rotvec()]) / dt
        np.testing.assert_allclose(T @ J @ np.asarray(V), numeric, atol=1e-5)
        if np.any(np.asarray(V) != 0.0):  # the opposite map (eq. 22 as printed) is not it
            assert not np.allclose(twist_adjoint(transform(R_body_camera, t_body_camera)) @ J @ np.asarray(V), numeric, atol=1e-3)


@pytest.mark.parametrize("R_body_camera, t_body_camera", MOUNTS)
def test_printed_eq22_is_the_inverse_map(R_body_camera, t_body_camera):
    printed = np.zeros((6, 6))
    printed[:3, :3] = R_body_camera
    printed[:3, 3:] = skew(t_body_camera) @ R_body_camera
    printed[3:, 3:] = R_body_camera
    np.testing.assert_allclose(printed @ robot_to_camera(R_body_camera, t_body_camera), np.eye(6), atol=1e-12)
    # ... and eq. 22's form evaluated with the inverse pose (^cR_r, ^ct_r) is ours.
    Ri, ti = R_body_camera.T, -R_body_camera.T @ t_body_camera
    as_meant = np.zeros((6, 6))
    as_meant[:3, :3] = Ri
    as_meant[:3, 3:] = skew(ti) @ Ri
    as_meant[3:, 3:] = Ri
    np.testing.assert_allclose(as_meant, robot_to_camera(R_body_camera, t_body_camera), atol=1e-12)


def test_jr_reference_point_does_not_change_the_camera_twist():
    R_body_camera, t_body_camera = MOUNTS[0]
    d = 0.325
    a = robot_to_camera(R_body_camera, t_body_camera - np.array([d, 0.0, 0.0])) @ car_jacobian_r(d)
    b = robot_to_camera(R_body_camera, t_body_camera) @ car_jacobian_r(0.0)
    np.testing.assert_allclose(a, b, atol=1e-12)
    np.testing.assert_array_equal(car_jacobian_r(d)[:, 1], [0, d, 0, 0, 0, 1])


@pytest.mark.parametrize("R_body_camera, t_body_camera", MOUNTS)
def test_feature_jacobian_is_L_T_J(R_body_camera, t_body_camera):
    f = bbox_features((300.0, 200.0, 360.0, 260.0))
    uv = f.reshape(4, 2) - (K.cu, K.cv)
    expected = (
        point_interaction_matrix(uv, 2.0, K.fx, K.fy)
        @ robot_to_camera(R_body_camera, t_body_camera)
        @ car_jacobian_r()
    )
    np.testing.assert_allclose(car_feature_jacobian(f, 2.0, K, R_body_camera, t_body_camera), expected, atol=1e-9)


def test_car_law_equals_the_pseudo_inverse_form_of_eq24():
    R_body_camera, t_body_camera = MOUNTS[0]
    f = bbox_features((300.0, 200.0, 360.0, 250.0))
    f_d = bbox_features((310.0, 220.0, 372.0, 270.0))
    A = car_feature_jacobian(f, 2.5, K, R_body_camera, t_body_camera)
    expected = -np.array(FRONT[:2]) * (np.linalg.pinv(A) @ (f - f_d))
    np.testing.assert_allclose(
        car_vs_velocity(f, f_d, 2.5, K, R_body_camera, t_body_camera, FRONT), expected, rtol=1e-9
    )
    assert np.allclose(car_vs_velocity(f, f, 2.5, K, R_body_camera, t_body_camera, FRONT), 0.0)


def test_car_law_falls_back_to_least_squares_when_rank_deficient():
    # One point at the focus of expansion of a level front camera: driving forward does not move
    # it, so the v-column of L_f T J_r is zero; the minimum-norm solution commands v = 0.
    R_body_camera, t_body_camera = camera_mount_rotation(0.0, 0.0), np.array([0.3, 0.0, 0.5])
    f, f_d = [K.cu, K.cv], [K.cu + 10.0, K.cv]
    A = car_feature_jacobian(f, 2.0, K, R_body_camera, t_body_camera)
    assert np.allclose(A[:, 0], 0.0)
    V = car_vs_velocity(f, f_d, 2.0, K, R_body_camera, t_body_camera, 0.5)
    np.testing.assert_allclose(V, -0.5 * np.linalg.pinv(A) @ (np.array(f) - f_d), atol=1e-12)
    assert V[0] == 0.0 and V[1] > 0.0  # feature left of target -> turn left (camera pans left)


def test_car_law_rejects_mismatched_features():
    R_body_camera, t_body_camera = MOUNTS[0]
    with pytest.raises(ValueError):
        car_vs_velocity(np.zeros(8), 0.0, 2.0, K, R_body_camera, t_body_camera, 1.0)


def test_car_gains_reading_of_the_papers_five_numbers():
    np.testing.assert_array_equal(car_gains(FRONT), [0.85, 0.3])
    np.testing.assert_array_equal(car_gains(REAR), [0.85, 1.05])
    np.testing.assert_array_equal(car_gains(0.5), [0.5, 0.5])
    np.testing.assert_array_equal(car_gains([0.2, 0.4]), [0.2, 0.4])
    for bad in ([1.0, 2.0, 3.0], [-1.0, 1.0], [np.nan, 1.0]):
        with pytest.raises(ValueError):
            car_gains(bad)


def test_camera_law_eq10():
    f = bbox_features((300.0, 200.0, 360.0, 250.0))
    f_d = bbox_features((305.0, 210.0, 368.0, 262.0))
    L = point_interaction_matrix(f.reshape(4, 2) - (K.cu, K.cv), 3.0, K.fx, K.fy)
    expected = -0.7 * np.linalg.pinv(L) @ (f - f_d)
    np.testing.assert_allclose(
        camera_vs_velocity(f, f_d, 3.0, K, 0.7), expected, rtol=1e-9, atol=1e-12
    )
    lam6 = np.array([1.0, 0.5, 0.2, 1.0, 1.0, 0.1])
    np.testing.assert_allclose(
        camera_vs_velocity(f, f_d, 3.0, K, lam6), lam6 * expected / 0.7, rtol=1e-9
    )
    with pytest.raises(ValueError):
        camera_vs_velocity(f, f_d, 3.0, K, [1.0, 2.0])


# ----------------------------------------------------------------------------- ideal feature loop
def box_vertices(centre, size):
    s = np.asarray(size) / 2.0
    return np.array(
        [
            [centre[0] + a * s[0], centre[1] + b * s[1], centre[2] + c * s[2]]
            for a in (-1, 1)
            for b in (-1, 1)
            for c in (-1, 1)
        ]
    )


def plane_depth(uv, Rwc, pwc, n, d0):
    """Camera depth Z of the point where pixel uv's ray meets the plane n.x = d0 (world)."""
    ray = Rwc @ np.array([(uv[0] - K.cu) / K.fx, (uv[1] - K.cv) / K.fy, 1.0])
    return (d0 - n @ pwc) / (n @ ray)


def servo(q0, verts, centre_d, plane, lam, R_body_camera, t_body_camera, T, dt, depth_at_centre):
    """Exact projections of the object, eq. 19 each tick, eq. 24, exact unicycle motion.

    Z_d is the depth of `plane` at the desired centre pixel (the paper reads it from the depth
    image there). Z_o is the depth of `plane` at the box centre pixel (flat object) or the camera
    depth of the object's centre (`depth_at_centre` = that centre).
    """
    q = np.array(q0, dtype=float)
    log = []
    for k in range(int(round(T / dt))):
        Rwc, pwc = camera_pose(q, R_body_camera, t_body_camera)
        Pc = (verts - pwc) @ Rwc
        u = K.fx * Pc[:, 0] / Pc[:, 2] + K.cu
        v = K.fy * Pc[:, 1] / Pc[:, 2] + K.cv
        bb = np.array([u.min(), v.min(), u.max(), v.max()])
        if depth_at_centre is None:
            Z_o = plane_depth(((bb[0] + bb[2]) / 2, (bb[1] + bb[3]) / 2), Rwc, pwc, *plane)
        else:
            Z_o = ((depth_at_centre - pwc) @ Rwc)[2]
        Z_d = plane_depth(centre_d, Rwc, pwc, *plane)
        f = bbox_features(bb)
        f_d = bbox_features(desired_bbox(bb, Z_o, Z_d, centre_d))
        A = car_feature_jacobian(f, Z_o, K, R_body_camera, t_body_camera)
        e = f - f_d
        V = car_vs_velocity(f, f_d, Z_o, K, R_body_camera, t_body_camera, lam)
        log.append((k * dt, e, np.linalg.lstsq(A, e, rcond=None)[0]))
        q = unicycle_step(q, V, dt)
    t = np.array([r[0] for r in log])
    E = np.array([r[1] for r in log])
    Y = np.array([r[2] for r in log])
    return t, E, Y


def test_ideal_loop_small_error_decays_as_e0_exp_minus_lambda_t():
    """Where the law's assumptions hold, f - f_d = e0 exp(-lambda t).

    Level camera, a vertical board facing it (box corners = projections of 3-D points at one
    depth), and an initial error produced by the car's own motion (so e0 lies, to first order,
    in the range of L_f T J_r): the closed loop is the linear system de/dt = -lambda e.
    """
    R_body_camera, t_body_camera = camera_mount_rotation(0.0, 0.0), np.array([0.3, 0.0, 0.8])
    centre = np.array([3.0, 0.0, 0.5])
    verts = box_vertices(centre, (0.01, 0.4, 0.3))
    Rwc, pwc = camera_pose(np.zeros(3), R_body_camera, t_body_camera)
    Pc = Rwc.T @ (centre - pwc)
    centre_d = np.array([K.fx * Pc[0] / Pc[2] + K.cu, K.fy * Pc[1] / Pc[2] + K.cv])
    q0 = np.zeros(3)
    for _ in range(50):
        q0 = unicycle_step(q0, [-0.4, 0.3], 0.01)  # back off and turn: 0.2 m, 8.6 deg
    lam = 1.0
    t, E, Y = servo(
        q0,
        verts,
        centre_d,
        (np.array([1.0, 0, 0]), 3.0),
        lam,
        R_body_camera,
        t_body_camera,
        5.0,
        0.01,
        centre,
    )
    e0 = E[0]
    assert feature_error(e0, 0 * e0) > 50.0
    dev = np.linalg.norm(E - np.outer(np.exp(-lam * t), e0), axis=1) / np.linalg.norm(e0)
    assert dev.max() < 0.03
    # With the paper's front gains each controlled component decays at its own rate.
    t, E, Y = servo(
        q0,
        verts,
        centre_d,
        (np.array([1.0, 0, 0]), 3.0),
        FRONT,
        R_body_camera,
        t_body_camera,
        3.0,
        0.01,
        centre,
    )
    expected = Y[0] * np.exp(-np.outer(t, car_gains(FRONT)))
    assert np.max(np.abs(Y - expected) / np.abs(Y[0])) < 0.15


@pytest.mark.parametrize(
    "obj_xy, lam",
    [((3.0, 0.6), 1.0), ((3.0, 0.6), FRONT), ((2.5, -0.4), REAR), ((3.0, 0.0), FRONT)],
)
def test_ideal_loop_large_error_controlled_component_and_norm(obj_xy, lam):
    """Large offsets, tilted camera, flat object on the ground (a box detector's corners).

    The car's 2 DoF cannot realise an arbitrary 8-D feature velocity, so e(t) is not e0 exp(-lt).
    What the law guarantees in the ideal loop: the controlled component y = (L_f T J_r)^+ e obeys
    dy/dt = -diag(lambda_v, lambda_w) y (here it decays at least that fast, the remaining
    nonlinearity speeding it up), and |e| = |f - f_d| decreases monotonically to the 2 px band.
    """
    R_body_camera, t_body_camera = camera_mount_rotation(0.0, np.deg2rad(20.0)), np.array([0.3, 0.0, 0.8])
    verts = box_vertices(np.array([*obj_xy, 0.0]), (0.3, 0.2, 0.0))
    centre_d = np.array([320.0, 330.0])
    g = car_gains(lam)
    T = 5.0 / g.min()
    t, E, Y = servo(
        np.zeros(3),
        verts,
        centre_d,
        (np.array([0, 0, 1.0]), 0.0),
        lam,
        R_body_camera,
        t_body_camera,
        T,
        0.02,
        None,
    )
    norms = np.linalg.norm(E, axis=1)
    assert norms[0] > 100.0
    assert np.all(np.diff(norms) <= 1e-9 * norms[:-1])
    for i in range(2):
        if abs(Y[0, i]) < 1e-9:
            assert np.allclose(Y[:, i], 0.0, atol=1e-9)
            continue
        m = t <= 2.0 / g[i]
        bound = np.abs(Y[0, i]) * np.exp(-g[i] * t[m]) * 1.05 + 1e-9
        assert np.all(np.abs(Y[m, i]) <= bound)
    assert feature_error(E[-1], 0 * E[-1]) < 2.0
