"""The racecar on flat_ground, measured from ground truth: straight line, bicycle yaw rate,
determinism, and the car_goto loop closed in the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar
from taskflow_sim.ground.flat_ground import FlatGround
from taskflow_tasks.ground.car_goto import CarGains, CarGoto

from taskflow.testing import task_context

ROBOT = Racecar(Racecar.Params())
L = ROBOT.params.wheelbase
DT = 1.0 / 20.0


def make_world(seed: int = 0, **params) -> FlatGround:
    world = FlatGround(ROBOT, FlatGround.Params(**params), seed=seed)
    world.reset()
    return world


def drive(world: FlatGround, v: float, steer: float, seconds: float) -> list[dict[str, float]]:
    trace = []
    for _ in range(round(seconds / DT)):
        world.apply({"v": np.array([v]), "steer": np.array([steer])})
        world.advance(DT)
        trace.append(world.ground_truth())
    return trace


def test_base_frame_is_rear_axle_midpoint():
    world = make_world(start=(1.0, -2.0, 0.7))
    try:
        gt = world.ground_truth()
        assert (gt["x"], gt["y"], gt["yaw"]) == pytest.approx((1.0, -2.0, 0.7), abs=1e-6)
        import pybullet as p

        car = world.sim.car
        wheels = [
            p.getLinkState(car.body, car.joints[n], physicsClientId=car.client)[4]
            for n in ("left_rear_wheel_joint", "right_rear_wheel_joint")
        ]
        np.testing.assert_allclose(np.mean(wheels, axis=0)[:2], [1.0, -2.0], atol=1e-6)
    finally:
        world.close()


def test_straight_drive_goes_along_the_heading():
    yaw, v, seconds = 0.7, 0.4, 3.0
    world = make_world(start=(1.0, -2.0, yaw))
    try:
        gt = drive(world, v, 0.0, seconds)[-1]
        tau = world.params.speed_tau
        expected = v * (seconds - tau)  # first-order speed response lags by tau
        assert world.t == pytest.approx(seconds)
        assert gt["x"] == pytest.approx(1.0 + expected * math.cos(yaw), abs=0.02)
        assert gt["y"] == pytest.approx(-2.0 + expected * math.sin(yaw), abs=0.02)
        assert gt["yaw"] == pytest.approx(yaw, abs=0.01)
        assert gt["v"] == pytest.approx(v, rel=0.01)
    finally:
        world.close()


@pytest.mark.parametrize("v, steer", [(0.4, 0.3), (0.5, -0.44), (-0.3, 0.2)])
def test_constant_steer_yaw_rate_matches_bicycle_model(v, steer):
    world = make_world()
    try:
        trace = drive(world, v, steer, 4.0)
        tail = trace[len(trace) // 2 :]  # steady state: last 2 s
        yaw = np.unwrap([g["yaw"] for g in tail])
        rate = (yaw[-1] - yaw[0]) / ((len(tail) - 1) * DT)
        v_gt = float(np.mean([g["v"] for g in tail]))
        bicycle = v_gt * math.tan(steer) / L
        assert rate == pytest.approx(bicycle, rel=0.03)
        assert world.observe().state["steer"] == pytest.approx(steer, abs=0.01)
    finally:
        world.close()


def run_trajectory(seed: int) -> tuple[np.ndarray, np.ndarray]:
    world = make_world(seed=seed, odom_noise=0.01, odom_yaw_noise=0.005)
    odo, gts = [], []
    try:
        for k in range(40):
            obs = world.observe()
            odo.append(obs.state["pose"])
            world.apply({"v": np.array([0.5]), "steer": np.array([0.3 * math.sin(k / 5)])})
            world.advance(DT)
            gts.append(list(world.ground_truth().values()))
    finally:
        world.close()
    return np.array(odo), np.array(gts)


def test_same_seed_gives_bit_identical_trajectories():
    odo_a, gt_a = run_trajectory(7)
    odo_b, gt_b = run_trajectory(7)
    assert np.array_equal(odo_a, odo_b) and np.array_equal(gt_a, gt_b)
    odo_c, gt_c = run_trajectory(8)
    assert np.array_equal(gt_a, gt_c)  # noise is on odometry only, not on the physics
    assert not np.array_equal(odo_a, odo_c)


def test_world_rejects_bad_use():
    world = FlatGround(ROBOT, FlatGround.Params(), seed=0)
    with pytest.raises(RuntimeError, match="reset"):
        world.observe()
    world.reset()
    try:
        with pytest.raises(ValueError, match="keys"):
            world.apply({"v": np.array([0.1])})
        with pytest.raises(ValueError, match="dt"):
            world.advance(-1.0)
    finally:
        world.close()


def test_car_goto_reaches_a_target_at_90_degrees():
    """Target 2 m straight to the left of the control point: within 5 cm (ground truth) in 15 s."""
    world = make_world(start=(0.0, 0.0, 0.0))
    target = [L, 2.0]
    ctx = task_context(CarGoto, CarGoto.Params(target=target), ROBOT, {"gains": CarGains(k1=(2.0, 1.0), d=L)})
    task = CarGoto(ctx)
    try:
        for _ in range(round(15.0 / DT)):
            obs = world.observe()
            result = task.step(obs)
            world.apply(result.command)
            world.advance(DT)
        gt = world.ground_truth()
        point = np.array([gt["x"] + L * math.cos(gt["yaw"]), gt["y"] + L * math.sin(gt["yaw"])])
        assert np.linalg.norm(point - target) < 0.05
        assert result.metrics["pos_error"] < 0.05
        assert abs(gt["v"]) < 0.05
    finally:
        world.close()
