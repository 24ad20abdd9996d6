"""Homography-based servoing laws (eqs. 2–7, 31–32) on a synthetic camera: points on a plane, exact
projection, no image processing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from taskflow_tasks.quad.homography import (
    HomographyGains,
    adaptive_gain,
    euclidean_homography,
    feedforward_blend,
    feedforward_velocity,
    gain_matrix,
    homography_control,
    intrinsic_matrix,
    largest_triangle,
    mean_pixel_error,
    normalize_homography,
    normalize_pixels,
    robot_velocity,
    sort_points,
    task_error,
    virtual_plane_homography,
)
from taskflow_tasks.quad.yaw_decoupling import axis_rotation, homography_yaw, yaw_decoupled_error

from taskflow.spatial import R_FLU_OPTICAL, skew, transform, twist_adjoint, vee

K = intrinsic_matrix(260.0, 260.0, 160.0, 119.0)
AD_BODY_CAMERA = twist_adjoint(transform(R_FLU_OPTICAL, [0.2, 0.0, -0.05]))  # eq. (5): camera twist → body twist


def wall_points(n: int = 60, seed: int = 0, x: float = 4.0) -> np.ndarray:
    """Points on the wall plane x = ``x`` (world frame, FLU: x forward, z up)."""
    rng = np.random.default_rng(seed)
    return np.column_stack((np.full(n, x), rng.uniform(-2.0, 2.0, n), rng.uniform(0.0, 2.5, n)))


def room_points(n: int = 90, seed: int = 1) -> np.ndarray:
    """Points on three walls (front and both sides): not coplanar."""
    rng = np.random.default_rng(seed)
    front = np.column_stack((np.full(n // 3, 4.0), rng.uniform(-2.0, 2.0, n // 3), rng.uniform(0.0, 2.5, n // 3)))
    left = np.column_stack((rng.uniform(2.8, 4.0, n // 3), np.full(n // 3, 2.0), rng.uniform(0.0, 2.5, n // 3)))
    right = np.column_stack((rng.uniform(2.8, 4.0, n // 3), np.full(n // 3, -2.0), rng.uniform(0.0, 2.5, n // 3)))
    return np.vstack((front, left, right))


def camera_pose(x: float, y: float, z: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """World ← camera-optical rotation and camera position of a quadcopter at ``[x, y, z, yaw]``
    (camera at the body origin for simplicity)."""
    Rb = Rotation.from_euler("z", yaw).as_matrix()
    return Rb @ R_FLU_OPTICAL, np.array([x, y, z])


def project(X: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    Xc = (X - t) @ R  # R^T (X - t), row-wise
    return (Xc[:, :2] / Xc[:, 2:3]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]


def error_at(X, pose, key):
    R, t = camera_pose(*pose)
    Rk, tk = camera_pose(*key)
    cur, kf = project(X, R, t), project(X, Rk, tk)
    H = euclidean_homography(cur, kf, K)
    tri = largest_triangle(kf)
    m_star = normalize_pixels(kf[list(tri)], K).mean(axis=0)
    return task_error(H, m_star), mean_pixel_error(cur, kf), H


def test_skew_and_vee_are_inverse():
    w = np.array([0.3, -1.2, 2.0])
    assert np.allclose(skew(w) @ [1.0, 2.0, 3.0], np.cross(w, [1.0, 2.0, 3.0]))
    assert np.allclose(vee(skew(w)), w)


def test_error_vanishes_at_the_keyframe_pose():
    X = wall_points()
    key = (1.5, 0.0, 0.5, 0.0)
    e, eps, H = error_at(X, key, key)
    assert np.allclose(H, np.eye(3), atol=1e-9)
    assert np.linalg.norm(e) < 1e-9 and eps < 1e-9


def test_homography_matches_the_plane_formula_and_middle_singular_value():
    X = wall_points()
    cur, key = (0.2, -0.3, 1.0, 0.2), (1.5, 0.0, 0.5, 0.0)
    R, t = camera_pose(*cur)
    Rk, tk = camera_pose(*key)
    _, _, H = error_at(X, cur, key)
    # X_k = R_rel X_c + t_rel (pose of the current camera in the keyframe camera frame)
    R_rel, t_rel = Rk.T @ R, Rk.T @ (t - tk)
    # the wall x = 4 in the current camera frame: n_c^T X_c = d_c
    n_c = R.T @ np.array([1.0, 0.0, 0.0])
    d_c = 4.0 - t[0]
    H_true = R_rel + np.outer(t_rel, n_c) / d_c
    assert np.allclose(H, H_true, atol=1e-8)
    assert np.linalg.svd(H, compute_uv=False)[1] == pytest.approx(1.0)


def test_normalize_homography_fixes_scale_and_sign():
    X = wall_points()
    R, t = camera_pose(0.3, 0.1, 0.8, -0.1)
    Rk, tk = camera_pose(1.0, 0.0, 0.5, 0.0)
    cur, kf = project(X, R, t), project(X, Rk, tk)
    H = euclidean_homography(cur, kf, K)
    G = K @ H @ np.linalg.inv(K)
    for s in (3.7, -0.2):
        Hn = normalize_homography(s * G, K, normalize_pixels(cur, K), normalize_pixels(kf, K))
        assert np.allclose(Hn, H, atol=1e-9)


def simulate(X, start, key, law_sign=1.0, steps=600, dt=0.04, direction="current_to_keyframe",
             lam=(2.8, 0.1, 5.0), gains=None):
    """Quadcopter single integrator (eq. 1) driven by eqs. 2–6 with exact projections."""
    gains = gains if gains is not None else HomographyGains(v_offset=(0.0, 0.0, 0.0))
    x = np.array(start, dtype=float)
    Rk, tk = camera_pose(*key)
    kf = project(X, Rk, tk)
    tri = list(largest_triangle(kf))
    m_star = normalize_pixels(kf[tri], K).mean(axis=0)
    for _ in range(steps):
        R, t = camera_pose(*x)
        cur = project(X, R, t)
        if direction == "current_to_keyframe":
            H = euclidean_homography(cur, kf, K)
        else:  # the other reading of eq. 2: H maps the keyframe to the current image
            H = euclidean_homography(kf, cur, K)
        e = task_error(H, m_star)
        g = gain_matrix(adaptive_gain(np.linalg.norm(e), *lam), gains)
        nu_e = robot_velocity(law_sign * homography_control(e, g), AD_BODY_CAMERA)
        c, s = math.cos(x[3]), math.sin(x[3])
        x += dt * np.array([c * nu_e[0] - s * nu_e[1], s * nu_e[0] + c * nu_e[1], nu_e[2], nu_e[3]])
        if not np.all(np.abs(x[:3]) < 50):
            break
    R, t = camera_pose(*x)
    return x, mean_pixel_error(project(X, R, t), kf)


@pytest.mark.parametrize("scene", ["plane", "room"])
def test_law_drives_the_synthetic_quadcopter_to_the_keyframe(scene):
    """§5.1's displacement: 1.5 m forward and 0.5 m down, plus some yaw and lateral offset."""
    X = wall_points() if scene == "plane" else room_points()
    key = (1.5, 0.0, 0.5, 0.0)
    x, eps = simulate(X, (0.0, 0.2, 1.0, 0.15), key)
    assert np.linalg.norm(x[:3] - key[:3]) < 0.01
    assert abs(x[3] - key[3]) < math.radians(0.5)
    assert eps < 0.5


