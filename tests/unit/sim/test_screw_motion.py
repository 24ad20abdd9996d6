"""The part's motion models: a constant conveyor and a smooth, seeded, irregular trolley."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_sim.screw.motion import PartMotion


def simulate(kind: str, seed: int, seconds: float, **kw) -> np.ndarray:
    m = PartMotion(kind, 0.0, 0.0, 0.0, 0.05, 0.0, np.random.default_rng(seed), **kw)
    out = []
    for _ in range(round(seconds / 0.004)):
        m.step(0.004)
        out.append((m.t, m.x, m.y, m.yaw, *m.velocity()))
    return np.array(out)


def test_conveyor_is_a_straight_line_at_constant_speed():
    tr = simulate("conveyor", 0, 10.0)
    assert tr[-1, 1] == pytest.approx(0.5, abs=1e-9) and np.all(tr[:, 2] == 0) and np.all(tr[:, 3] == 0)


def test_trolley_fluctuates_smoothly_around_50_mm_per_s():
    tr = simulate("trolley", 1, 300.0, speed_sigma=0.3, heading_sigma=0.1, tau=1.5, yaw_gain=0.5)  # amplitudes are parameters
    speed = np.hypot(tr[:, 4], tr[:, 5])
    assert speed.mean() == pytest.approx(0.05, abs=0.004)
    assert speed.std() == pytest.approx(0.015, rel=0.3)
    heading = np.arctan2(tr[:, 5], tr[:, 4])
    assert heading.std() == pytest.approx(0.1, rel=0.3)
    assert np.degrees(tr[:, 3].std()) == pytest.approx(np.degrees(0.05), rel=0.3)
    # smooth: bounded acceleration (a push by hand), no step-to-step jumps
    acc = np.diff(speed) / 0.004
    assert np.abs(acc).max() < 0.1


def test_trolley_is_seeded():
    a, b, c = (simulate("trolley", s, 5.0, speed_sigma=0.3, heading_sigma=0.1) for s in (7, 7, 8))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert math.isfinite(a[-1, 1])
