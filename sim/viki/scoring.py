"""``viki_ground``'s scoring: the ground truth measured once per control tick and the run's summary metrics.

:class:`ViKiScore` is fed by the world's stepping hook (never by ``observe()``) with the robot's true pose and
speed: it keeps the speed trace (reversals of the direction of travel), the path length and, from
:mod:`taskflow_sim.viki.clearance`, ``min_clearance_m`` — the smallest distance over the run between the car's
body footprint and the object's footprint, 0 when they touched — and ``contact`` (footprints overlapping or a
PyBullet contact point between the two bodies, e.g. a steered front wheel the footprint misses).
:func:`summary` adds the final object error against the manipulation-zone ``goal`` and the detector's counts.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_sim.viki.clearance import Footprint, footprint_clearance
from taskflow_sim.viki.objects import PlacedObject

#: the trace's ``camera`` column: 0 none, 1 front, 2 rear
CAMERA_CODE = {None: 0.0, "front": 1.0, "rear": 2.0}


class ViKiScore:
    """Ground truth accumulated over a run, one :meth:`track` per control tick."""

    def __init__(self, footprint: Footprint, obj: PlacedObject) -> None:
        self.footprint, self.object = footprint, obj
        self.v_trace: list[tuple[float, float]] = []
        self.path = 0.0
        self._last_xy: tuple[float, float] | None = None
        self.min_clearance = math.inf
        self.contact = False  # touched at some tick so far
        self.touching = False  # touching at the latest tick

    def track(self, t: float, v: float, pose: tuple[float, float, float], touching: bool) -> None:
        """One control tick at time ``t``: speed ``v`` (m/s), true planar pose, whether a PyBullet contact
        point joins the car and the object (the clearance is then 0)."""
        self.v_trace.append((t, v))
        d = 0.0 if touching else footprint_clearance(self.footprint, pose, self.object)
        self.min_clearance = min(self.min_clearance, d)
        self.touching = d == 0.0
        self.contact = self.contact or self.touching
        x, y = pose[0], pose[1]
        if self._last_xy is not None:
            self.path += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
        self._last_xy = (x, y)

    def motion_metrics(self) -> dict[str, Any]:
        """Reversals of the direction of travel (over the run and its last 5 s), path length, clearance."""
        ts = np.array([t for t, _ in self.v_trace]) if self.v_trace else np.zeros(0)
        vs = np.array([v for _, v in self.v_trace]) if self.v_trace else np.zeros(0)
        return {
            "v_sign_changes": sign_changes(vs),
            "v_sign_changes_last_5s": sign_changes(vs[ts >= ts[-1] - 5.0]) if ts.size else 0,
            "path_length_m": self.path,
            "min_clearance_m": self.min_clearance if math.isfinite(self.min_clearance) else None,
            "contact": self.contact,
        }


def summary(score: ViKiScore, obj_in_robot: tuple[float, float], goal: tuple[float, float],
            first_detection_t: float | None, frames: int, detections: int, missed: int) -> dict[str, Any]:
    """The world's summary metrics (module doc): final error, object placement, detector counts, motion."""
    ox, oy = obj_in_robot
    gx, gy = goal
    obj = score.object
    return {
        "final_error_x_m": ox - gx,
        "final_error_y_m": oy - gy,
        "final_error_m": math.hypot(ox - gx, oy - gy),
        "object_x_m": ox,
        "object_y_m": oy,
        "object_kind": obj.shape.kind,
        "object_world_x_m": obj.x,
        "object_world_y_m": obj.y,
        "first_detection_s": first_detection_t,
        "frames": frames,
        "detections": detections,
        "detections_missed": missed,
        "dropout_fraction": missed / (detections + missed) if detections + missed else 0.0,
        **score.motion_metrics(),
    }


def sign_changes(v: NDArray[np.float64], deadband: float = 0.01) -> int:
    """Reversals of the direction of travel, ignoring speeds below ``deadband`` (m/s)."""
    s = np.sign(v[np.abs(v) > deadband])
    return int(np.count_nonzero(s[1:] != s[:-1])) if s.size > 1 else 0
