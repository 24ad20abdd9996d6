"""The keep-out rule (taskflow_tasks.core.keep_out) against hand-computed gaps."""

from __future__ import annotations

import math

import pytest
from taskflow_tasks.core.keep_out import body_gap, keep_out_speed

BODY = (-0.05, 0.41, -0.15, 0.15)


def test_body_gap_to_a_disc():
    assert body_gap(BODY, (1.0, 0.0), 0.05) == pytest.approx(0.54)       # straight ahead: 1 - 0.41 - 0.05
    assert body_gap(BODY, (0.2, 0.5), 0.05) == pytest.approx(0.30)       # beside: 0.5 - 0.15 - 0.05
    assert body_gap(BODY, (0.71, 0.55), 0.0) == pytest.approx(0.5)       # off the corner: hypot(0.3, 0.4)
    assert body_gap(BODY, (0.45, 0.0), 0.05) == 0.0                      # overlapping
    with pytest.raises(ValueError, match="min < max"):
        body_gap((0.4, -0.05, -0.15, 0.15), (1.0, 0.0), 0.05)


def test_keep_out_turns_a_command_toward_a_near_object_around():
    near_ahead, near_behind, far = (0.6, 0.1), (-0.3, 0.0), (1.0, 0.0)
    assert keep_out_speed(0.4, BODY, near_ahead, 0.05, 0.3) == -0.4      # nose toward it: back away
    assert keep_out_speed(-0.4, BODY, near_ahead, 0.05, 0.3) == -0.4     # already backing away
    assert keep_out_speed(-0.2, BODY, near_behind, 0.05, 0.3) == 0.2     # reversing into it: go forward
    assert keep_out_speed(0.4, BODY, far, 0.05, 0.3) == 0.4              # gap 0.54 >= 0.3: untouched
    assert keep_out_speed(0.0, BODY, near_ahead, 0.05, 0.3) == 0.0
    assert math.isclose(keep_out_speed(0.4, BODY, far, 0.05, 0.55), -0.4)  # a wider margin reaches it
    with pytest.raises(ValueError, match="margin"):
        keep_out_speed(0.4, BODY, far, 0.05, -0.1)
