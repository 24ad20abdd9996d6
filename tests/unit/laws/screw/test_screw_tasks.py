"""The screw tasks integrate over the control period ``TaskContext.dt`` (1 / rate_hz) — never a period
estimated from observation times — checked by hand at the paper's 40 Hz control rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.mobile_iiwa import MobileIiwa
from taskflow_tasks.core import pbvs
from taskflow_tasks.core.impedance import ImpedanceProfile
from taskflow_tasks.core.pid import PidProfile
from taskflow_tasks.screw.data import ADMITTANCE, PID_B, PREDICTOR, Q_NOM
from taskflow_tasks.screw.home import ArmHome, HomeParams
from taskflow_tasks.screw.mobile_pbvs import ArmParams, FollowParams, PbvsArm, PbvsFollow, PbvsPlatform, PlatformParams
from taskflow_tasks.screw.prediction import MotionPredictor, Prediction

from taskflow import spatial
from taskflow.api import MissingObservation, Observation
from taskflow.messages import MarkerPose, Wrench
from taskflow.testing import task_context

ROBOT = MobileIiwa(MobileIiwa.Params())
DT = 1.0 / 40.0  # the paper's control rate
CAMERA_TARGET = {"xyz": [0.0, -0.0003, 0.6711], "rpy_deg": [145.008, -24.644, -30.782]}
NO_LIMITS = {"u_max": [math.inf] * 6, "i_limit": [math.inf] * 6}


def obs(t: float, H_co: np.ndarray, q: np.ndarray, force=(0.0, 0.0, 0.0)) -> Observation:
    return Observation(t, state={"q": q, "qd": np.zeros(7), "q_ref": q, "odom": np.zeros(3), "base_twist": np.zeros(3)},
                       sensors={"marker": MarkerPose(stamp=t - 0.025, frame="camera", T_camera_object=H_co, seq=1),
                                "wrench": Wrench(stamp=t, frame="tool", force=np.array(force, dtype=float), torque=np.zeros(3))})


def marker_offset_along_base_x(H_co_star: np.ndarray, d: float) -> np.ndarray:
    """The marker seen ``d`` metres off its target along the platform's x: ``E_co = T(R_cb (d, 0, 0))``,
    so the camera error vector in the base frame (eqs. 25–32) is exactly ``[0, 0, 0, d, 0, 0]``."""
    R_bc = ROBOT.params.T_body_camera()[:3, :3]
    H = H_co_star.copy()
    H[:3, 3] += R_bc.T @ np.array([d, 0.0, 0.0])
    return H


def test_platform_pid_integrates_the_control_period_at_40_hz():
    pid = PidProfile(kp=[0, 0, 0, 2.0, 0, 0], ki=[0, 0, 0, 1.5, 0, 0], **NO_LIMITS)
    zero = PidProfile(kp=[0] * 6)
    params = PlatformParams.model_validate({"camera_target": CAMERA_TARGET})
    memory: dict = {}
    task = PbvsPlatform(task_context(PbvsPlatform, params, ROBOT, {"platform": pid, "arm": zero}, memory=memory, dt=DT))
    H_co = marker_offset_along_base_x(params.camera_target.matrix(), 0.01)
    q = np.array(ROBOT.params.q_home)
    np.testing.assert_allclose(pbvs.camera_error_vector(H_co @ spatial.inverse(params.camera_target.matrix()),
                                                        ROBOT.params.T_body_camera()[:3, :3]), [0, 0, 0, 0.01, 0, 0], atol=1e-12)
    for k in range(1, 4):
        r = task.step(obs(k * DT, H_co, q))
        # ∫e dt grows by e · 0.025 s per tick, from the first tick on (1 cm error → 0.25 mm·s per tick)
        assert PID_B(memory).integral[3] == pytest.approx(k * 0.01 * 0.025, rel=1e-9)
        # v_x = kp e + ki ∫e dt
        assert r.command["base_twist"][0] == pytest.approx(2.0 * 0.01 + 1.5 * k * 0.01 * 0.025, rel=1e-9)


def test_the_period_does_not_come_from_observation_times():
    """Irregular observation stamps (a late first tick, a gap) change nothing: each tick is 1 / rate_hz."""
    pid = PidProfile(kp=[0] * 6, ki=[0, 0, 0, 1.0, 0, 0], **NO_LIMITS)
    params = PlatformParams.model_validate({"camera_target": CAMERA_TARGET})
    memory: dict = {}
    task = PbvsPlatform(task_context(PbvsPlatform, params, ROBOT, {"platform": pid, "arm": PidProfile(kp=[0] * 6)}, memory=memory,
                                     dt=DT))
    H_co = marker_offset_along_base_x(params.camera_target.matrix(), 0.02)
    q = np.array(ROBOT.params.q_home)
    for t in (3.0, 3.025, 7.0):  # e.g. after a searching state without a task
        task.step(obs(t, H_co, q))
    assert PID_B(memory).integral[3] == pytest.approx(3 * 0.02 * 0.025, rel=1e-9)


def test_arm_step_and_admittance_use_the_control_period_at_40_hz():
    arm = PidProfile(kp=[5.0] * 6, **NO_LIMITS)
    imp = ImpedanceProfile(K=[1000.0, 1000.0, 600.0], D=[120.0, 120.0, 80.0], M=[1.0, 1.0, 1.0], force=[0.0, 0.0, 3.0])
    params = ArmParams.model_validate({"camera_target": CAMERA_TARGET,
                                       "target": {"xyz": [0.14, 0.06, 0.0075], "rpy_deg": [180, 0, -90]}})
    memory: dict = {}
    task = PbvsArm(task_context(PbvsArm, params, ROBOT, {"platform": PidProfile(kp=[0] * 6), "arm": arm, "impedance": imp},
                                memory=memory, dt=DT))
    q = np.array(ROBOT.params.q_home)
    f = np.array([0.5, -0.2, -1.0])
    task.step(obs(0.0, params.camera_target.matrix(), q, force=f))
    # eq. 37 with the joint-speed limit: the tool starts ~0.3 m from the bolt, so the step is the limit
    # qd_max · dt = 1.5 rad/s · 0.025 s on the fastest joint
    dq = Q_NOM(memory) - q
    assert float(np.max(np.abs(dq))) == pytest.approx(ROBOT.params.qd_max * 0.025, rel=1e-9)
    # eq. 39 as meant, from rest, one implicit-Euler step of 25 ms: x = ΔF / (M/dt² + D/dt + K)
    dF = f + np.array([0.0, 0.0, 3.0])
    x = dF / (np.array([1.0, 1.0, 1.0]) / 0.025**2 + np.array([120.0, 120.0, 80.0]) / 0.025 + np.array([1000.0, 1000.0, 600.0]))
    np.testing.assert_allclose(ADMITTANCE(memory).x, x, rtol=1e-12)


def test_arm_home_ramps_at_its_speed_over_the_control_period():
    memory: dict = {}
    task = ArmHome(task_context(ArmHome, HomeParams(speed=0.6), ROBOT, memory=memory, dt=DT))
    home = np.array(ROBOT.params.q_home)
    q0 = home + np.array([0.0, 0.3, 0.0, -0.1, 0.0, 0.0, 0.0])
    q_ref = q0.copy()
    for k in range(1, 4):
        r = task.step(Observation(k * DT, state={"q": q0, "q_ref": q_ref}))
        q_ref = q_ref + r.command["arm_dq"]
        # the farthest joint (0.3 rad away) moves 0.6 rad/s · 0.025 s = 15 mrad per tick
        assert q_ref[1] == pytest.approx(q0[1] - k * 0.015, abs=1e-12)
        assert q_ref[3] == pytest.approx(q0[3] + k * 0.005, abs=1e-12)


@pytest.mark.parametrize("cls, params", [
    (PbvsPlatform, PlatformParams.model_validate({"camera_target": CAMERA_TARGET})),
    (ArmHome, HomeParams()),
])
def test_a_task_without_a_control_period_is_refused(cls, params):
    profiles = {"platform": PidProfile(kp=[1.0] * 6), "arm": PidProfile(kp=[0] * 6)} if cls is PbvsPlatform else {}
    with pytest.raises(ValueError, match="TaskContext.dt"):
        cls(task_context(cls, params, ROBOT, profiles))


def test_the_motion_predictor_keeps_its_whole_state_under_one_key():
    """With prediction on, the part's fitted motion lives in one MotionPredictor under ``screw.predictor``
    (the only screw.* key beside the controllers' and q*), and a moving marker's velocity is fitted."""
    pid = PidProfile(kp=[0, 0, 0, 2.0, 0, 0], **NO_LIMITS)
    params = PlatformParams.model_validate({"camera_target": CAMERA_TARGET})
    memory: dict = {}
    task = PbvsPlatform(task_context(PbvsPlatform, params, ROBOT, {"platform": pid, "arm": PidProfile(kp=[0] * 6),
                                                                    "prediction": Prediction(enabled=True)},
                                     memory=memory, dt=DT))
    q = np.array(ROBOT.params.q_home)
    T = params.camera_target.matrix()
    for k in range(12):  # the part moves 1 mm per tick along the platform's x
        t = k * DT
        T_k = marker_offset_along_base_x(T, 0.001 * k)
        task.step(Observation(t, state={"q": q, "qd": np.zeros(7), "q_ref": q, "odom": np.zeros(3),
                                        "base_twist": np.zeros(3)},
                              sensors={"marker": MarkerPose(stamp=t, frame="camera", T_camera_object=T_k, seq=k + 1),
                                       "wrench": None}))
    assert sorted(memory) == ["screw.adm", "screw.pid_b", "screw.predictor", "screw.q_nom"]
    predictor = PREDICTOR(memory)
    assert isinstance(predictor, MotionPredictor) and predictor.seq == 12 and predictor.fit is not None
    np.testing.assert_allclose(predictor.fit.slope[:2], [0.001 / DT, 0.0], atol=1e-9)  # 1 mm per tick along x


def _moving_part_obs(k: int, T: np.ndarray, q: np.ndarray, seq: int | None = None) -> Observation:
    """Tick ``k``: the part 1 mm further along the platform's x per tick; the marker is the one captured at
    tick ``seq`` (default ``k``: a fresh one) — an older one is what a lost marker leaves in the observation."""
    s = k if seq is None else seq
    return Observation(k * DT, state={"q": q, "qd": np.zeros(7), "q_ref": q, "odom": np.zeros(3), "base_twist": np.zeros(3)},
                       sensors={"marker": MarkerPose(stamp=s * DT, frame="camera", T_camera_object=marker_offset_along_base_x(T, 0.001 * s),
                                                     seq=s + 1), "wrench": None})


@pytest.mark.parametrize("enabled", [True, False])
def test_searching_follows_the_predicted_part_for_the_coast_then_stops(enabled):
    """pbvs_follow with the marker lost after 12 ticks of a part moving 40 mm/s: with prediction it keeps
    commanding the platform after the part (v_x > 0) while the last marker is at most ``coast`` old, and holds
    the tool pose it had on the part as the arm's target; past the coast — or without prediction, at once — it
    commands no motion at all (the paper's searching); a new marker (``target_seen``) re-aligns the platform."""
    pid = PidProfile(kp=[0, 0, 0, 1.5, 0, 0], **NO_LIMITS)
    q = np.array(ROBOT.params.q_home)
    memory: dict = {}
    profiles = {"platform": pid, "arm": PidProfile(kp=[0] * 6), "prediction": Prediction(enabled=enabled)}
    params = PlatformParams.model_validate({"camera_target": CAMERA_TARGET})
    T = params.camera_target.matrix()
    before = PbvsPlatform(task_context(PbvsPlatform, params, ROBOT, profiles, memory=memory, dt=DT))
    for k in range(12):
        before.step(_moving_part_obs(k, T, q))
    fparams = FollowParams.model_validate({"camera_target": CAMERA_TARGET, "coast": 0.5})
    arm = PidProfile(kp=[1.0] * 6, **NO_LIMITS)
    task = PbvsFollow(task_context(PbvsFollow, fparams, ROBOT, {**profiles, "arm": arm}, memory=memory, dt=DT, t=12 * DT))
    out = [task.step(_moving_part_obs(k, T, q, seq=11)) for k in range(12, 12 + 40)]  # 1 s without a new marker
    follow = [r.metrics["following"] for r in out]
    coasting = [r for r in out if r.metrics["following"] == 1.0]
    if enabled:
        # the last marker (tick 11) is at most 0.5 s old up to tick 31: 20 ticks of following
        assert follow == [1.0] * 20 + [0.0] * 20
        assert all(r.command["base_twist"][0] > 0.03 for r in coasting)
        assert task.T_object_target is not None and "ee_error.t" in coasting[0].metrics
    else:
        assert follow == [0.0] * 40 and task.T_object_target is None
    for r in out[len(coasting):]:
        assert not np.any(r.command["base_twist"]) and not np.any(r.command["arm_dq"])
        assert r.metrics["target_seen"] == 0.0
    seen = task.step(_moving_part_obs(60, T, q))  # the marker is back: 60 mm off (the robot of this test never moves)
    assert seen.metrics["target_seen"] == 1.0 and seen.metrics["camera_error.t"] == pytest.approx(0.06, abs=1e-9)
    assert seen.command["base_twist"][0] > 0.05  # re-aligning on it


def test_a_required_observation_that_is_absent_is_an_error_not_a_default():
    task = ArmHome(task_context(ArmHome, HomeParams(), ROBOT, memory={}, dt=DT))
    with pytest.raises(MissingObservation, match="state.q_ref"):
        task.step(Observation(0.0, state={"q": np.array(ROBOT.params.q_home)}))