def test_printed_sign_needs_h_from_current_to_keyframe():
    """The sign check of eq. 3: with H read the other way round the printed law moves away."""
    X = wall_points()
    key = (1.5, 0.0, 0.5, 0.0)
    start = (1.0, 0.1, 0.7, 0.05)
    _, eps0 = simulate(X, start, key, steps=0)
    _, eps_good = simulate(X, start, key, steps=25)
    _, eps_bad = simulate(X, start, key, steps=25, direction="keyframe_to_current")
    assert eps_good < 0.5 * eps0
    assert eps_bad > eps0


def test_adaptive_gain_end_values_and_slope():
    l0, linf, s = 2.8, 0.1, 5.0
    assert adaptive_gain(0.0, l0, linf, s) == pytest.approx(l0)
    assert adaptive_gain(1e6, l0, linf, s) == pytest.approx(linf)
    h = 1e-7
    assert (adaptive_gain(h, l0, linf, s) - l0) / h == pytest.approx(-s, rel=1e-4)
    vals = adaptive_gain(np.linspace(0, 5, 50), l0, linf, s)
    assert np.all(np.diff(vals) < 0)
    assert adaptive_gain(0.3, 1.0, 1.0, 5.0) == 1.0


def test_gain_matrix_paper_5_1():
    g = gain_matrix(2.0, HomographyGains(v_offset=(0.0, 2.5, 0.0), w_scale=0.5))
    assert np.allclose(g, [2.0, 4.5, 2.0, 1.0, 1.0, 1.0])


