"""The screw_conveyor world on PyBullet, judged from its ground truth: part motion, platform, marker
events and perception (both modes), the F/T sensor, and the screwdriver's coupling rule."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest
from taskflow_robots.mobile_iiwa import MobileIiwa
from taskflow_sim.screw.world import ScrewConveyor, ScrewdriverParams
from taskflow_tasks.core import pbvs

from taskflow import spatial
from taskflow.registry import WORLDS

ROBOT = MobileIiwa(MobileIiwa.Params())
DT = 1.0 / 100.0  # the missions' control rate
HOLD = {"base_twist": np.zeros(3), "arm_dq": np.zeros(7)}


def make(seed: int = 0, **params) -> ScrewConveyor:
    w = ScrewConveyor(ROBOT, ScrewConveyor.Params(**params), seed=seed)
    w.reset()
    return w


def run(w: ScrewConveyor, seconds: float, command=HOLD) -> list[tuple[float, str]]:
    events = []
    for _ in range(round(seconds / DT)):
        o = w.observe()
        events += [(o.t, e) for e in o.events]
        w.apply(command)
        w.advance(DT)
    return events + [(w.t, e) for e in w.observe().events]


def ik(q0: np.ndarray, H_target: np.ndarray) -> np.ndarray:
    k = ROBOT.kinematics
    q = q0.copy()
    for _ in range(200):
        H, J = k.fk_jacobian(q)
        q = q + pbvs.dls_solve(J, pbvs.ee_error_vector(H, H_target), 0.01)
    return q


def test_registered():
    assert WORLDS.get("screw_conveyor") is ScrewConveyor
    assert ScrewConveyor.actions == {"screwdriver": ("tool_activated", "tool_failed", "screw_done")}
    assert ScrewConveyor.action_params == {"screwdriver": ScrewdriverParams}


def test_conveyor_moves_the_part_at_50_mm_per_s_and_the_platform_follows_its_twist():
    w = make()
    try:
        x0 = w.ground_truth()["part_x"]
        b0 = w.ground_truth()
        run(w, 2.0, {"base_twist": np.array([0.2, 0.0, 0.0]), "arm_dq": np.zeros(7)})
        gt = w.ground_truth()
        assert gt["part_x"] - x0 == pytest.approx(0.10, abs=1e-6)
        # first-order lag (0.1 s) then 0.2 m/s along the platform's heading
        moved = math.hypot(gt["base_x"] - b0["base_x"], gt["base_y"] - b0["base_y"])
        assert moved == pytest.approx(0.2 * (2.0 - 0.1), abs=0.01)
        assert math.atan2(gt["base_y"] - b0["base_y"], gt["base_x"] - b0["base_x"]) == pytest.approx(b0["base_yaw"], abs=1e-3)
        # the speed limit is the paper's 1 m/s
        w.apply({"base_twist": np.array([3.0, 4.0, 0.0]), "arm_dq": np.zeros(7)})
        for _ in range(200):
            w.advance(DT)
        speed = float(np.hypot(*w.body.platform.twist[:2]))
        assert 0.999 < speed <= 1.0 + 1e-12
    finally:
        w.close()


def test_pose_mode_marker_latency_noise_and_lost_found_events():
    w = make(occlusions=[(1.0, 1.6)], dropout=0.0)
    try:
        events = run(w, 2.2)
        names = [e for _, e in events]
        assert names == ["target_found", "target_lost", "target_found"]
        t_found0, t_lost, t_found1 = (t for t, _ in events)
        lat, lost_after = w.params.latency, w.params.lost_after
        # events reach the robot at the next control tick after the physics step they happen in
        late = 2 * DT + 1e-9
        assert lat <= t_found0 <= lat + late
        # the last frame before the occlusion is taken at 0.975 s; lost once lost_after has passed since
        assert 0.975 + lost_after + lat <= t_lost <= 0.975 + lost_after + lat + late
        assert 1.6 + lat <= t_found1 <= 1.6 + lat + late  # the first frame after the occlusion
        o = w.observe()
        m = o.sensors["marker"]
        assert o.t - m.stamp >= lat - 1e-9 and m.frame == "camera"
        err = spatial.inverse(m.T_camera_object) @ w.true_T_camera_object()
        # the measurement is stale by its age: the part moved 50 mm/s x age relative to the camera
        assert np.linalg.norm(err[:3, 3]) < 0.05 * (o.t - m.stamp) + 0.002
    finally:
        w.close()


def test_rendered_mode_finds_the_marker_to_a_fraction_of_a_millimetre():
    w = make(perception="rendered", speed=0.0)
    try:
        run(w, 0.1)
        m = w.observe().sensors["marker"]
        assert m is not None
        truth = w.true_T_camera_object()  # nothing moves: the truth at capture is the truth now
        H = m.T_camera_object
        assert np.linalg.norm(truth[:3, 3] - H[:3, 3]) < 0.001
        assert spatial.rotation_angle(H[:3, :3] @ truth[:3, :3].T) < math.radians(0.2)
        assert w.detector.frames >= 4
        s = w.summary_metrics()
        assert s["perception_rms_xy_mm"] < 0.3 and s["perception_rms_z_mm"] < 1.0 and s["perception_rms_r_deg"] < 0.2
    finally:
        w.close()


def test_force_torque_sensor_reads_the_contact_force_without_the_tool_weight():
    w = make(speed=0.0)
    try:
        run(w, 0.2)
        wrench = w.observe().sensors["wrench"]
        assert wrench.frame == "tool" and np.linalg.norm(wrench.force) < 0.3  # weight compensated
        H_wb = w.body.base_pose()
        bolt = spatial.inverse(H_wb) @ w.bolt_poses()[0]
        q = ik(np.array(ROBOT.params.q_home), bolt @ spatial.transform(np.eye(3), np.array([0.0, 0.0, 0.001])))
        w.body.set_joints(ik(np.array(ROBOT.params.q_home), bolt @ spatial.transform(np.eye(3), np.array([0.0, 0.0, -0.01]))))
        w.apply({"base_twist": np.zeros(3), "arm_dq": q - w.body.q_ref_target})
        w.advance(0.5)
        run(w, 0.5)
        f = w.observe().sensors["wrench"].force
        contacts = p.getContactPoints(w.body.id, w.part.part, physicsClientId=w.client)
        normal = sum(c[9] for c in contacts)
        assert normal > 1.0
        assert -f[2] == pytest.approx(normal, rel=0.05)  # the part pushes the tool back along −z_tool
    finally:
        w.close()


@pytest.mark.parametrize("offset, expected", [(0.0, "tool_activated"), (0.006, "tool_failed")])
def test_screwdriver_couples_only_when_the_bit_sits_on_the_bolt(offset, expected):
    w = make(speed=0.0)
    try:
        H_wb = w.body.base_pose()
        bolt = spatial.inverse(H_wb) @ w.bolt_poses()[2]
        target = bolt @ spatial.transform(np.eye(3), np.array([offset, 0.0, 0.0005]))
        w.body.set_joints(ik(np.array(ROBOT.params.q_home), target))
        run(w, 0.2)
        w.start_action("screwdriver", {"phase": "activate"})
        events = run(w, 1.2)
        assert [e for _, e in events] == [expected]
        assert events[0][0] == pytest.approx(0.2 + ROBOT.params.tool.activation_s, abs=0.02)
        if expected == "tool_activated":
            w.start_action("screwdriver", {"phase": "fasten", "duration": 0.5})
            assert [e for _, e in run(w, 0.7)] == ["screw_done"]
        s = w.summary_metrics()
        ok = expected == "tool_activated"
        assert (s["operations"], s["operations_fastened"], s["operations_failed"]) == (1, int(ok), int(not ok))
        assert s["bolts_on_part"] == 4 and s["bolts_fastened"] == int(ok)
        op = s["operation_log"][0]
        assert op["outcome"] == ("fastened" if ok else "failed")
        assert op["nearest_bolt"] == 2 and op["nearest_bolt_mm"] == pytest.approx(math.hypot(offset, 0.0005) * 1e3, abs=0.6)
        if ok:
            assert op["bolt"] == 2 and op["failure"] is None
            assert op["err_t_mean_mm"] == pytest.approx(math.hypot(offset, 0.0005) * 1e3, abs=0.6)
            assert s["fastened_err_operations"] == s["at_bolt_err_operations"] == 1
            assert s["fastened_err_t_mean_mm"] == pytest.approx(op["err_t_mean_mm"])
            # activation started at 0.2 s, fastening at 1.4 s (after the 1.2 s run) for 0.5 s
            assert op["t_start"] == pytest.approx(0.2, abs=0.02) and op["t_end"] == pytest.approx(1.9, abs=0.02)
            assert op["screwing_s"] == pytest.approx(1.7, abs=0.02)
        else:  # 6 mm off the bolt: beyond the 3 mm coupling tolerance from the start, so no bolt was under the bit
            assert op["bolt"] is None and op["failure"] == "no_bolt" and op["err_t_mean_mm"] is None
            assert s["operations_no_bolt"] == 1
            assert s["fastened_err_operations"] == s["at_bolt_err_operations"] == 0
            assert s["fastened_err_t_mean_mm"] is None and s["at_bolt_err_t_mean_mm"] is None
    finally:
        w.close()


def test_same_seed_same_trolley_and_noise():
    def trace(seed: int) -> list[float]:
        w = make(seed, motion="trolley")
        try:
            run(w, 1.0)
            m = w.observe().sensors["marker"]
            return [w.ground_truth()["part_x"], w.ground_truth()["part_yaw"], float(m.T_camera_object[0, 3])]
        finally:
            w.close()

    assert trace(3) == trace(3)
    assert trace(3) != trace(4)


def place_tip(w: ScrewConveyor, bolt: int, offset_in_bolt: tuple[float, float, float]) -> None:
    """Teleport the arm so the tool tip sits at ``offset_in_bolt`` (m) in bolt ``bolt``'s frame."""
    bolt_b = spatial.inverse(w.body.base_pose()) @ w.bolt_poses()[bolt]
    w.body.set_joints(ik(np.array(ROBOT.params.q_home), bolt_b @ spatial.transform(np.eye(3), np.array(offset_in_bolt))))


