"""Fault intervals: the one model of a sensor's dropouts, occlusions and blackouts in time.

A world parameter of type :data:`FaultIntervals` is a list of ``[t0, t1]`` intervals (s, simulation
time), each with ``0 <= t0 < t1`` — checked when the mission loads, with the parameter's name in the
message.  Intervals may overlap or touch: the fault is active on their union.  :class:`IntervalFault`
answers whether a fault is active at ``t``: half-open, ``t0 <= t < t1``, so a sensor sample taken at
``t1`` is fine again.  (A detector's random per-frame misses are another model:
:class:`taskflow_sim.perception_common.DropoutModel`.)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

from pydantic import AfterValidator, ValidationInfo

Interval = tuple[float, float]


def check_intervals(intervals: Sequence[Interval], what: str = "fault") -> list[Interval]:
    """``intervals`` as a list, after checking each is ``[t0, t1]`` with ``0 <= t0 < t1`` (a
    ``ValueError`` naming ``what`` and the interval otherwise)."""
    out = []
    for a, b in intervals:
        if not (0.0 <= a < b):
            raise ValueError(f"{what} interval [{a}, {b}] must have 0 <= t0 < t1")
        out.append((a, b))
    return out


def _validate(v: list[Interval], info: ValidationInfo) -> list[Interval]:
    return check_intervals(v, info.field_name or "fault")


FaultIntervals = Annotated[list[Interval], AfterValidator(_validate)]
"""A pydantic field type: ``[t0, t1]`` intervals (s) with ``0 <= t0 < t1``, named by the field in errors."""


class IntervalFault:
    """A fault active on the union of half-open intervals ``[t0, t1)`` of simulation time."""

    def __init__(self, intervals: Sequence[Interval], what: str = "fault") -> None:
        self.intervals = tuple(check_intervals(intervals, what))

    def active(self, t: float) -> bool:
        return any(a <= t < b for a, b in self.intervals)

    def __bool__(self) -> bool:
        return bool(self.intervals)
