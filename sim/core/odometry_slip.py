"""Odometry that drifts: the robot's travel integrated with a scale error and random slip.

A real car's odometry (the paper's LiDAR odometry, F-LOAM [32]; or wheel encoders) is not the ground
truth: it integrates motion increments, each measured with a small relative error, so its error grows
with the distance driven.  :class:`SlipOdometry` reproduces that on top of the simulator's true pose:
every control tick it takes the true motion since the previous tick in the previous robot frame
``(dx, dy, dtheta)``, scales the translation by ``1 + scale_error + slip_noise * N(0, 1)`` (one draw per
tick, seeded) and composes it onto its own pose, which starts at the true start pose.  The heading
increment is taken as is (the translational drift is what the positioning task feels: the object's
position in the robot frame comes from the camera, the robot's motion between detections from here).

``scale_error = slip_noise = 0`` gives back the true pose exactly (the world does not use the model then).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray


class SlipOdometry:
    """Dead-reckoned pose ``(x, y, theta)`` with a translational scale error and per-tick slip noise."""

    def __init__(self, rng: np.random.Generator, scale_error: float, slip_noise: float) -> None:
        if not scale_error > -1.0:
            raise ValueError(f"odometry scale error must be > -1 (a fraction of the distance), got {scale_error}")
        if not slip_noise >= 0.0:
            raise ValueError(f"odometry slip noise must be >= 0, got {slip_noise}")
        self.rng = rng
        self.scale_error = float(scale_error)
        self.slip_noise = float(slip_noise)
        self._true: NDArray[np.float64] | None = None
        self.pose = np.zeros(3)

    def reset(self, true_pose: NDArray[np.float64]) -> None:
        """Start at the true pose (the odometry frame is the start pose)."""
        self._true = np.asarray(true_pose, dtype=float).copy()
        self.pose = self._true.copy()

    def update(self, true_pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """Integrate the true motion since the last call; return the odometry pose (a copy)."""
        new = np.asarray(true_pose, dtype=float)
        if self._true is None:
            self.reset(new)
            return self.pose.copy()
        x0, y0, th0 = self._true
        c, s = math.cos(th0), math.sin(th0)
        dxw, dyw = new[0] - x0, new[1] - y0
        dx, dy = c * dxw + s * dyw, -s * dxw + c * dyw  # motion in the previous robot frame
        dth = math.remainder(float(new[2] - th0), 2.0 * math.pi)
        k = 1.0 + self.scale_error + self.slip_noise * float(self.rng.normal())
        ox, oy, oth = self.pose
        co, so = math.cos(oth), math.sin(oth)
        self.pose = np.array([ox + k * (co * dx - so * dy), oy + k * (so * dx + co * dy),
                              math.remainder(oth + dth, 2.0 * math.pi)])
        self._true = new.copy()
        return self.pose.copy()