def test_an_operation_with_no_bolt_under_the_tool_fails_and_stays_out_of_the_bolt_error_statistics():
    """A mission pose where the part has no bolt (here half-way between bolts 0 and 2, 50 mm from each):
    the activation fails as ``no_bolt``, the operation is in the log with the distance to the nearest
    bolt, and that miss enters no bolt-error statistic."""
    w = make(speed=0.0)
    try:
        place_tip(w, 0, (0.0, -0.05, 0.0005))  # bolt frame x is −y_P: 50 mm along the part towards bolt 2
        run(w, 0.2)
        w.start_action("screwdriver", {"phase": "activate"})
        events = run(w, 1.2)
        assert [e for _, e in events] == ["tool_failed"]
        assert events[0][0] == pytest.approx(0.2 + ROBOT.params.tool.activation_s, abs=0.02)
        place_tip(w, 3, (0.0, 0.0, 0.0005))  # then a real bolt: coupled and fastened
        run(w, 0.2)
        w.start_action("screwdriver", {"phase": "activate"})
        assert [e for _, e in run(w, 1.1)] == ["tool_activated"]
        w.start_action("screwdriver", {"phase": "fasten", "duration": 0.5})
        assert [e for _, e in run(w, 0.6)] == ["screw_done"]
        s = w.summary_metrics()
        assert (s["operations"], s["operations_fastened"], s["operations_failed"], s["operations_no_bolt"]) == (2, 1, 1, 1)
        assert s["operations_unfinished"] == 0
        miss, ok = s["operation_log"]
        assert miss["bolt"] is None and miss["outcome"] == "failed" and miss["failure"] == "no_bolt"
        assert miss["nearest_bolt_mm"] == pytest.approx(50.0, abs=1.0) and miss["err_samples"] == 0
        assert ok["bolt"] == 3 and ok["outcome"] == "fastened" and ok["failure"] is None
        # the statistics are over the fastened operation only, and say so
        assert s["fastened_err_operations"] == 1 and s["at_bolt_err_operations"] == 1
        assert s["fastened_err_samples"] == ok["err_samples"] > 100
        assert s["fastened_err_t_max_mm"] < 1.5 and s["at_bolt_err_t_max_mm"] < 1.5
        assert s["bolts_fastened"] == 1 and s["bolts_on_part"] == 4
    finally:
        w.close()


