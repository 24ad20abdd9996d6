"""What ``screw_conveyor``'s robot senses: the marker camera and the tool's force/torque sensor.

* :class:`MarkerStream` — the camera's marker detections: frames are taken at the camera's rate
  (``schedule``); a frame inside an occlusion interval sees nothing; the dropout (both modes) misses a
  frame; the pose mode gives the true ``T_camera_object`` with calibrated noise when the marker is
  visible, the rendered mode runs the ArUco detector on a rendered frame.  Detections wait ``latency``
  seconds (image transfer + processing), are then delivered in capture order as a numbered
  :class:`taskflow.messages.MarkerPose`, and drive the ``target_found`` / ``target_lost`` events.  The
  random draws come from one stream (``rng``) in a fixed order: the rendered mode's dropout before
  the frame is rendered, the pose mode's after the visibility test and before the noise.
* :class:`WrenchSensor` — PyBullet's F/T reading on the fixed tool joint, gravity-compensated for the
  screwdriver, with white force noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.mobile_iiwa import ToolParams
from taskflow_sim.core.faults import IntervalFault
from taskflow_sim.core.stepped import SensorSchedule
from taskflow_sim.screw.perception import MarkerDetection, PoseNoise, RenderedDetector

from taskflow.spatial import rotation_angle

GRAVITY = 9.81


def perception_error(measured: NDArray[np.float64], truth: NDArray[np.float64]) -> tuple[float, float, float]:
    """A marker pose's error against the truth, both ``T_camera_object``: (m across the view, m along
    it, rad)."""
    d = measured[:3, 3] - truth[:3, 3]
    R = measured[:3, :3] @ truth[:3, :3].T
    return math.hypot(d[0], d[1]), abs(d[2]), rotation_angle(R)


@dataclass
class MarkerStream:
    """The camera's marker detections: when frames are taken (``schedule``, at the camera's rate), the
    occlusion fault, the pose-mode noise and the dropout stream (``rng``, both modes), the rendered
    ``detector`` (None in the pose mode), ``dropped``: rendered frames the dropout skipped,
    detections in flight (``queue``, delivered after the latency), the perception error of every
    detection against the truth (``errors``: m across the view, m along it, rad) and the lost/found
    bookkeeping (``last_seen``: capture time of the last delivered detection)."""

    schedule: SensorSchedule
    occlusions: IntervalFault
    noise: PoseNoise
    rng: np.random.Generator
    detector: RenderedDetector | None
    queue: list[MarkerDetection] = field(default_factory=list)
    errors: list[tuple[float, float, float]] = field(default_factory=list)
    last_seen: float | None = None
    visible: bool = False
    dropped: int = 0


@dataclass
class WrenchSensor:
    """The F/T sensor on the fixed tool joint, gravity-compensated for the screwdriver (``weight`` N,
    centre of mass ``com`` in the tool frame), with white force noise of std ``noise`` N."""

    rng: np.random.Generator
    noise: float
    com: NDArray[np.float64]
    weight: float

    @classmethod
    def for_tool(cls, tool: ToolParams, rng: np.random.Generator, noise: float) -> WrenchSensor:
        return cls(rng, noise, np.array([0.0, 0.0, 0.5 * (tool.length - tool.bit_length)]), tool.mass * GRAVITY)

    def read(self, reading: NDArray[np.float64], R_wt: NDArray[np.float64]) -> NDArray[np.float64]:
        """The contact wrench (force N, torque N·m about the tool joint, tool frame) from the joint's
        ``reading`` (force of the flange on the tool) and the tool's orientation ``R_wt``."""
        w = R_wt[2] * -self.weight  # the tool's weight in the tool frame (Rᵀ [0, 0, −mg])
        f = -reading[:3] - w
        c = self.com
        m = -reading[3:] - np.array([c[1] * w[2] - c[2] * w[1], c[2] * w[0] - c[0] * w[2], c[0] * w[1] - c[1] * w[0]])
        if self.noise > 0.0:
            f = f + self.rng.normal(0.0, self.noise, 3)
        return np.concatenate([f, m])
