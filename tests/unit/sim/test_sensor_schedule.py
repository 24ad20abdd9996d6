"""SensorSchedule (sim/core/stepped.py) and the fault-interval model (sim/core/faults.py), without a simulator."""

from __future__ import annotations

import math

import pytest
from pydantic import ValidationError
from taskflow_sim.core.faults import FaultIntervals, IntervalFault, check_intervals
from taskflow_sim.core.stepped import SensorSchedule

from taskflow.api import StrictModel


def firing_ticks(rate_hz: float, control_hz: float, ticks: int, physics_hz: float | None = None, t0: float = 0.0) -> list[int]:
    """Tick indices at which a schedule polled once per control tick fires; tick times as a stepped world
    computes them (physics steps over physics_hz)."""
    s = SensorSchedule(rate_hz, t0)
    per_tick = round((physics_hz or control_hz) / control_hz)
    return [i for i in range(ticks) if s.poll(i * per_tick / (physics_hz or control_hz))]


def test_a_rate_equal_to_the_control_rate_fires_every_tick():
    assert firing_ticks(25.0, 25.0, 50, physics_hz=250.0) == list(range(50))


def test_a_rate_dividing_the_control_rate_fires_every_nth_tick():
    assert firing_ticks(40.0, 100.0, 10) == [0, 3, 5, 8]  # grid 0, .025, .05, .075 → first tick at or after
    assert firing_ticks(25.0, 100.0, 12, physics_hz=100.0) == [0, 4, 8]


@pytest.mark.parametrize("rate, control", [(15.0, 20.0), (7.0, 20.0), (40.0, 100.0), (33.0, 240.0)])
def test_a_rate_that_does_not_divide_fires_on_the_ticks_crossing_each_grid_time(rate, control):
    ticks = firing_ticks(rate, control, 400)
    expect = sorted({math.ceil(k * control / rate - 1e-6) for k in range(int(400 * rate / control) + 1)})
    assert ticks == [i for i in expect if i < 400]
    assert len(ticks) == pytest.approx(400 * rate / control, abs=1)


def test_a_15hz_camera_in_a_20hz_loop_fires_three_ticks_in_four():
    assert firing_ticks(15.0, 20.0, 8) == [0, 2, 3, 4, 6, 7]


def test_a_sensor_faster_than_the_loop_fires_once_per_tick_and_skips_to_the_next_grid_time():
    s = SensorSchedule(100.0)
    assert [s.poll(t / 10) for t in range(4)] == [True] * 4
    assert s.next_t == pytest.approx(0.31) and s.fired == 4


def test_same_inputs_same_ticks_and_restart_starts_a_new_grid():
    assert firing_ticks(15.0, 20.0, 200) == firing_ticks(15.0, 20.0, 200)
    s = SensorSchedule(10.0)
    assert s.poll(0.0) and not s.poll(0.05) and s.poll(0.1)
    s.restart(0.13, 4.0)
    assert s.poll(0.13) and not s.poll(0.35) and s.poll(0.38)
    assert s.next_t == pytest.approx(0.63)


def test_a_rate_must_be_positive():
    with pytest.raises(ValueError, match="finite and > 0 Hz"):
        SensorSchedule(0.0)


# --- fault intervals ---------------------------------------------------------------------------------

class Faulty(StrictModel):
    blackout: FaultIntervals = []


def test_intervals_are_half_open_and_overlaps_act_as_their_union():
    f = IntervalFault([(1.0, 2.0), (1.5, 3.0), (3.0, 3.5)])
    assert [f.active(t) for t in (0.99, 1.0, 1.7, 2.5, 3.0, 3.49, 3.5)] == [False, True, True, True, True, True, False]
    assert not IntervalFault([]) and not IntervalFault([]).active(0.0)


@pytest.mark.parametrize("bad", [[(-0.1, 1.0)], [(2.0, 1.0)], [(1.0, 1.0)], [(0.0, 1.0), (-2.0, -1.0)]])
def test_negative_empty_and_reversed_intervals_are_refused_with_the_field_name(bad):
    with pytest.raises(ValidationError, match=r"blackout interval \[.*\] must have 0 <= t0 < t1"):
        Faulty(blackout=bad)
    with pytest.raises(ValueError, match=r"occlusions interval"):
        IntervalFault(bad, "occlusions")


def test_the_validator_keeps_valid_intervals():
    assert Faulty(blackout=[[0, 1], [0.5, 2]]).blackout == [(0.0, 1.0), (0.5, 2.0)]
    assert check_intervals([(0.0, 0.1)]) == [(0.0, 0.1)]


def test_the_worlds_use_the_one_validator():
    from taskflow_sim.quad.params import QuadRoomParams
    from taskflow_sim.screw.params import ScrewWorldParams

    with pytest.raises(ValidationError, match=r"blackout interval \[3.0, 2.0\] must have 0 <= t0 < t1"):
        QuadRoomParams(blackout=[(3.0, 2.0)])
    with pytest.raises(ValidationError, match=r"occlusions interval \[-1.0, 2.0\] must have 0 <= t0 < t1"):
        ScrewWorldParams(occlusions=[(-1.0, 2.0)])