def test_a_bit_that_leaves_the_bolt_during_activation_fails_coupling_at_that_bolt():
    w = make(speed=0.0)
    try:
        place_tip(w, 1, (0.0, 0.0, 0.0005))
        run(w, 0.2)
        w.start_action("screwdriver", {"phase": "activate"})
        run(w, 0.3)
        # move the tool 6 mm sideways while the screwdriver couples
        bolt_b = spatial.inverse(w.body.base_pose()) @ w.bolt_poses()[1]
        q = ik(w.body.q_ref_target, bolt_b @ spatial.transform(np.eye(3), np.array([0.006, 0.0, 0.0005])))
        w.apply({"base_twist": np.zeros(3), "arm_dq": q - w.body.q_ref_target})
        w.advance(DT)
        assert [e for _, e in run(w, 0.8)] == ["tool_failed"]
        s = w.summary_metrics()
        op = s["operation_log"][0]
        assert op["bolt"] == 1 and op["failure"] == "coupling" and op["coupling_error_mm"] > 3.0
        assert (s["operations_failed"], s["operations_no_bolt"], s["operations_fastened"]) == (1, 0, 0)
        assert s["fastened_err_operations"] == 0 and s["fastened_err_t_max_mm"] is None
        assert s["at_bolt_err_operations"] == 1 and s["at_bolt_err_t_max_mm"] == pytest.approx(op["err_t_max_mm"])
        assert s["at_bolt_err_t_max_mm"] > 5.0
    finally:
        w.close()


