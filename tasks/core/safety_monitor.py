"""A safety monitor for a parallel region: it drives nothing and publishes what a protective stop is
decided on — the force the tool feels and how long the marker has been unseen.

It runs in a region that owns no command part (``owns: []``), next to the region that operates the
robot, so its guards pre-empt the operation from outside it (docs/missions.md, "Parallel regions").

Metrics:

* ``tool_force`` (N): the magnitude ``‖f‖`` of the force the wrist F/T sensor measures
  (:class:`~taskflow.messages.Wrench`, tool frame), 0 before the first reading;
* ``marker_age`` (s): sim time since the capture of the latest marker detection
  (:class:`~taskflow.messages.MarkerPose` ``stamp``), or since the monitor started if none has come yet.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import BaseModel
from taskflow_tasks.core.keys import MARKER, WRENCH

from taskflow.api import AGE, FORCE, Observation, StepResult, StrictModel, Task, TaskContext
from taskflow.messages import MarkerPose, Wrench
from taskflow.registry import register_task
from taskflow.specs import Requires


class MonitorParams(StrictModel):
    """The monitor has no parameters: the thresholds live in the guards of its region."""


def force_magnitude(wrench: Wrench | None) -> float:
    """``‖f‖`` of a wrench reading (N); 0 without one."""
    if wrench is None:
        return 0.0
    f = wrench.force
    return math.sqrt(float(f[0]) ** 2 + float(f[1]) ** 2 + float(f[2]) ** 2)


def marker_age(t: float, marker: MarkerPose | None, since: float) -> float:
    """Seconds from the latest marker capture (or from ``since`` without one) to ``t``."""
    return t - (marker.stamp if marker is not None else since)


@register_task("contact_monitor")
class ContactMonitor(Task[MonitorParams, BaseModel]):  # no robot parameters (ctx.robot_params is None)
    """Watches the wrist F/T sensor and the marker; commands nothing (``command_interface`` empty)."""

    Params: ClassVar[type[BaseModel]] = MonitorParams
    metrics: ClassVar[dict[str, str]] = {"tool_force": FORCE, "marker_age": AGE}
    requires: ClassVar[Requires] = (WRENCH, MARKER)

    def __init__(self, ctx: TaskContext[MonitorParams, BaseModel]) -> None:
        super().__init__(ctx)
        self.started = ctx.t

    def step(self, obs: Observation) -> StepResult:
        return StepResult({}, {"tool_force": force_magnitude(WRENCH(obs)),
                               "marker_age": marker_age(obs.t, MARKER(obs), self.started)})
