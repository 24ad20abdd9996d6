"""A command's transport delay: a value given at time ``t`` takes effect at ``t + delay`` (s).

One model for every actuator that acts late: ``screw_conveyor``'s platform (``base_delay``) and
``quad_room``'s drone (``command_delay_s``).  Pure: simulation times in, values out.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")


class CommandDelay(Generic[T]):
    """A delay line of commands.

    :meth:`at` returns the latest value due by ``t`` (the initial value before any is due) and sets
    :attr:`arrived` to whether that call released a new one (a relative-move drone starts a new move
    then); values due within ``eps`` s of ``t`` count as due (times are sums of float steps).  A pushed
    value is kept as given: do not mutate it afterwards."""

    def __init__(self, delay: float, initial: T, eps: float = 1e-9) -> None:
        if not (math.isfinite(delay) and delay >= 0.0):
            raise ValueError(f"CommandDelay needs a finite delay >= 0 s, got {delay!r}")
        self.delay = float(delay)
        self.eps = eps
        self.value = initial
        self.arrived = False
        self._queue: deque[tuple[float, T]] = deque()

    def push(self, t: float, value: T) -> None:
        """Give ``value`` at time ``t`` (s; not earlier than the last one given)."""
        self._queue.append((t + self.delay, value))

    def at(self, t: float) -> T:
        """The value in effect at time ``t``: the latest one given at or before ``t − delay``."""
        q = self._queue
        self.arrived = False
        while q and q[0][0] <= t + self.eps:
            self.value = q.popleft()[1]
            self.arrived = True
        return self.value

    def clear(self, value: T) -> None:
        """Drop every pending value; ``value`` is in effect from now on."""
        self._queue.clear()
        self.value = value
        self.arrived = False
