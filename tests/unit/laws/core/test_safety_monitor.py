"""The contact monitor: hand-computed force magnitudes and marker ages, and a step that commands nothing."""

from __future__ import annotations

import numpy as np
import pytest
from taskflow_tasks.core.safety_monitor import ContactMonitor, MonitorParams, force_magnitude, marker_age

from taskflow.api import Observation
from taskflow.messages import MarkerPose, Wrench
from taskflow.registry import ROBOTS
from taskflow.testing import task_context


def wrench(f):  # type: ignore[no-untyped-def]
    return Wrench(stamp=0.0, frame="tool", force=np.array(f, dtype=float), torque=np.zeros(3))


def test_force_magnitude_is_the_norm_of_the_force():
    assert force_magnitude(wrench([3.0, 4.0, 12.0])) == pytest.approx(13.0)
    assert force_magnitude(None) == 0.0


def test_marker_age_counts_from_the_capture_or_from_the_start():
    m = MarkerPose(stamp=1.25, frame="camera", T_camera_object=np.eye(4), seq=3)
    assert marker_age(2.0, m, since=0.5) == pytest.approx(0.75)
    assert marker_age(2.0, None, since=0.5) == pytest.approx(1.5)


def test_the_monitor_commands_nothing_and_publishes_both_metrics():
    cls = ROBOTS.get("mobile_iiwa")
    robot = cls(cls.Params())
    ctx = task_context(ContactMonitor, MonitorParams(), robot, t=0.2)
    task = ContactMonitor(ctx)
    res = task.step(Observation(1.0, sensors={"wrench": wrench([0.0, -6.0, 8.0]), "marker": None}))
    assert res.command == {}
    assert res.metrics == {"tool_force": pytest.approx(10.0), "marker_age": pytest.approx(0.8)}
