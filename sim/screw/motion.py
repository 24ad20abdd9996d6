"""How the part moves — unknown to the robot (screw-fastening paper, section 9).

* ``conveyor``: a straight line at a constant speed (paper: 50 mm/s on a two-metre belt).
* ``trolley``: pushed by hand "trying to keep 50 mm/s": speed and heading fluctuate around the
  nominal values as two independent smooth random processes — white noise through two cascaded
  first-order filters of time constant ``tau`` (a second-order Gauss–Markov process: continuous
  rate, bounded acceleration, as a push by hand; a plain Ornstein–Uhlenbeck path would have
  unbounded acceleration).  Stationary std ``speed_sigma`` × speed and ``heading_sigma``; the
  trolley turns with its heading (``yaw_gain``: part yaw change per heading change).  Seeded: the
  same seed gives the same motion.

Both integrate exactly per physics step and are pure numpy (no simulator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class SmoothNoise:
    """Unit-variance second-order Gauss–Markov noise: white noise → first-order lag (``tau``) →
    first-order lag (``tau``), discretised exactly per step."""

    def __init__(self, rng: np.random.Generator, tau: float) -> None:
        self.rng, self.tau = rng, tau
        # stationary start: x1 ~ N(0, 2), x2 ~ N(0, 1) with their stationary correlation ignored
        self.x1 = float(rng.normal(0.0, math.sqrt(2.0)))
        self.x2 = float(rng.normal(0.0, 1.0))

    def step(self, h: float) -> float:
        a = math.exp(-h / self.tau)
        self.x1 = a * self.x1 + math.sqrt(2.0 * (1.0 - a * a)) * float(self.rng.normal())
        self.x2 = a * self.x2 + (1.0 - a) * self.x1
        return self.x2


@dataclass
class PartMotion:
    """Planar pose ``(x, y, yaw)`` of the part frame and its current velocity."""

    kind: str
    x: float
    y: float
    yaw: float
    speed: float
    direction: float
    rng: np.random.Generator
    speed_sigma: float = 0.0
    heading_sigma: float = 0.0
    tau: float = 1.0
    yaw_gain: float = 0.5
    n_speed: float = 0.0
    n_heading: float = 0.0
    t: float = 0.0

    def __post_init__(self) -> None:
        self.yaw0 = self.yaw
        self._yaw_rate = 0.0
        if self.kind == "trolley":
            self._ns = SmoothNoise(self.rng, self.tau)
            self._nh = SmoothNoise(self.rng, self.tau)
            self.n_speed, self.n_heading = self._ns.x2, self._nh.x2
            self.yaw = self.yaw0 + self.yaw_gain * self.heading_sigma * self.n_heading

    def velocity(self) -> tuple[float, float, float]:
        """World-frame ``(v_x, v_y, ω)`` now."""
        if self.kind == "conveyor":
            return self.speed * math.cos(self.direction), self.speed * math.sin(self.direction), 0.0
        s = max(0.0, self.speed * (1.0 + self.speed_sigma * self.n_speed))
        h = self.direction + self.heading_sigma * self.n_heading
        return s * math.cos(h), s * math.sin(h), self._yaw_rate

    def step(self, h: float) -> None:
        if self.kind == "trolley":
            self.n_speed = self._ns.step(h)
            self.n_heading = self._nh.step(h)
            yaw = self.yaw0 + self.yaw_gain * self.heading_sigma * self.n_heading
            self._yaw_rate = (yaw - self.yaw) / h
            self.yaw = yaw
        vx, vy, _ = self.velocity()
        self.x += vx * h
        self.y += vy * h
        self.t += h
