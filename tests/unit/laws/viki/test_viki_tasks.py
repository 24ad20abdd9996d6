"""The viki_hyco and viki_rotate Task classes fed synthetic detections (no simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_robots.racecar import Racecar
from taskflow_tasks.ground.car_goto import CarGains
from taskflow_tasks.ground.car_kinematics import kinematic_control
from taskflow_tasks.viki.evidence import cut_box_near_point
from taskflow_tasks.viki.hyco import MEM_OBJECT, MEM_TARGET, ViKiGains, ViKiHyCo, ViKiHyCoParams
from taskflow_tasks.viki.laws import desired_centre, object_base, reverse_control, saturate_twist
from taskflow_tasks.viki.rotation import ViKiRotate, k_turn_legs

from taskflow.api import Observation
from taskflow.messages import Detection
from taskflow.testing import task_context

ROBOT = Racecar(Racecar.Params())
RP = ROBOT.params
K = (468.94, 468.94, 320.0, 179.0)
REAR = dict(lam=(0.85, 1.05, 1.0, 1.0, 1.0), k1=(1.0, 2.0))
W_MAX = RP.v_max * math.tan(RP.psi_max) / RP.wheelbase


def make_task(memory=None, t=0.0, gains=REAR, **params):
    p = dict(camera="rear", desired=(-0.9, 0.0), smoothing=False)
    p.update(params)
    ctx = task_context(ViKiHyCo, ViKiHyCoParams(**p), ROBOT, {"gains": ViKiGains(**gains)}, t=t, memory=memory)
    return ViKiHyCo(ctx)


def det(t, bbox=(300.0, 110.0, 340.0, 190.0), depth=1.3, camera="rear", zd=1.25):
    return Detection(stamp=t, frame=f"{camera}_camera", camera=camera, seq=int(t * 15), bbox=bbox, depth=depth,
                     intrinsics=K, width=640, height=360, depth_at=lambda u, v: zd, depth_in=lambda box: zd)


def obs(t, detection=None, pose=(0.0, 0.0, 0.0)):
    sensors = {} if detection is None else {"detection": detection}
    return Observation(t=t, state={"pose": np.array(pose, float), "v": 0.0, "steer": 0.0}, sensors=sensors)


def test_a_detection_drives_eq24_toward_the_desired_box_and_selects_the_camera():
    task = make_task()
    d = det(0.0)
    r = task.step(obs(0.0, d))
    assert r.sensors == ("rear_camera",) and set(r.command) == {"v", "steer"}
    assert r.metrics["detected"] == 1.0 and task.last.used_vs
    # desired centre: the object's measured base would be at the goal
    T = RP.rear_camera.T_body_camera()
    _, rad, z_c = object_base(d.bbox, d.depth, K, T)
    c = desired_centre((-0.9, 0.0), rad, z_c, K, T)
    fd = task.last.f_d
    assert 0.5 * (fd[0] + fd[4]) == pytest.approx(c[0]) and 0.5 * (fd[1] + fd[5]) == pytest.approx(c[1])
    # eq. 19: size k = Z_o / Z_d times the current box
    assert (fd[4] - fd[0]) == pytest.approx(40.0 * 1.3 / 1.25)
    assert r.metrics["feature_error"] == pytest.approx(task.last.feature_error)


@pytest.mark.parametrize("camera", ["rear", "front"])
def test_eq25_switches_between_visual_and_kinematic_laws(camera):
    front = camera == "front"
    gains = dict(lam=(0.85, 0.3, 1, 1, 1), k1=(2.0, 1.0)) if front else REAR
    task = make_task(camera=camera, desired=(1.0, 0.0) if front else (-0.9, 0.0), gains=gains)
    seq = [True, True, False, False, True, False]
    pose = np.array([0.0, 0.0, 0.1])
    used = []
    for k, seen in enumerate(seq):
        t = k / 20
        r = task.step(obs(t, det(t, camera=camera) if seen else None, pose))
        used.append(r.metrics["detected"])
        if not seen:
            # goal ahead: eq. 4 driving forward; goal behind: eq. 4 on the car seen backwards
            law = kinematic_control if front else reverse_control
            V = saturate_twist(law(pose, task.target, gains["k1"], RP.wheelbase), RP.v_max, W_MAX)
            np.testing.assert_allclose(task.last.V, V)
            assert "feature_error" in r.metrics  # the latest detection's error stays published
            # pos_error: the controlled point (d ahead, or d behind when reversing) to the target
            d = RP.wheelbase if front else -RP.wheelbase
            h = pose[:2] + d * np.array([math.cos(pose[2]), math.sin(pose[2])])
            assert r.metrics["pos_error"] == pytest.approx(np.hypot(*(task.target - h)))
    assert used == [1.0 if s else 0.0 for s in seq]


def test_first_detection_fixes_the_object_and_later_states_use_it():
    memory: dict = {}
    task = make_task(memory, target_update="first")  # the paper's rule (the default follows the evidence)
    task.step(obs(0.0, det(0.0)))
    O1 = MEM_OBJECT(memory).copy()
    target1 = task.target.copy()
    task.step(obs(0.05, det(0.05, bbox=(200.0, 60.0, 230.0, 120.0), depth=2.0)))  # the box moved a lot
    np.testing.assert_array_equal(MEM_OBJECT(memory), O1)
    np.testing.assert_array_equal(task.target, target1)
    # a later state (same mission memory) has a target before it sees anything, and drives toward it
    later = make_task(memory, t=1.0, gains=dict(lam=(0.85, 0.3, 1, 1, 1), k1=(2.0, 1.0)))
    r = later.step(obs(1.0, None, pose=(0.5, 0.2, 0.0)))
    assert r.metrics["detected"] == 0.0 and "pos_error" in r.metrics and abs(r.command["v"][0]) > 0.0
    np.testing.assert_allclose(MEM_TARGET(memory), later.target)
    # the object seen from the new pose, in the robot frame, comes from the memory
    assert (r.metrics["object_x"], r.metrics["object_y"]) == pytest.approx((O1[0] - 0.5, O1[1] - 0.2))


def test_target_update_latest_re_anchors_on_every_detection():
    memory: dict = {}
    task = make_task(memory, target_update="latest")
    task.step(obs(0.0, det(0.0)))
    O1 = MEM_OBJECT(memory).copy()
    task.step(obs(0.05, det(0.05, bbox=(200.0, 60.0, 230.0, 120.0), depth=2.0)))
    assert not np.allclose(MEM_OBJECT(memory), O1)


def test_vs_only_stops_when_the_detection_drops():
    task = make_task(mode="vs_only")
    assert task.step(obs(0.0, det(0.0))).command["v"][0] != 0.0
    r = task.step(obs(0.05, None))
    assert r.command["v"][0] == 0.0 and r.metrics["detected"] == 0.0


def test_other_camera_and_stale_frames_count_as_no_detection():
    task = make_task()
    r = task.step(obs(0.0, det(0.0, camera="front")))
    assert r.metrics["detected"] == 0.0 and not MEM_OBJECT.present(task.memory)
    r = task.step(obs(0.5, det(0.1)))  # 0.4 s old > max_age
    assert r.metrics["detected"] == 0.0 and not MEM_OBJECT.present(task.memory)


def test_no_detection_at_the_start_raises_no_target_after_the_timeout():
    task = make_task(search_timeout=1.0)
    assert task.step(obs(0.5)).events == ()
    r = task.step(obs(1.0))
    assert r.events == ("no_target",) and r.command["v"][0] == 0.0
    # with the object already in memory there is something to drive to: no event
    task2 = make_task({MEM_OBJECT.name: np.array([-2.0, 0.0])}, search_timeout=1.0)
    assert task2.step(obs(1.5)).events == ()


def test_gain_and_parameter_validation():
    with pytest.raises(ValidationError, match="5 gains"):
        ViKiGains(lam=(0.85, 0.3, 1.0))
    with pytest.raises(ValidationError, match="> 0"):
        ViKiGains(lam=(0.85, -0.3, 1.0, 1.0, 1.0))
    with pytest.raises(ValidationError, match="k1"):
        ViKiGains(lam=(0.85, 0.3, 1.0, 1.0, 1.0), k1=(0.0, 1.0))
    with pytest.raises(ValidationError, match="object_size"):
        ViKiHyCoParams(camera="front", desired=(1.0, 0.0), mode="mgbm")
    with pytest.raises(ValidationError):
        ViKiHyCoParams(camera="top", desired=(1.0, 0.0))


# -- the rotation -----------------------------------------------------------------------------------


def test_k_turn_ends_behind_the_start_facing_away():
    r, d = 0.8, RP.wheelbase
    legs = k_turn_legs((1.0, 2.0), 0.5, r, 1, d)
    (p1, dir1), (p2, dir2) = legs
    assert (dir1, dir2) == (-1.0, 1.0)
    c, s = math.cos(0.5), math.sin(0.5)
    end_rear = np.array([1.0, 2.0]) + (-2 * r) * np.array([c, s])
    np.testing.assert_allclose(p2[-1], end_rear + d * np.array([-c, -s]), atol=1e-12)  # forward point, heading + pi
    # the legs join at the cusp: rear axle at (-r, -r) in the path frame, heading +90 deg
    cusp_rear = np.array([1.0, 2.0]) + np.array([[c, -s], [s, c]]) @ np.array([-r, -r])
    heading = 0.5 + math.pi / 2
    np.testing.assert_allclose(p1[-1], cusp_rear - d * np.array([math.cos(heading), math.sin(heading)]), atol=1e-12)
    np.testing.assert_allclose(p2[0], cusp_rear + d * np.array([math.cos(heading), math.sin(heading)]), atol=1e-12)


def test_reverse_control_backs_toward_a_point_behind():
    v, w = reverse_control(np.array([0.0, 0.0, 0.0]), np.array([-1.325, 0.0]), np.array([1.0, 1.0]), 0.325)
    assert v < 0.0 and w == pytest.approx(0.0)


def make_rotate(memory, **params):
    ctx = task_context(ViKiRotate, ViKiRotate.Params(**params), ROBOT, {"gains": CarGains(k1=(2.0, 2.0))},
                       memory=memory)
    return ViKiRotate(ctx)


def test_rotation_plans_from_the_memory_object_and_starts_reversing():
    memory = {MEM_OBJECT.name: np.array([1.0, 0.0])}
    task = make_rotate(memory)
    r = task.step(obs(0.0))
    assert r.command["v"][0] < 0.0 and r.sensors == ()
    np.testing.assert_allclose(memory["viki.rotation_target"], [-1.6 - RP.wheelbase, 0.0], atol=1e-12)
    assert r.metrics["pos_error"] == pytest.approx(1.6 + RP.wheelbase + RP.wheelbase)
    assert r.metrics["leg"] == 0.0


def test_the_rotation_never_drives_the_body_toward_the_object_within_the_keep_out_margin():
    """The K-turn's first leg reverses; with the object (memory) 0.6 m behind the rear axle, 0.55 m from the
    body, reversing drives toward it: within a 1 m margin the keep-out turns the command around, with
    margin 0 (off) it passes."""
    cmds = {}
    for margin in (0.0, 1.0):
        memory = {MEM_OBJECT.name: np.array([1.0, 0.0])}
        task = make_rotate(memory, keep_out_margin=margin)
        task.step(obs(0.0))  # plans the K-turn with the object ahead
        memory[MEM_OBJECT.name] = np.array([-0.6, 0.0])
        cmds[margin] = task.step(obs(0.05)).command["v"][0]
    assert cmds[0.0] < 0.0 and cmds[1.0] == -cmds[0.0]


def test_rotation_without_an_object_raises_no_target():
    r = make_rotate({}).step(obs(0.0))
    assert r.events == ("no_target",) and r.command["v"][0] == 0.0


def test_rotation_radius_below_the_car_minimum_is_refused():
    with pytest.raises(ValueError, match="minimum turning radius"):
        make_rotate({}, radius=0.3)


@pytest.mark.parametrize("zd", ["window", "pixel"])
def test_zd_is_read_at_the_desired_centre(zd):
    calls = []
    d = Detection(stamp=0.0, frame="rear_camera", camera="rear", seq=0, bbox=(300.0, 110.0, 340.0, 190.0), depth=1.3,
                  intrinsics=K, width=640, height=360, depth_at=lambda u, v: calls.append(("pixel", (u, v))) or 1.2,
                  depth_in=lambda box: calls.append(("window", box)) or 1.2)
    task = make_task(zd=zd)
    task.step(obs(0.0, d))
    fd = task.last.f_d
    c = (0.5 * (fd[0] + fd[4]), 0.5 * (fd[1] + fd[5]))
    assert [k for k, _ in calls] == [zd]
    if zd == "pixel":
        assert calls[0][1] == pytest.approx(c)
    else:  # the current box (40 x 80 px) moved to the desired centre
        assert calls[0][1] == pytest.approx((c[0] - 20, c[1] - 40, c[0] + 20, c[1] + 40))
    assert fd[4] - fd[0] == pytest.approx(40.0 * 1.3 / 1.2)  # eq. 19, k = Z_o / Z_d


@pytest.mark.parametrize("camera", ["rear", "front"])
def test_the_reported_camera_twist_is_the_derivative_of_the_camera_pose(camera):
    """viki_hyco's camera-twist metrics use the robot → camera map (eq. 20-22 as meant); the camera → robot
    map (``twist_adjoint``, eq. 22 as printed) would give other numbers: drive the car along an arc and
    differentiate the camera pose (car: x forward, yaw rate about z; the body twist is [v, 0, 0, 0, 0, w])."""
    from taskflow import spatial

    task = make_task(camera=camera)
    T_body_camera = getattr(RP, f"{camera}_camera").T_body_camera()
    V = np.array([0.3, 0.8])
    h = 1e-6

    def T_world_camera(s):
        th = V[1] * s
        x, y = (V[0] / V[1]) * math.sin(th), (V[0] / V[1]) * (1.0 - math.cos(th))
        return spatial.transform_xyz_yaw(x, y, 0.0, th) @ T_body_camera

    X = spatial.inverse(T_world_camera(0.0)) @ (T_world_camera(h) - T_world_camera(-h)) / (2 * h)
    numeric = np.r_[X[:3, 3], spatial.vee(X[:3, :3])]
    np.testing.assert_allclose(task._cam_twist @ V, numeric, atol=1e-6)
    assert not np.allclose(spatial.twist_adjoint(T_body_camera)[:, [0, 5]] @ V, numeric, atol=1e-3)


def test_a_box_cut_by_the_border_steers_the_servo_but_does_not_move_the_target():
    memory: dict = {}
    task = make_task(memory)
    task.step(obs(0.0, det(0.0)))
    O1, target1 = MEM_OBJECT(memory).copy(), task.target.copy()
    # the object half out of view at the left border: biased box, not evidence of where the object is
    r = task.step(obs(0.05, det(0.05, bbox=(-0.5, 100.0, 12.0, 190.0), depth=1.0)))
    assert r.metrics["detected"] == 1.0 and task.last.used_vs  # the servo still turns toward it
    np.testing.assert_array_equal(MEM_OBJECT(memory), O1)
    np.testing.assert_array_equal(task.target, target1)
    # 1 px from the border is cut too (border_px = 2); 3 px is not and re-anchors
    task.step(obs(0.1, det(0.1, bbox=(0.5, 100.0, 40.0, 190.0), depth=1.0)))
    np.testing.assert_array_equal(MEM_OBJECT(memory), O1)
    task.step(obs(0.15, det(0.15, bbox=(2.5, 100.0, 40.0, 190.0), depth=1.0)))
    assert not np.allclose(MEM_OBJECT(memory), O1)


def test_only_a_cut_box_still_gives_a_first_target():
    memory: dict = {}
    task = make_task(memory)
    r = task.step(obs(0.0, det(0.0, bbox=(-0.5, 100.0, 12.0, 190.0), depth=1.0)))
    assert MEM_OBJECT.present(memory) and task.target is not None  # better than no target at all
    assert "goal_error" not in r.metrics and "view_shift" not in r.metrics  # but it is no evidence
    # where: the floor point under the box's inner column (issue 25), not eq. 18 on the cut box
    T = RP.rear_camera.T_body_camera()
    np.testing.assert_allclose(MEM_OBJECT(memory), cut_box_near_point((-0.5, 100.0, 12.0, 190.0), 640, 360, 2.0, K, T))
    # while only cut boxes fixed it, each new one re-anchors it; a whole box then does, and cut boxes no longer
    task.step(obs(0.05, det(0.05, bbox=(-0.5, 100.0, 30.0, 200.0), depth=1.0)))
    np.testing.assert_allclose(MEM_OBJECT(memory), cut_box_near_point((-0.5, 100.0, 30.0, 200.0), 640, 360, 2.0, K, T))
    task.step(obs(0.1, det(0.1)))
    whole = MEM_OBJECT(memory).copy()
    task.step(obs(0.15, det(0.15, bbox=(-0.5, 100.0, 12.0, 190.0), depth=1.0)))
    np.testing.assert_array_equal(MEM_OBJECT(memory), whole)


def test_goal_error_averages_the_whole_detections_near_the_current_view():
    task = make_task()
    T = RP.rear_camera.T_body_camera()
    d1, d2 = det(0.0), det(0.05, bbox=(302.0, 110.0, 342.0, 190.0))
    B1, B2 = (object_base(d.bbox, d.depth, K, T)[0] for d in (d1, d2))
    r = task.step(obs(0.0, d1))
    assert r.metrics["goal_error"] == pytest.approx(float(np.hypot(*(B1 - (-0.9, 0.0)))))
    assert r.metrics["view_shift"] == 0.0
    r = task.step(obs(0.05, d2))  # the mean of both frames' object positions
    assert r.metrics["goal_error"] == pytest.approx(float(np.hypot(*(0.5 * (B1 + B2) - (-0.9, 0.0)))))
    # no detection, the car moved 1 cm straight back: the object is 1 cm nearer the goal point...
    r = task.step(obs(0.1, None, pose=(-0.01, 0.0, 0.0)))
    B = 0.5 * (B1 + B2)
    assert r.metrics["goal_error"] == pytest.approx(float(np.hypot(B[0] + 0.01 + 0.9, B[1])))
    assert r.metrics["view_shift"] == pytest.approx(0.01)  # ...and the view has shifted by 1 cm
    # turning by 0.03 rad swings the goal point 0.9 m behind by 2.7 cm: beyond the 2 cm evidence window
    r = task.step(obs(0.15, None, pose=(0.0, 0.0, 0.03)))
    assert r.metrics["view_shift"] == pytest.approx(2 * 0.9 * math.sin(0.015))
    assert "goal_error" not in r.metrics  # the detections no longer describe this view


def test_keep_out_turns_the_fallback_around_within_the_margin():
    """Front camera, goal 1 m ahead, object 2 m ahead in memory, no detection: eq. 4 drives forward. With
    the car's body given and a margin wider than the 1.59 m gap, the same command is turned around."""
    front = dict(camera="front", desired=(1.0, 0.0), gains=dict(lam=(0.85, 0.3, 1, 1, 1), k1=(2.0, 1.0)))
    free = make_task({MEM_OBJECT.name: np.array([2.0, 0.0])}, **front)
    r_free = free.step(obs(0.0, None))
    body = (-0.05, 0.41, -0.15, 0.15)
    near = make_task({MEM_OBJECT.name: np.array([2.0, 0.0])}, keep_out_body=body, keep_out_margin=1.6, **front)
    r = near.step(obs(0.0, None))
    assert r_free.command["v"][0] > 0.0 and r.command["v"][0] == pytest.approx(-r_free.command["v"][0])
    assert r.command["steer"][0] == pytest.approx(r_free.command["steer"][0])
    far = make_task({MEM_OBJECT.name: np.array([2.0, 0.0])}, keep_out_body=body, keep_out_margin=1.5, **front)
    assert far.step(obs(0.0, None)).command["v"][0] == pytest.approx(r_free.command["v"][0])


def test_the_tasks_read_what_they_declare_and_a_missing_required_entry_is_an_error():
    """requires and the reads are one set of keys: no silent default for the measured speed or the pose."""
    from taskflow_tasks.core import keys
    from taskflow_tasks.viki.hyco import DETECTION

    from taskflow.specs import MissingObservation, required_specs

    assert set(required_specs(ViKiHyCo.requires)) == {keys.POSE.name, DETECTION.name, keys.SPEED.name}
    assert set(required_specs(ViKiRotate.requires)) == {keys.POSE.name, keys.SPEED.name}
    task = make_task()
    assert task.step(obs(0.0)).metrics["detected"] == 0.0  # the detection is optional: absent is "none yet"
    no_speed = Observation(t=0.0, state={"pose": np.zeros(3)}, sensors={"detection": det(0.0)})
    with pytest.raises(MissingObservation, match="state.v"):
        make_task().step(no_speed)
