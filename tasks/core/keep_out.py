"""Keep-out: a car never drives its body toward an object it is closer to than a margin.

Pure function.  The car's body is a rectangle in the robot frame ``(x_min, x_max, y_min, y_max)`` (m;
x ahead of the rear-axle midpoint, y left); the object is a disc of radius ``radius`` at ``object_xy`` in
the robot frame (its estimated base centre).  When the gap between them is under ``margin`` and the
commanded speed ``v`` moves the body toward the object (forward when the object lies ahead of the body's
middle, backward when behind), the command is turned around: the car backs away at the same speed and
steering, which also brings an object that left the camera's view (beside the car's nose) back into it.
Otherwise ``v`` passes unchanged.

Why it is needed (issue 14): at bearings near the edge of the view the visual servo can bring the car
beside the object, the object leaves the image, and the kinematic fallback (eq. 4) — whose target pose
lies beyond the object — drives the car's nose into it at full lock.  The object's estimate carries the
detector's error (eq. 17 averages floor pixels into a thin object's depth: 10-20 cm too far at 2 m), so
the margin must cover it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["RACECAR_BODY", "body_gap", "keep_out_speed"]

# the racecar's footprint (x_min, x_max, y_min, y_max), m, robot frame: taskflow_sim.viki.clearance.measure_footprint
# of the PyBullet racecar, rounded outward (tests/sim/test_viki_clearance.py checks it covers the measured one)
RACECAR_BODY: tuple[float, float, float, float] = (-0.05, 0.41, -0.15, 0.15)


def body_gap(body: ArrayLike, object_xy: ArrayLike, radius: float) -> float:
    """Distance (m) between the body rectangle and the object's disc, 0 when they overlap."""
    x0, x1, y0, y1 = (float(v) for v in np.asarray(body, dtype=float).reshape(4))
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"body must be (x_min, x_max, y_min, y_max) with min < max, got {(x0, x1, y0, y1)}")
    ox, oy = (float(v) for v in np.asarray(object_xy, dtype=float).reshape(2))
    d = math.hypot(max(x0 - ox, 0.0, ox - x1), max(y0 - oy, 0.0, oy - y1))
    return max(0.0, d - max(float(radius), 0.0))


def keep_out_speed(v: float, body: ArrayLike, object_xy: ArrayLike, radius: float, margin: float) -> float:
    """``v``, or ``-v`` when the body is within ``margin`` of the object and ``v`` moves it toward the object."""
    if not margin >= 0.0:
        raise ValueError(f"margin must be >= 0, got {margin}")
    if v == 0.0 or body_gap(body, object_xy, radius) >= margin:
        return v
    x0, x1 = (float(b) for b in np.asarray(body, dtype=float).reshape(4)[:2])
    ahead = float(np.asarray(object_xy, dtype=float).reshape(2)[0]) > 0.5 * (x0 + x1)
    toward = (v > 0.0) == ahead
    return -v if toward else v