def test_body_camera_twist_map_and_selection():
    # a pure camera forward velocity (optical z) is a body forward velocity
    nu = robot_velocity([0, 0, 1.0, 0, 0, 0], AD_BODY_CAMERA)
    assert np.allclose(nu, [1.0, 0, 0, 0])
    # camera x (right) is body -y; camera y (down) is body -z
    assert np.allclose(robot_velocity([1.0, 0, 0, 0, 0, 0], AD_BODY_CAMERA), [0, -1.0, 0, 0])
    assert np.allclose(robot_velocity([0, 1.0, 0, 0, 0, 0], AD_BODY_CAMERA), [0, 0, -1.0, 0])
    # a yaw rate about the camera's -y axis, with the camera 0.2 m ahead of the body origin:
    # the body origin moves sideways by -w x t
    nu = robot_velocity([0, 0, 0, 0, -1.0, 0], AD_BODY_CAMERA)
    assert np.allclose(nu[3], 1.0)
    assert np.allclose(nu[:3], np.cross([0.2, 0.0, -0.05], [0, 0, 1.0]))


def test_mean_pixel_error():
    assert mean_pixel_error([[0, 0], [3, 4]], [[0, 0], [0, 0]]) == pytest.approx(2.5)
    with pytest.raises(ValueError):
        mean_pixel_error([[0, 0]], [])


def test_largest_triangle_and_sort_points():
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 100, (40, 2))
    pts = np.vstack((pts, [[-50, -50], [200, -40], [60, 300]]))
    tri = largest_triangle(pts)
    assert set(tri) == {40, 41, 42}
    order = sort_points(pts)
    assert set(order[:3]) == {40, 41, 42} and list(order[3:]) == list(range(40))
    with pytest.raises(ValueError):
        largest_triangle([[0, 0], [1, 1], [2, 2]])


def test_virtual_plane_homography_through_three_room_points():
    """Malis & Chaumette's generic homography: built from F and three non-coplanar-scene points, it
    equals the homography induced by the plane through the three 3D points."""
    X = room_points()
    R, t = camera_pose(0.3, 0.2, 0.9, 0.1)
    Rk, tk = camera_pose(1.5, 0.0, 0.5, 0.0)
    cur, kf = project(X, R, t), project(X, Rk, tk)
    m, ms = normalize_pixels(cur, K), normalize_pixels(kf, K)
    R_rel, t_rel = Rk.T @ R, Rk.T @ (t - tk)
    E = skew(t_rel) @ R_rel  # m*^T E m = 0
    tri = list(largest_triangle(kf))
    Hv = virtual_plane_homography(E, m[tri], ms[tri])
    Hv = normalize_homography(Hv, np.eye(3), m[tri], ms[tri])
    # the plane through the three points, in the current frame
    Xc = (X[tri] - t) @ R
    n = np.cross(Xc[1] - Xc[0], Xc[2] - Xc[0])
    n /= np.linalg.norm(n)
    d = float(n @ Xc[0])
    if d < 0:
        n, d = -n, -d
    H_true = R_rel + np.outer(t_rel, n) / d
    assert np.allclose(Hv, H_true, atol=1e-8)


