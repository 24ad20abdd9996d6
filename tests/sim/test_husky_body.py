"""The Husky body on flat_ground, measured from ground truth: it drives straight, turns both ways by
skid-steer wheel contact, stops, and is deterministic."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.husky import Husky
from taskflow_sim.core.bodies import GroundBody
from taskflow_sim.ground.flat_ground import FlatGround
from taskflow_sim.ground.husky_body import HuskyBody

ROBOT = Husky(Husky.Params())
DT = 0.05


def drive(world: FlatGround, v: float, w: float, seconds: float) -> dict[str, float]:
    for _ in range(round(seconds / DT)):
        world.apply({"v": np.array([v]), "w": np.array([w])})
        world.advance(DT)
    return world.ground_truth()


@pytest.fixture
def world():
    w = FlatGround(ROBOT, FlatGround.Params(start=(1.0, -1.0, 0.5)), seed=0)
    w.reset()
    yield w
    w.close()


def test_flat_ground_builds_the_husky_body_from_the_registry(world):
    assert isinstance(world.sim.car, HuskyBody) and isinstance(world.sim.car, GroundBody)
    gt = world.ground_truth()
    assert (gt["x"], gt["y"], gt["yaw"]) == pytest.approx((1.0, -1.0, 0.5), abs=2e-3)
    assert set(world.observe().state) == {"pose", "v", "w"}


def test_drives_straight_along_the_heading(world):
    gt = drive(world, 0.6, 0.0, 3.0)
    moved = math.hypot(gt["x"] - 1.0, gt["y"] + 1.0)
    assert moved == pytest.approx(0.6 * 3.0, rel=0.1)  # ramp at a_max and the speed lag cost a little
    assert math.atan2(gt["y"] + 1.0, gt["x"] - 1.0) == pytest.approx(0.5, abs=0.01)
    assert gt["v"] == pytest.approx(0.6, abs=0.02)


@pytest.mark.parametrize("w", [0.8, -0.8])
def test_turns_by_skid_steer(world, w):
    yaw0 = world.ground_truth()["yaw"]
    gt = drive(world, 0.4, w, 2.0)
    turned = math.remainder(gt["yaw"] - yaw0, 2 * math.pi)
    assert math.copysign(1.0, turned) == math.copysign(1.0, w)
    assert 0.3 * abs(w) * 2.0 < abs(turned) < 1.5 * abs(w) * 2.0  # skid-steer slips: within a broad band


def test_stop_command_brings_it_to_rest(world):
    drive(world, 0.8, 0.0, 2.0)
    world.sim.car.stop()
    for _ in range(40):
        world.advance(DT)
    assert abs(world.ground_truth()["v"]) < 1e-2


def test_same_seed_same_trajectory():
    def run() -> list[dict[str, float]]:
        w = FlatGround(ROBOT, FlatGround.Params(odom_noise=0.01), seed=4)
        w.reset()
        try:
            out = []
            for _ in range(30):
                w.apply({"v": np.array([0.5]), "w": np.array([0.5])})
                w.advance(DT)
                out.append({**w.ground_truth(), "odom_x": float(w.observe().state["pose"][0])})
            return out
        finally:
            w.close()

    assert run() == run()


def test_rejects_a_racecar_command(world):
    with pytest.raises(ValueError, match="husky command needs keys"):
        world.apply({"v": np.array([0.1]), "steer": np.array([0.0])})
