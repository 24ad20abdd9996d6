"""The quadcopter's command response models (``taskflow_sim.quad.response``) and their use in ``quad_room``:
ViSP's Bebop 2 ``setVelocity`` as relative moves, the command delay line (tests/unit/sim/test_command_delay.py) and the frame latency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.quadcopter import Quadcopter, QuadcopterParams
from taskflow_sim.quad.params import QuadRoomParams
from taskflow_sim.quad.response import move_target, relative_move_step
from taskflow_sim.quad.world import QuadRoom


def test_move_target_is_the_body_frame_move_turned_by_the_yaw():
    """Facing +y (yaw π/2), a forward move of 0.5 m/s for 0.04 s ends 2 cm further along +y; the yaw adds."""
    t = move_target(np.array([1.0, 2.0, 0.5, math.pi / 2]), np.array([0.5, 0.1, -0.25, 0.2]), 0.04)
    assert t == pytest.approx([1.0 - 0.004, 2.02, 0.49, math.pi / 2 + 0.008])


def test_relative_move_step_is_a_first_order_approach_with_wrapped_yaw():
    pose = np.array([0.0, 0.0, 1.0, 3.0])
    target = np.array([0.2, -0.1, 1.0, 3.0 + 0.4])  # the yaw target lies past π
    half = relative_move_step(pose, target, 0.1 * math.log(2.0), 0.1)  # h = τ ln 2: half the way
    assert half[:3] == pytest.approx([0.1, -0.05, 1.0])
    assert half[3] == pytest.approx(math.remainder(3.2, 2 * math.pi))
    assert relative_move_step(pose, target, 0.01, 0.0) == pytest.approx([0.2, -0.1, 1.0, math.remainder(3.4, 2 * math.pi)])


def _world(**params) -> QuadRoom:
    w = QuadRoom(Quadcopter(QuadcopterParams()), QuadRoomParams(perception="geometric", **params), seed=0)
    w.reset()
    return w


@pytest.mark.sim
def test_relative_moves_lose_what_a_command_period_does_not_finish():
    """Each 40 ms command is a move of v·40 ms from where the drone is, approached with τ = 0.1 s and
    replaced by the next: after 25 periods the drone has gone 25 (1 − e^(−0.4)) v·0.04 (hand:
    0.3297 × 0.5 m/s × 1 s = 0.1648 m), a third of what the velocity response gives."""
    w = _world(command_response="relative_move", move_tau=0.1)
    try:
        for _ in range(25):
            w.apply({"nu": np.array([0.5, 0.0, 0.0, 0.0])})
            w.advance(0.04)
        assert w.pose[0] == pytest.approx(25 * (1.0 - math.exp(-0.4)) * 0.5 * 0.04, rel=1e-9)
        assert w.ground_truth()["vx"] > 0.0
    finally:
        w.close()


@pytest.mark.sim
def test_command_delay_and_frame_latency_in_the_world():
    """With a 0.12 s command delay the drone does not move for three 40 ms periods; with a 0.04 s frame
    latency each frame is stamped (and seen) one period late."""
    w = _world(command_delay_s=0.12, frame_latency_s=0.04, camera_rate_hz=25.0)
    try:
        xs, stamps = [], []
        for _ in range(6):
            obs = w.observe()
            stamps.append(obs.sensors["frame_t"])
            w.apply({"nu": np.array([0.5, 0.0, 0.0, 0.0])})
            w.advance(0.04)
            xs.append(float(w.pose[0]))
        assert xs[:3] == [0.0, 0.0, 0.0] and xs[3] > 0.0
        assert stamps[0] == 0.0 and stamps[1:] == pytest.approx([0.0, 0.04, 0.08, 0.12, 0.16])
    finally:
        w.close()


def test_paper_fidelity_fills_the_bebop_parameters_unless_set():
    p = QuadRoomParams(fidelity="paper")
    assert (p.command_response, p.camera_rate_hz, p.frame_latency_s) == ("relative_move", 30.0, 0.04)
    assert QuadRoomParams(fidelity="paper", command_response="velocity").command_response == "velocity"
    ideal = QuadRoomParams()
    assert (ideal.command_response, ideal.command_delay_s, ideal.frame_latency_s, ideal.camera_rate_hz) == \
        ("velocity", 0.0, 0.0, None)
