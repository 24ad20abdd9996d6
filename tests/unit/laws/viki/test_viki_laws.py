"""ViKi-HyCo geometry and the one-tick law (tasks/viki/laws.py), without a simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar
from taskflow_tasks.core.hybrid import smooth_velocity
from taskflow_tasks.ground.car_kinematics import car_command, kinematic_control
from taskflow_tasks.viki.bbox_target import desired_bbox, static_desired_bbox
from taskflow_tasks.viki.car_visual_servo import car_vs_velocity
from taskflow_tasks.viki.image_features import bbox_features
from taskflow_tasks.viki.laws import (
    ServoInputs,
    desired_centre,
    goal_heading,
    kinematic_target,
    mgbm_depth,
    object_base,
    object_point,
    reverse_control,
    saturate_twist,
    viki_velocity,
)

RP = Racecar(Racecar.Params()).params
K = (468.94, 468.94, 320.0, 179.0)
T_REAR = RP.rear_camera.T_body_camera()
T_FRONT = RP.front_camera.T_body_camera()
LAM = np.array([0.85, 1.05, 1.0, 1.0, 1.0])
KW = dict(intrinsics=K, T_body_camera=T_REAR, lam=LAM, k1=np.array([1.0, 2.0]), d=RP.wheelbase, wheelbase=RP.wheelbase,
          v_max=RP.v_max, psi_max=RP.psi_max)


def project(T_body_camera, P):
    Pc = T_body_camera[:3, :3].T @ (np.asarray(P, float) - T_body_camera[:3, 3])
    return np.array([K[0] * Pc[0] / Pc[2] + K[2], K[1] * Pc[1] / Pc[2] + K[3]]), Pc[2]


@pytest.mark.parametrize("T_body_camera, P", [(T_REAR, (-1.2, 0.15, 0.06)), (T_FRONT, (1.6, -0.3, 0.1))])
def test_eq18_object_point_round_trips_a_projected_point(T_body_camera, P):
    uv, Z = project(T_body_camera, P)
    bbox = (uv[0] - 10, uv[1] - 20, uv[0] + 10, uv[1] + 20)
    np.testing.assert_allclose(object_point(bbox, Z, K, T_body_camera), P, atol=1e-9)


@pytest.mark.parametrize("T_body_camera, goal", [(T_REAR, (-0.9, 0.0)), (T_REAR, (-1.1, 0.2)), (T_FRONT, (1.0, 0.0))])
def test_box_at_the_desired_centre_means_the_base_estimate_is_at_the_goal(T_body_camera, goal):
    r, z_c = 0.04, 0.12
    c = desired_centre(goal, r, z_c, K, T_body_camera)
    # the visible surface point that projects there, at the object's half-width in front of the axis
    cam = T_body_camera[:2, 3]
    u = (np.asarray(goal) - cam) / np.linalg.norm(np.asarray(goal) - cam)
    P = np.array([*(np.asarray(goal) - r * u), z_c])
    uv, Z = project(T_body_camera, P)
    np.testing.assert_allclose(uv, c, atol=1e-9)
    half_w = r * K[0] / Z
    B, r_est, z_est = object_base((c[0] - half_w, c[1] - 15, c[0] + half_w, c[1] + 15), Z, K, T_body_camera)
    np.testing.assert_allclose(B, goal, atol=1e-9)
    assert r_est == pytest.approx(r) and z_est == pytest.approx(z_c)


def test_desired_centre_refuses_a_goal_behind_the_camera():
    with pytest.raises(ValueError, match="behind the camera"):
        desired_centre((1.0, 0.0), 0.03, 0.05, K, T_REAR)


@pytest.mark.parametrize("goal", [(1.0, 0.0), (-0.9, 0.0), (-0.9, 0.3)])
def test_kinematic_target_is_the_control_point_of_the_goal_pose(goal):
    O = np.array([2.0, 1.0])
    pose = np.array([0.3, -0.4, 0.2])
    th = goal_heading(pose, O, goal)
    h = kinematic_target(O, goal, th, 0.325)
    p = h - 0.325 * np.array([math.cos(th), math.sin(th)])  # rear axle of the goal pose
    c, s = math.cos(th), math.sin(th)
    rel = np.array([[c, s], [-s, c]]) @ (O - p)  # object in that pose's frame
    np.testing.assert_allclose(rel, goal, atol=1e-12)


def test_goal_heading_faces_the_object_ahead_and_away_behind():
    pose, O = (0.0, 0.0, 1.0), (1.0, 1.0)
    assert goal_heading(pose, O, (1.0, 0.0)) == pytest.approx(math.pi / 4)
    assert math.remainder(goal_heading(pose, O, (-0.9, 0.0)) - (math.pi / 4 + math.pi), 2 * math.pi) == pytest.approx(0)


def test_saturate_twist_keeps_the_curvature():
    out = saturate_twist([2.0, 1.0], 0.5, 0.72)
    assert out[0] == pytest.approx(0.5) and out[1] / out[0] == pytest.approx(0.5)
    out = saturate_twist([0.1, -3.0], 0.5, 0.72)
    assert abs(out[1]) == pytest.approx(0.72) and out[1] / out[0] == pytest.approx(-30.0)
    np.testing.assert_array_equal(saturate_twist([0.1, 0.2], 0.5, 0.72), [0.1, 0.2])


def test_mgbm_depth_from_areas():
    assert mgbm_depth((0, 0, 10, 20), (0, 0, 20, 40), 1.0) == pytest.approx(2.0)


def _inputs(**kw):
    base = dict(pose=np.array([0.1, 0.2, 0.3]), detected=True, bbox=np.array([300.0, 120.0, 330.0, 190.0]),
                Z_o=1.4, Z_d=1.1, centre=np.array([320.0, 170.0]), target=np.array([-1.0, 0.5]),
                v_prev=np.zeros(2))
    base.update(kw)
    return ServoInputs(**base)


def test_detected_hybrid_tick_is_eq19_then_eq24_then_limits():
    inp = _inputs()
    out = viki_velocity(inp, smoothing=False, **KW)
    box_d = desired_bbox(inp.bbox, inp.Z_o, inp.Z_d, inp.centre)
    f, fd = bbox_features(inp.bbox), bbox_features(box_d)
    V = car_vs_velocity(f, fd, inp.Z_o, K, T_REAR[:3, :3], T_REAR[:3, 3], LAM)
    V = saturate_twist(V, RP.v_max, RP.v_max * math.tan(RP.psi_max) / RP.wheelbase)
    assert out.used_vs
    np.testing.assert_allclose(out.V, V)
    np.testing.assert_allclose(out.f_d, fd)
    assert out.feature_error == pytest.approx(np.max(np.abs(f - fd)))
    assert (out.v_cmd, out.psi) == pytest.approx(car_command(V[0], V[1], RP.wheelbase, RP.v_max, RP.psi_max))


def test_undetected_hybrid_tick_is_the_kinematic_controller():
    inp = _inputs(detected=False)
    out = viki_velocity(inp, smoothing=False, **KW)
    V = np.array(kinematic_control(inp.pose, inp.target, KW["k1"], RP.wheelbase))
    V = saturate_twist(V, RP.v_max, RP.v_max * math.tan(RP.psi_max) / RP.wheelbase)
    assert not out.used_vs and out.feature_error is None
    np.testing.assert_allclose(out.V, V)


def test_undetected_backward_tick_is_the_reversed_kinematic_controller():
    inp = _inputs(detected=False, reverse=True)
    out = viki_velocity(inp, smoothing=False, **KW)
    V = np.array(reverse_control(inp.pose, inp.target, KW["k1"], RP.wheelbase))
    V = saturate_twist(V, RP.v_max, RP.v_max * math.tan(RP.psi_max) / RP.wheelbase)
    np.testing.assert_allclose(out.V, V)
    # it is eq. 4 for the car turned around: the same law with heading + pi and the speed negated
    flipped = inp.pose + np.array([0.0, 0.0, math.pi])
    v, w = kinematic_control(flipped, inp.target, KW["k1"], RP.wheelbase)
    assert reverse_control(inp.pose, inp.target, KW["k1"], RP.wheelbase) == pytest.approx((-v, w))


def test_hybrid_without_detection_or_target_holds_still():
    out = viki_velocity(_inputs(detected=False, target=None), **KW)
    assert out.v_cmd == 0.0 and np.all(out.V == 0.0)


def test_vs_only_stops_without_detection_even_with_a_target():
    out = viki_velocity(_inputs(detected=False), mode="vs_only", **KW)
    assert out.v_cmd == 0.0 and not out.used_vs
    det = viki_velocity(_inputs(), mode="vs_only", smoothing=False, **KW)
    hyb = viki_velocity(_inputs(), mode="hybrid", smoothing=False, **KW)
    np.testing.assert_allclose(det.V, hyb.V)


def test_mgbm_uses_the_static_box_of_the_known_size():
    inp = _inputs()
    out = viki_velocity(inp, mode="mgbm", object_size=(0.08, 0.25), smoothing=False, **KW)
    box_d = static_desired_bbox((0.08, 0.25), inp.Z_d, K, inp.centre)
    np.testing.assert_allclose(out.f_d, bbox_features(box_d))
    with pytest.raises(ValueError, match="object_size"):
        viki_velocity(inp, mode="mgbm", **KW)


def test_eq26_smoothing_damps_from_the_previous_output():
    inp = _inputs(v_prev=np.array([0.1, 0.0]))
    raw = viki_velocity(inp, smoothing=False, **KW)
    out = viki_velocity(inp, smoothing=True, **KW)
    np.testing.assert_allclose(out.V, smooth_velocity(raw.V, [0.1, 0.0]))
    assert np.all(np.abs(out.V) <= np.abs(raw.V) + 1e-15)


def test_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="mode"):
        viki_velocity(_inputs(), mode="nope", **KW)