@pytest.mark.parametrize("params, field", [
    ({"phase": "fasten", "duration": -3.0}, "duration"),
    ({"phase": "fasten", "duration": 0.0}, "duration"),
    ({"phase": "activate", "duration": float("nan")}, "duration"),
    ({"phase": "fasten", "duration": float("inf")}, "duration"),
    ({"phase": "spin"}, "phase"),
    ({"phase": "fasten", "torque": 2.0}, "torque"),
])
def test_screwdriver_refuses_nonsense_parameters(params, field):
    with pytest.raises(ValueError, match=field):
        ScrewdriverParams.model_validate(params)
    w = make(speed=0.0)
    try:
        with pytest.raises(ValueError, match=field):
            w.start_action("screwdriver", params)
        assert w.summary_metrics()["operations"] == 0 and [e for _, e in run(w, 0.2)] == ["target_found"]
    finally:
        w.close()


@pytest.mark.parametrize("params", [
    {"latency": float("inf")}, {"direction": float("nan")}, {"part_start": (0.0, float("inf"), 0.0)},
    {"occlusions": [(1.0, float("inf"))]}, {"fasten_s": -3.0}, {"fasten_s": 1e9}, {"noise_z": -0.001},
    {"lost_after": 0.0},
])
def test_world_parameters_refuse_nonsense(params):
    with pytest.raises(ValueError):
        ScrewConveyor.Params(**params)


