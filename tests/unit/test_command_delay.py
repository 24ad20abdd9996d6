"""The platform's command transport delay (:class:`taskflow_sim.core.command_delay.CommandDelay`, the screw
platform's and the drone's), against
hand-computed times."""

from __future__ import annotations

import pytest
from taskflow_sim.core.command_delay import CommandDelay


def test_a_command_takes_effect_delay_seconds_after_it_was_given():
    d = CommandDelay(0.025, (0.0, 0.0, 0.0))
    d.push(0.00, (1.0, 0.0, 0.0))
    d.push(0.01, (2.0, 0.0, 0.0))
    assert d.at(0.00) == (0.0, 0.0, 0.0)  # nothing due yet: the initial value
    assert d.at(0.02) == (0.0, 0.0, 0.0)
    assert d.at(0.025) == (1.0, 0.0, 0.0)  # 0.00 + 0.025
    assert d.at(0.03) == (1.0, 0.0, 0.0)
    assert d.at(0.035) == (2.0, 0.0, 0.0)  # 0.01 + 0.025 (float sums within eps count as due)
    assert d.at(1.0) == (2.0, 0.0, 0.0)  # the last one stays in effect


def test_steps_between_commands_take_the_latest_due_one_and_clear_drops_the_pending():
    d = CommandDelay(0.02, (0.0,))
    for k in range(5):  # commands every 10 ms
        d.push(0.01 * k, (float(k),))
    assert d.at(0.045) == (2.0,)  # given at 0.00, 0.01, 0.02 are due (0.02, 0.03, 0.04): the latest, 2
    d.clear((9.0,))
    assert d.at(1.0) == (9.0,)


def test_a_zero_delay_acts_at_once_and_a_bad_delay_is_refused():
    d = CommandDelay(0.0, (0.0,))
    d.push(0.5, (3.0,))
    assert d.at(0.5) == (3.0,)
    for bad in (-0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="finite delay >= 0"):
            CommandDelay(bad, (0.0,))


def test_arrived_says_whether_the_call_released_a_new_value():
    d = CommandDelay(0.1, (0.0,))
    d.push(0.0, (0.5,))
    d.push(0.04, (0.2,))
    assert d.at(0.05) == (0.0,) and not d.arrived
    assert d.at(0.1) == (0.5,) and d.arrived
    assert d.at(0.12) == (0.5,) and not d.arrived  # still in effect, nothing new
    assert d.at(0.14) == (0.2,) and d.arrived