def test_feedforward_equals_the_scaled_law_between_consecutive_keyframes():
    X = room_points()
    k0, k1 = (1.0, 0.0, 1.0, 0.0), (1.5, 0.0, 1.0, math.radians(15))
    e, _, _ = error_at(X, k0, k1)  # keyframe k seen as "current", keyframe k+1 as the target
    g = gain_matrix(adaptive_gain(np.linalg.norm(e), 1.5, 0.8, 5.0))
    nu_p = feedforward_velocity(e, g, 0.75, AD_BODY_CAMERA)
    assert np.allclose(nu_p, 0.75 * robot_velocity(homography_control(e, g), AD_BODY_CAMERA))
    assert nu_p[0] > 0.0 and nu_p[3] > 0.0  # forward and turning left, like the segment
    nu_e = np.array([0.1, 0.0, 0.0, 0.0])
    assert np.allclose(feedforward_blend(nu_e, nu_p, 0.5), 0.5 * nu_e + 0.5 * nu_p)
    assert np.allclose(feedforward_blend(nu_e, nu_p, 1.0), nu_e)
    with pytest.raises(ValueError):
        feedforward_velocity(e, g, 1.5, AD_BODY_CAMERA)
    with pytest.raises(ValueError):
        feedforward_blend(nu_e, nu_p, -0.1)


YAW_AXIS = np.array([0.0, -1.0, 0.0])  # body z (up) in the optical camera frame (y down)


def R_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def test_axis_rotation_is_rodrigues():
    """About the optical y axis the rotation is R_y; about −y (the body's up axis seen by the optical
    camera) it is R_y(−θ); a vector of angles gives a stack."""
    assert axis_rotation(0.3, [0.0, 1.0, 0.0]) == pytest.approx(R_y(0.3), abs=1e-15)
    assert axis_rotation(0.3, YAW_AXIS) == pytest.approx(R_y(-0.3), abs=1e-15)
    stack = axis_rotation(np.array([0.1, -0.2]), YAW_AXIS)
    assert stack.shape == (2, 3, 3) and stack[1] == pytest.approx(R_y(0.2), abs=1e-15)


def test_homography_yaw_of_a_pure_yaw_and_of_a_pure_lateral_translation():
    """H = R_y(−0.2): the yaw is 0.2 about the body's up axis.  H = I + t nᵀ/d with t = (0.3, 0, 0),
    n = (0, 0, 1), d = 3 has a second yaw-only decomposition, R_y(φ) with tan(φ/2) = 0.1/2 (H − R_y(φ)
    is rank one there too, by hand: 2 − 2 cos φ = 0.1 sin φ), whose plane normal ≈ (1, 0, 0) puts points
    left and right of the image centre at opposite depths; the visibility test picks θ = 0."""
    m = np.array([[-0.3, -0.2], [0.3, -0.2], [-0.3, 0.2], [0.3, 0.2], [0.05, 0.0]])
    assert homography_yaw(R_y(-0.2), YAW_AXIS, m) == pytest.approx(0.2, abs=1e-8)
    H = np.eye(3) + np.outer([0.3, 0.0, 0.0], [0.0, 0.0, 1.0]) / 3.0
    phi = 2.0 * math.atan(0.05)
    assert np.linalg.svd(H - R_y(phi), compute_uv=False)[1] == pytest.approx(0.0, abs=1e-12)  # the other root
    assert homography_yaw(H, YAW_AXIS, m) == pytest.approx(0.0, abs=1e-8)


