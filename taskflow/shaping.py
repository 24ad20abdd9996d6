"""The activation function shared by mission blends and the control laws that fade tasks in and out.

Quadcopter paper, eq. 20: ``h(t) = ½ (1 − cos(π (t − t0) / (tf − t0)))`` — 0 at ``t0``, 1 at ``tf``,
with zero slope at both ends.  ``tasks/`` may import this module (it is not the runtime).
"""

from __future__ import annotations

import math


def activation(tau: float, duration: float) -> float:
    """``h`` at ``tau = t − t0`` for a rise lasting ``duration``: 0 before, 1 after (eq. 20)."""
    if duration <= 0.0 or tau >= duration:
        return 1.0
    if tau <= 0.0:
        return 0.0
    return 0.5 * (1.0 - math.cos(math.pi * tau / duration))
