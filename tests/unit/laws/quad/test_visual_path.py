"""Perception (ORB/SIFT + RANSAC, largest triangle, LK, colour segmentation) on synthetic images,
the servo law on exact projections, and the load-time checks of the visual-path tasks."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_robots.quadcopter import Quadcopter, QuadcopterParams
from taskflow_sim.quad.scene import generate_texture
from taskflow_tasks.quad.correspondences import landmark_pairs
from taskflow_tasks.quad.feedforward import segment_velocities
from taskflow_tasks.quad.gains import HierarchyGains, PathGains, VisualGains
from taskflow_tasks.quad.homography import (
    intrinsic_matrix,
    largest_triangle,
    normalize_homography,
    normalize_pixels,
    task_error,
)
from taskflow_tasks.quad.law import ServoLaw
from taskflow_tasks.quad.params import KeyframeRef, RematchParams, VisualPathParams
from taskflow_tasks.quad.perception import (
    PointTracker,
    detect,
    estimate_homography,
    make_detector,
    match_keyframe,
    obstacle_edges,
    to_grey,
)
from taskflow_tasks.quad.tracking import image_pairs, match_with_retry

from taskflow.spatial import twist_adjoint

K = intrinsic_matrix(207.8, 207.8, 160.0, 119.0)


@pytest.fixture(scope="module")
def texture() -> np.ndarray:
    bgr = generate_texture(np.random.default_rng(5), 480, 360, 160.0)
    return np.ascontiguousarray(bgr[:, :, ::-1])


def view(texture: np.ndarray, G: np.ndarray) -> np.ndarray:
    """A 320x240 view of the textured plane through the projective map G (texture px → image px)."""
    return cv2.warpPerspective(texture, G, (320, 240), flags=cv2.INTER_LINEAR)


def plane_map(yaw: float, tx: float, tz: float) -> np.ndarray:
    """Texture (a wall 2 m ahead, 160 px/m, centred) seen by a camera yawed by ``yaw`` and moved by
    (tx, tz) (camera x right, z forward): projective map texture px → image px."""
    d = 2.0
    # texture px (u, v) → wall point (X, Y, d) in the reference camera
    A = np.array([[1 / 160.0, 0, -240 / 160.0], [0, 1 / 160.0, -180 / 160.0], [0, 0, 1.0]])
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # world → camera
    t = -R @ np.array([tx, 0.0, tz])
    P = K @ np.column_stack((R[:, 0], R[:, 1], R[:, 2] * d + t))  # [X, Y, 1] → image
    return P @ A


@pytest.mark.parametrize("kind", ["orb", "sift"])
def test_matching_recovers_the_homography(texture, kind):
    G0, G1 = plane_map(0.0, 0.0, 0.0), plane_map(0.08, 0.15, 0.3)
    kf, cur = view(texture, G0), view(texture, G1)
    det = make_detector(kind, 800)
    fk, fc = detect(det, to_grey(kf), kind), detect(det, to_grey(cur), kind)
    c, k = match_keyframe(fk, fc)
    assert len(c) >= 40
    tri = largest_triangle(k)
    assert tuple(tri) == (0, 1, 2)  # sorted: the largest triangle first
    H, inl = estimate_homography(c, k, K)
    G_true = G0 @ np.linalg.inv(G1)  # current image → keyframe image
    H_true = normalize_homography(G_true, K)
    assert np.allclose(H, H_true, atol=0.02)
    assert inl.mean() > 0.9
    m_star = normalize_pixels(k[:3], K).mean(axis=0)
    assert np.linalg.norm(task_error(H, m_star) - task_error(H_true, m_star)) < 0.02


def test_matching_rejects_unrelated_images(texture):
    other = np.ascontiguousarray(generate_texture(np.random.default_rng(99), 320, 240, 160.0)[:, :, ::-1])
    det = make_detector("orb", 800)
    c, _ = match_keyframe(detect(det, to_grey(view(texture, plane_map(0, 0, 0))), "orb"),
                          detect(det, to_grey(other), "orb"))
    assert len(c) < 16
    black = np.zeros((240, 320), np.uint8)
    c, _ = match_keyframe(detect(det, to_grey(view(texture, plane_map(0, 0, 0))), "orb"), detect(det, black, "orb"))
    assert len(c) == 0
    with pytest.raises(ValueError):
        make_detector("surf", 100)


def test_lk_tracking_follows_a_small_motion_and_refine_removes_offsets(texture):
    G0, G1, G2 = plane_map(0, 0, 0), plane_map(0.01, 0.02, 0.05), plane_map(0.015, 0.03, 0.08)
    kf, f1, f2 = (to_grey(view(texture, G)) for G in (G0, G1, G2))
    det = make_detector("orb", 800)
    c, k = match_keyframe(detect(det, kf, "orb"), detect(det, f1, "orb"))
    tr = PointTracker(f1, c + 0.7, k)  # a constant 0.7 px offset, like detector quantisation
    assert tr.track(f2) > 0.8 * len(c)
    truth = cv2.perspectiveTransform(tr.kf.reshape(-1, 1, 2).astype(np.float64), G2 @ np.linalg.inv(G0)).reshape(-1, 2)
    before = np.median(np.linalg.norm(tr.cur - truth, axis=1))
    moved = tr.refine(kf, f2)
    after = np.median(np.linalg.norm(tr.cur - truth, axis=1))
    assert moved > 0.5 * len(tr) and before > 0.5 and after < 0.2
    assert tr.track(np.zeros_like(f2)) < 16  # a black frame loses the points


def test_refine_through_the_plane_homography_removes_drift_far_from_the_keyframe(texture):
    """Up to 1.5 px of drift on every point of a view 0.7 m nearer and 9° turned: searched in the raw
    image the keyframe patches differ in scale and the drift stays; searched in the image warped into
    the keyframe's geometry through the plane's homography, it goes.  Points tracked 5 px off their
    keyframe patch are dropped."""
    G0, G1 = plane_map(0.0, 0.0, 0.0), plane_map(0.15, 0.3, 0.7)
    kf, cur = to_grey(view(texture, G0)), to_grey(view(texture, G1))
    det = make_detector("orb", 800)
    _, k = match_keyframe(detect(det, kf, "orb"), detect(det, cur, "orb"))
    assert len(k) >= 40
    T = G1 @ np.linalg.inv(G0)  # keyframe px → current px

    def truth(kf_px: np.ndarray) -> np.ndarray:
        return cv2.perspectiveTransform(kf_px.reshape(-1, 1, 2).astype(np.float64), T).reshape(-1, 2)

    rng = np.random.default_rng(0)
    angle, size = rng.uniform(0.0, 2.0 * math.pi, len(k)), rng.uniform(0.5, 1.5, len(k))
    drifted = truth(k) + np.column_stack((size * np.cos(angle), size * np.sin(angle)))
    slipped = np.arange(3, 8)
    drifted[slipped] += 5.0

    def error(tr: PointTracker) -> float:
        return float(np.median(np.linalg.norm(tr.cur - truth(tr.kf), axis=1)))

    raw = PointTracker(cur, drifted, k)
    raw.refine(kf, cur)
    assert len(raw) == len(k) and error(raw) > 0.8
    warped = PointTracker(cur, drifted, k)
    moved = warped.refine(kf, cur, np.linalg.inv(T))
    assert len(warped) == len(k) - len(slipped)
    assert not np.isin(k[slipped], warped.kf).all(axis=1).any()
    assert moved >= 0.9 * len(warped) and error(warped) < 0.1


def test_matching_retries_with_a_larger_budget_when_the_view_shares_little(texture):
    """A view turned 29° and moved 1.2 m sideways shares a corner of the keyframe: the 1000 strongest
    keypoints of each image give fewer than min_points matches, the retry with 4x the budget finds
    enough, and they are right."""
    G0, G1 = plane_map(0.0, 0.0, 0.0), plane_map(0.5, 1.2, 0.0)
    kf_img, cur = view(texture, G0), to_grey(view(texture, G1))
    p = RematchParams(keyframe=KeyframeRef(id=0), n_features=1000, retry_scale=4)
    c, _ = match_with_retry({}, kf_img, 0, cur, p.model_copy(update={"retry_scale": 1}))
    assert len(c) < p.min_points
    c, k = match_with_retry({}, kf_img, 0, cur, p)
    assert len(c) >= p.min_points
    truth = cv2.perspectiveTransform(k.reshape(-1, 1, 2).astype(np.float64), G1 @ np.linalg.inv(G0)).reshape(-1, 2)
    assert np.median(np.linalg.norm(c - truth, axis=1)) < 1.0


def test_obstacle_segmentation_edges(texture):
    img = view(texture, plane_map(0, 0, 0)).copy()
    assert obstacle_edges(img) is None  # textures carry no obstacle green
    cv2.rectangle(img, (100, 0), (119, 239), (25, 204, 38), -1)
    det = obstacle_edges(img)
    assert det is not None and det.bbox == (100, 0, 119, 239) and not det.touches_border
    assert det.p1 == (99.5, 119.5) and det.p2 == (119.5, 119.5)
    img2 = img.copy()
    cv2.rectangle(img2, (0, 0), (12, 239), (25, 204, 38), -1)
    cv2.rectangle(img2, (100, 0), (119, 239), (0, 0, 0), -1)
    assert obstacle_edges(img2).touches_border
    blob = view(texture, plane_map(0, 0, 0)).copy()
    cv2.rectangle(blob, (100, 100), (140, 120), (25, 204, 38), -1)  # wide, short: not a column
    assert obstacle_edges(blob) is None


def test_segment_velocities_match_the_scaled_law(texture):
    """Feed-forward (eq. 32) from keyframe images: segment k → k+1 moves forward/right like the
    displacement between the two views."""
    rob = Quadcopter(QuadcopterParams())
    imgs = tuple(view(texture, plane_map(0.0, 0.1 * k, 0.25 * k)) for k in range(3))
    nus = segment_velocities(image_pairs(imgs), K, twist_adjoint(rob.T_body_camera()), VisualGains(lambda_0=1.5, lambda_inf=0.8), 0.75)
    assert len(nus) == 2
    for nu in nus:
        assert nu[0] > 0.0 and nu[1] < 0.0  # forward, and to the right (body y is left)
        assert abs(nu[3]) < 0.05
    assert np.allclose(nus[0], nus[1], atol=0.05)


# ---------------------------------------------------------------------------------------------
# the servo law on exact projections


def test_servo_law_regulates_a_quadcopter_with_exact_points():
    rob = Quadcopter(QuadcopterParams(tau=0.1))
    cam = rob.params.camera
    Kc, Ad_body_camera = cam.K(), twist_adjoint(rob.T_body_camera())
    rng = np.random.default_rng(0)
    X = np.column_stack((np.full(300, 4.0), rng.uniform(-2.5, 2.5, 300), rng.uniform(0, 3, 300)))

    def project(pose):
        R, t = cam.pose_in_world(pose)
        Xc = (X - t) @ R
        uv = Xc[:, :2] / Xc[:, 2:3] * [Kc[0, 0], Kc[1, 1]] + [Kc[0, 2], Kc[1, 2]]
        return uv, (uv[:, 0] > 0) & (uv[:, 0] < 319) & (uv[:, 1] > 0) & (uv[:, 1] < 239)

    key = (1.5, 0.0, 0.5, 0.0)
    kf, ok_k = project(key)
    pose = np.array([0.0, 0.2, 1.0, 0.1])
    params = VisualPathParams(keyframe=KeyframeRef(id=0))
    law = ServoLaw(Kc, Ad_body_camera, (320, 240), params, VisualGains(), HierarchyGains(), PathGains(), 0.0)
    vel, dt = np.zeros(4), 0.04
    for i in range(300):
        cur, ok = project(pose)
        sel = ok & ok_k
        nu, metrics = law(i * dt, cur[sel], kf[sel], None)
        vel += (1 - math.exp(-dt / 0.1)) * (rob.saturate(nu) - vel)
        c, s = math.cos(pose[3]), math.sin(pose[3])
        pose += dt * np.array([c * vel[0] - s * vel[1], s * vel[0] + c * vel[1], vel[2], vel[3]])
    assert metrics["epsilon"] < 0.5
    assert np.linalg.norm(pose[:3] - key[:3]) < 0.01 and abs(pose[3]) < math.radians(0.5)
    assert metrics["h_a"] == 0.0 and metrics["h_t"] == 1.0  # a single keyframe: no h_t (Alg. 1, n = 1)


def test_epsilon_progress_is_the_drop_of_epsilon_over_its_window():
    """``epsilon_progress``: NaN until a window has passed, then ε a window ago minus ε now; flat ε
    gives 0 (the feed-forward stall a mission can end with it)."""
    rob = Quadcopter(QuadcopterParams())
    kf = np.random.default_rng(1).uniform([20, 20], [300, 220], (40, 2))
    params = VisualPathParams(keyframe=KeyframeRef(id=0), progress_window_s=1.0)
    law = ServoLaw(K, twist_adjoint(rob.T_body_camera()), (320, 240), params, VisualGains(), HierarchyGains(), PathGains(), 0.0)
    out = []
    for i in range(100):
        t = i * 0.04
        shift = max(10.0 - 4.0 * t, 2.0)  # ε falls 4 px/s for 2 s, then stays at 2 px
        _, m = law(t, kf + [shift, 0.0], kf, None, H=np.eye(3))
        out.append((t, m["epsilon"], m["epsilon_progress"]))
    assert all(math.isnan(p) for t, _, p in out if t < 1.0 - 1e-9)
    for t, eps, p in out:
        if 1.0 - 1e-9 <= t <= 2.0 + 1e-9:
            assert p == pytest.approx(4.0, abs=1e-6)  # 4 px over the last second
        if t >= 3.0:
            assert eps == pytest.approx(2.0) and p == pytest.approx(0.0, abs=1e-9)


def test_rebase_keeps_the_epsilon_rules_on_the_scale_of_a_grown_point_set():
    """Re-matched points join the set at t = 1.5 s and raise ε by half on that frame: rebased, the
    history still reads as ε falling (progress > 0, no rising count); not rebased, the jump would
    read as ε rising and progress would turn negative for a window."""
    rob = Quadcopter(QuadcopterParams())
    rng = np.random.default_rng(1)
    kf = rng.uniform([20, 20], [300, 220], (40, 2))
    extra = rng.uniform([20, 20], [300, 220], (40, 2))
    params = VisualPathParams(keyframe=KeyframeRef(id=0), path=[KeyframeRef(id=0), KeyframeRef(id=1)],
                              progress_window_s=1.0, feedforward=True)
    runs = {}
    for rebase in (True, False):
        law = ServoLaw(K, twist_adjoint(rob.T_body_camera()), (320, 240), params, VisualGains(), HierarchyGains(), PathGains(), 0.0)
        out = []
        for i in range(100):
            t = i * 0.04
            shift = 20.0 - 4.0 * t
            cur, ref = kf + [shift, 0.0], kf
            if t >= 1.5 - 1e-9:
                cur, ref = np.vstack((cur, extra + [2.0 * shift, 0.0])), np.vstack((kf, extra))
                if rebase and abs(t - 1.52) < 1e-9:
                    law.rebase(1.5)  # (40 shift + 40 x 2 shift) / 80 over shift, on this frame
            _, m = law(t, cur, ref, None, H=np.eye(3))
            out.append((t, m["epsilon_rising"], m["epsilon_progress"]))
        runs[rebase] = out
    after = [(r, p) for t, r, p in runs[True] if t >= 1.52 - 1e-9]
    assert all(r == 0.0 for r, _ in after) and all(p > 0.0 for _, p in after)
    assert any(r > 0.0 for t, r, _ in runs[False] if t >= 1.52 - 1e-9)
    assert any(p < 0.0 for t, _, p in runs[False] if t >= 1.52 - 1e-9)


def test_segment_velocities_from_landmark_views_point_along_the_path():
    """Feed-forward (eq. 32) from the geometric camera's keyframe views (correspondence by id):
    keyframes 0.3 m apart straight ahead give a forward ``nu_p``; a yawed keyframe a turn."""
    from types import SimpleNamespace

    rob = Quadcopter(QuadcopterParams())
    cam = rob.params.camera
    Kc = cam.K()
    X = np.column_stack((np.full(400, 3.0), np.random.default_rng(2).uniform(-2, 2, 400),
                         np.random.default_rng(3).uniform(0, 2.5, 400)))

    def view(x, yaw):
        R, t = cam.pose_in_world((x, 0.0, 1.0, yaw))
        Xc = (X - t) @ R
        uv = Xc[:, :2] / Xc[:, 2:3] * [Kc[0, 0], Kc[1, 1]] + [Kc[0, 2], Kc[1, 2]]
        ok = np.flatnonzero((uv[:, 0] > 0) & (uv[:, 0] < 319) & (uv[:, 1] > 0) & (uv[:, 1] < 239))
        return SimpleNamespace(ids=ok, uv=uv[ok])

    nus = segment_velocities(landmark_pairs((view(0.0, 0.0), view(0.3, 0.0), view(0.3, 0.25))), Kc, twist_adjoint(rob.T_body_camera()),
                             VisualGains(lambda_0=1.5, lambda_inf=0.8), 0.75)
    assert nus[0][0] > 0.02 and abs(nus[0][1]) < 0.2 * nus[0][0] and abs(nus[0][3]) < 0.01
    assert nus[1][3] > 0.02  # yaw left (+z)
    # the yawed segment under the paper's law (3) also slides sideways (e_v holds the rotation); with the
    # yaw decoupled (homography.yaw_decoupled_error) it turns in place, as the taught segment does
    decoupled = segment_velocities(landmark_pairs((view(0.3, 0.0), view(0.3, 0.25))), Kc, twist_adjoint(rob.T_body_camera()),
                                 VisualGains(lambda_0=1.5, lambda_inf=0.8, yaw_decoupling=True), 0.75)
    # (what is left sideways is the camera's own swing: it sits 0.17 m ahead of the yaw axis)
    assert nus[1][1] > 0.1 and decoupled[0][3] > 0.02
    assert abs(decoupled[0][1]) < 0.25 * nus[1][1] and abs(decoupled[0][0]) < 0.01


# ---------------------------------------------------------------------------------------------
# load-time checks


def test_feedforward_needs_two_keyframes():
    path = [{"id": 0}]
    with pytest.raises(ValidationError, match="at least two keyframes"):
        VisualPathParams(keyframe=path[0], path=path, feedforward=True)
    VisualPathParams(keyframe=path[0], path=path + [{"id": 1}], feedforward=True)


def test_keyframe_must_belong_to_its_path():
    path = [{"id": 0}, {"id": 1, "sigma": 0.1}]
    with pytest.raises(ValidationError, match="not entry 1"):
        VisualPathParams(keyframe={"id": 1, "sigma": 0.2}, path=path)
    p = VisualPathParams(keyframe=path[1], path=path)
    assert p.is_last and p.n_keyframes == 2


def test_the_taught_pose_does_not_travel_into_the_task():
    """A robot has its keyframe images, not the poses they were taught at (the world's ground truth)."""
    with pytest.raises(ValidationError, match="pose"):
        VisualPathParams(keyframe={"id": 0, "pose": [1, 0, 1, 0]})


@pytest.mark.parametrize(
    "model, values, message",
    [
        (VisualGains, {"lambda_0": 0.1, "lambda_inf": 2.8}, "lambda_0"),
        (VisualGains, {"lambda_0": -1.0}, "greater than 0"),
        (VisualGains, {"lambda_0_slope": 0.0}, "greater than 0"),
        (VisualGains, {"v_offset": [0, -1, 0]}, "v_offset"),
        (HierarchyGains, {"sigma": 0.0}, "greater than 0"),
        (HierarchyGains, {"lambda_a": -0.01}, "greater than 0"),
        (PathGains, {"h0": 1.5}, "less than or equal to 1"),
        (PathGains, {"gamma": -0.1}, "greater than or equal to 0"),
        (PathGains, {"p": 2.0}, "less than or equal to 1"),
    ],
)
def test_gains_outside_their_range_are_refused(model, values, message):
    with pytest.raises(ValidationError, match=message):
        model(**values)
