"""The screw_conveyor world's ``paper`` fidelity level and the platform's command delay, on PyBullet."""

from __future__ import annotations

import numpy as np
import pytest
import taskflow_robots.mobile_iiwa  # noqa: F401 - registers mobile_iiwa
from taskflow_robots.mobile_iiwa import MobileIiwa
from taskflow_sim.screw.world import ScrewConveyor


def test_the_paper_level_sets_the_latency_and_the_platform_delay_unless_the_mission_does():
    paper = ScrewConveyor.Params(fidelity="paper")
    assert (paper.latency, paper.base_delay, paper.base_tau) == (0.045, 0.025, 0.1)
    ideal = ScrewConveyor.Params()
    assert (ideal.latency, ideal.base_delay, ideal.base_tau) == (0.025, 0.0, 0.1)
    assert ScrewConveyor.Params(fidelity="paper", base_delay=0.05).base_delay == 0.05  # the mission's value wins


@pytest.mark.parametrize("delay", [0.0, 0.03])
def test_the_platform_acts_on_a_twist_command_after_its_delay(delay):
    """A 0.05 m/s forward command at t = 0 (below the acceleration limit): the platform's twist (odometry) stays zero for the delay, then
    rises through its first-order lag (0.1 s: 1 − e^(−0.1/0.1) = 63 % of the command 0.1 s later, within
    the discretisation of 10 ms steps)."""
    w = ScrewConveyor(MobileIiwa(MobileIiwa.Params()), ScrewConveyor.Params(speed=0.0, base_delay=delay), seed=0)
    w.reset()
    try:
        cmd = {"base_twist": np.array([0.05, 0.0, 0.0]), "arm_dq": np.zeros(7)}
        speeds = []
        for _ in range(20):
            w.apply(cmd)
            w.advance(0.01)
            speeds.append(float(w.observe().state["base_twist"][0]))
        first = next(i for i, v in enumerate(speeds) if v > 0.0)  # tick i ends at (i + 1) * 10 ms
        assert first == round(delay / 0.01)
        assert speeds[first + 9] == pytest.approx(0.05 * (1.0 - np.exp(-1.0)), rel=0.05)
    finally:
        w.close()