def test_yaw_decoupled_error_separates_yaw_and_translation():
    """Pure yaw H = R_y(0.2), m* on the axis: e_v' = 0 (the paper's e_v = (sin 0.2, 0, cos 0.2 − 1)),
    e_w' = e_w = (0, 2 sin 0.2, 0).  Pure lateral translation (as above): all of it stays in e_v' =
    (0.1, 0, 0) and e_w' = 0 (the paper's e_w = n × t / d = (0, 0.1, 0) would turn the drone).  Both:
    H = R + t nᵀ/d gives e_v' = Rᵀ t (nᵀ m*)/d and e_w' = 2 sin θ a."""
    s = math.sin(0.2)
    theta = homography_yaw(R_y(0.2), YAW_AXIS, [[-0.3, 0.0], [0.3, 0.1], [0.0, -0.2]])
    assert yaw_decoupled_error(R_y(0.2), (0.0, 0.0), YAW_AXIS, theta) == pytest.approx([0, 0, 0, 0, 2.0 * s, 0], abs=1e-8)
    assert task_error(R_y(0.2), (0.0, 0.0)) == pytest.approx([s, 0.0, math.cos(0.2) - 1.0, 0.0, 2.0 * s, 0.0], abs=1e-12)
    H = np.eye(3) + np.outer([0.3, 0.0, 0.0], [0.0, 0.0, 1.0]) / 3.0
    assert yaw_decoupled_error(H, (0.0, 0.0, 1.0), 2.0 * YAW_AXIS, 0.0) == pytest.approx([0.1, 0, 0, 0, 0, 0], abs=1e-12)
    t, n, R = np.array([0.2, 0.0, -0.1]), np.array([0.0, 0.0, 1.0]), R_y(-0.25)
    e = yaw_decoupled_error(R + np.outer(t, n) / 2.0, (0.1, 0.05), YAW_AXIS, 0.25)
    assert e[:3] == pytest.approx(R.T @ t * (n @ [0.1, 0.05, 1.0]) / 2.0, abs=1e-12)
    assert e[3:] == pytest.approx([0.0, -2.0 * math.sin(0.25), 0.0], abs=1e-12)
    with pytest.raises(ValueError, match="non-zero"):
        yaw_decoupled_error(H, (0.0, 0.0), np.zeros(3), 0.0)


def test_yaw_decoupled_law_turns_toward_a_yawed_keyframe_without_sliding_sideways():
    """At the keyframe's position but 16° short of its heading (one step of the shipped oval's curve),
    the paper's law (3) commands a sideways velocity about as large as the yaw rate; the decoupled
    error leaves the yaw rate and (almost) no sideways velocity."""
    X = wall_points()
    e, _, H = error_at(X, (0.0, 0.0, 1.0, -0.28), (0.0, 0.0, 1.0, 0.0))
    kf = project(X, *camera_pose(0.0, 0.0, 1.0, 0.0))
    m_star = normalize_pixels(kf[list(largest_triangle(kf))], K).mean(axis=0)
    ad = twist_adjoint(transform(R_FLU_OPTICAL, [0.0, 0.0, 0.0]))
    paper = robot_velocity(homography_control(e, 1.0), ad)
    theta = homography_yaw(H, ad[2, :3], normalize_pixels(project(X, *camera_pose(0.0, 0.0, 1.0, -0.28)), K))
    assert theta == pytest.approx(-0.28, abs=1e-6)  # the current camera is turned right of the keyframe
    decoupled = robot_velocity(homography_control(yaw_decoupled_error(H, m_star, ad[2, :3], theta), 1.0), ad)
    assert paper[3] > 0.2 and decoupled[3] == pytest.approx(paper[3])  # turns left toward the keyframe
    assert abs(paper[1]) > 0.2  # the paper's law slides sideways as fast
    assert abs(decoupled[1]) < 0.1 * abs(paper[1])