def test_marker_loss_faster_than_the_camera_is_refused():
    with pytest.raises(ValueError, match="camera period"):
        ScrewConveyor(ROBOT, ScrewConveyor.Params(lost_after=0.02), seed=0)  # 40 Hz camera: 25 ms between frames


@pytest.mark.parametrize("tool", [{"slip_t": 0.002}, {"tol_t": -0.001}, {"activation_s": float("inf")}, {"tol_r": 2.0}])
def test_tool_tolerances_refuse_nonsense(tool):
    with pytest.raises(ValueError):
        MobileIiwa.Params.model_validate({"tool": tool})


def test_safe_stop_brings_the_platform_and_the_arm_to_rest_from_full_speed():
    """From the 1 m/s speed limit and a full yaw rate, with the arm moving: within 1 s of safe_stop (the
    runtime's stop time) the platform is at rest by PyBullet's base pose and the arm joints by
    PyBullet's joint speeds."""
    w = make(speed=0.0)
    try:
        rng = np.random.default_rng(0)
        for _ in range(150):  # 1.5 s: full speed, full yaw rate, the arm swinging at up to ~1 rad/s
            w.apply({"base_twist": np.array([0.8, 0.6, 1.0]), "arm_dq": rng.uniform(-0.01, 0.01, 7)})
            w.advance(DT)
        gt = w.ground_truth()
        assert gt["base_speed"] == pytest.approx(1.0, abs=1e-3)  # measured from PyBullet's base pose
        assert gt["base_yaw_rate"] == pytest.approx(1.0, abs=1e-3)
        assert gt["arm_speed"] > 0.05
        for _ in range(round(0.6 / DT)):  # 1 m/s at the 2 m/s² brake deceleration: at rest after 0.5 s
            w.safe_stop()
            w.advance(DT)
        gt = w.ground_truth()
        assert gt["base_speed"] < 1e-9 and abs(gt["base_yaw_rate"]) < 1e-9
        for _ in range(round(0.4 / DT)):
            w.safe_stop()
            w.advance(DT)
        gt = w.ground_truth()
        assert gt["base_speed"] < 1e-9 and abs(gt["base_yaw_rate"]) < 1e-9
        assert gt["arm_speed"] < 1e-3
        pose = (gt["base_x"], gt["base_y"], gt["base_yaw"])
        for _ in range(50):
            w.safe_stop()
            w.advance(DT)
        gt = w.ground_truth()
        assert (gt["base_x"], gt["base_y"], gt["base_yaw"]) == pose
        s = w.summary_metrics()
        assert s["final_base_speed_mps"] < 1e-9 and s["final_arm_speed_radps"] < 1e-3
        # a command after the stop drives again
        for _ in range(50):
            w.apply({"base_twist": np.array([0.2, 0.0, 0.0]), "arm_dq": np.zeros(7)})
            w.advance(DT)
        assert w.ground_truth()["base_speed"] > 0.1
    finally:
        w.close()


def test_the_sensors_are_declared_streams_and_observe_is_pure():
    """The marker camera and the F/T sensor are the world's declared streams (sim/screw/sensors.py); two
    observe() calls in a row return equal observations and change nothing (no capture, no noise draw)."""
    w = make()
    try:
        assert set(w.streams) == {"marker", "wrench"}
        run(w, 0.3)
        a, b = w.observe(), w.observe()
        assert a.t == b.t and a.events == b.events
        assert a.sensors["marker"] is b.sensors["marker"] and a.sensors["marker"] is not None
        np.testing.assert_array_equal(a.sensors["wrench"].force, b.sensors["wrench"].force)
        for key in a.state:
            np.testing.assert_array_equal(a.state[key], b.state[key])
        assert w.marker.captured > 0 and w.wrench.delivered > 0
    finally:
        w.close()
