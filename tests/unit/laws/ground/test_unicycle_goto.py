"""The unicycle point-regulation law against hand-computed values and its closed-form bearing decay."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.husky import Husky
from taskflow_tasks.ground.unicycle_goto import UnicycleGains, UnicycleGoto, saturate, unicycle_point_law

from taskflow.api import Observation
from taskflow.testing import task_context


def test_hand_computed_diagonal_target():
    # rho = sqrt(2), alpha = pi/4: v = 0.5 sqrt(2) cos(pi/4) = 0.5; w = 1.5 pi/4 + 0.5 sin cos = 1.178097 + 0.25
    v, w, rho, alpha = unicycle_point_law(np.array([0.0, 0.0, 0.0]), np.array([1.0, 1.0]), 0.5, 1.5)
    assert (v, w, rho, alpha) == pytest.approx((0.5, 1.5 * math.pi / 4 + 0.25, math.sqrt(2.0), math.pi / 4))


def test_target_straight_ahead_and_behind():
    v, w, rho, alpha = unicycle_point_law(np.array([1.0, 2.0, math.pi / 2]), np.array([1.0, 4.0]), 0.5, 1.5)
    assert (v, w, rho) == pytest.approx((1.0, 0.0, 2.0)) and alpha == pytest.approx(0.0, abs=1e-12)
    # target to the right and slightly behind: alpha = -3pi/4, v < 0 (backs up), w < 0 (turns clockwise)
    v, w, rho, alpha = unicycle_point_law(np.array([0.0, 0.0, 0.0]), np.array([-1.0, -1.0]), 1.0, 2.0)
    assert alpha == pytest.approx(-3 * math.pi / 4)
    assert v == pytest.approx(math.sqrt(2.0) * math.cos(-3 * math.pi / 4)) and v < 0
    assert w == pytest.approx(2.0 * -3 * math.pi / 4 + math.sin(-3 * math.pi / 4) * math.cos(-3 * math.pi / 4))


def test_at_the_target_the_command_is_zero():
    assert unicycle_point_law(np.array([1.0, 1.0, 0.3]), np.array([1.0, 1.0]), 0.5, 1.5) == (0.0, 0.0, 0.0, 0.0)


def test_saturation_keeps_the_curvature():
    assert saturate(2.0, 1.0, 1.0, 2.0) == pytest.approx((1.0, 0.5))
    assert saturate(0.2, -3.0, 1.0, 1.5) == pytest.approx((0.1, -1.5))
    assert saturate(0.2, 0.1, 1.0, 1.5) == (0.2, 0.1)


def test_closed_loop_bearing_decays_as_exp_minus_k_alpha_t():
    """Integrating the ideal unicycle under the law: alpha(t) = alpha0 exp(-k_alpha t), rho decreasing."""
    k_rho, k_alpha, h = 0.4, 1.2, 1e-4
    pose, target = np.array([0.0, 0.0, 0.0]), np.array([2.0, 1.5])
    _, _, rho0, alpha0 = unicycle_point_law(pose, target, k_rho, k_alpha)
    last_rho = rho0
    for _ in range(1, 20001):
        v, w, rho, _ = unicycle_point_law(pose, target, k_rho, k_alpha)
        assert rho <= last_rho + 1e-12
        last_rho = rho
        pose = pose + h * np.array([v * math.cos(pose[2]), v * math.sin(pose[2]), w])
    _, _, rho, alpha = unicycle_point_law(pose, target, k_rho, k_alpha)
    assert alpha == pytest.approx(alpha0 * math.exp(-k_alpha * 2.0), rel=1e-3)
    assert rho < rho0


def test_task_commands_the_unicycle_interface_within_the_robot_limits():
    robot = Husky(Husky.Params(v_max=0.5, w_max=1.0))
    ctx = task_context(UnicycleGoto, UnicycleGoto.Params(target=[10.0, 0.0]), robot, {"gains": UnicycleGains()})
    res = UnicycleGoto(ctx).step(Observation(t=0.0, state={"pose": np.zeros(3), "v": 0.0, "w": 0.0}))
    assert set(res.command) == set(Husky.command_keys)
    assert float(res.command["v"][0]) == pytest.approx(0.5) and float(res.command["w"][0]) == pytest.approx(0.0)
    assert res.metrics["pos_error"] == pytest.approx(10.0)


def test_the_task_reads_what_it_declares_and_an_absent_entry_is_an_error_not_a_default():
    """``requires`` and the reads are the same keys (tasks/core/keys.py): the load-time check sees what
    ``step`` reads, and a required entry that is absent raises instead of reading as a silent 0."""
    from taskflow_tasks.core.keys import POSE, SPEED

    from taskflow.api import MissingObservation

    assert UnicycleGoto.requires == {POSE.name: POSE.spec, SPEED.name: SPEED.spec}
    robot = Husky(Husky.Params())
    ctx = task_context(UnicycleGoto, UnicycleGoto.Params(target=[1.0, 0.0]), robot, {"gains": UnicycleGains()})
    with pytest.raises(MissingObservation, match="state.v"):
        UnicycleGoto(ctx).step(Observation(t=0.0, state={"pose": np.zeros(3)}))
