"""What ``screw_conveyor``'s robot senses, declared as sensor streams (:mod:`taskflow_sim.core.sensors`).

* the **marker camera** (:func:`marker_stream`, stream ``marker``): frames at the camera's rate
  (polled after every physics step); a frame inside an ``occlusions`` interval sees nothing; the
  ``dropout`` misses a frame (both modes); the pose mode gives the true ``T_camera_object`` with the
  calibrated Gauss–Markov noise when the marker is visible, the rendered mode runs the ArUco detector
  on a rendered frame.  A detection is a numbered :class:`taskflow.messages.MarkerPose` (``seq`` 1, 2,
  ... in capture order, which is the order of delivery), delivered ``latency`` seconds after its
  capture, and drives the ``target_found`` / ``target_lost`` events (``lost_after``).  The random draws
  come from one generator in the stream's order: the rendered mode's dropout before the frame is
  rendered (``dropout_first``), the pose mode's after the visibility test and before the noise.
* the **force/torque sensor** (:func:`wrench_stream`, stream ``wrench``): PyBullet's reaction on the
  fixed ``tool_joint`` at the end of every control tick, gravity-compensated for the screwdriver
  (:class:`WrenchSensor`), with white force noise; nothing before the first physics step.

:class:`MarkerCamera` keeps what the camera's pipeline learns beside its readings: the perception
error of every detection against the truth at capture, and (rendered mode) the detector and the
image its latest frame was run on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.mobile_iiwa import CameraParams, ToolParams
from taskflow_sim.core.faults import IntervalFault
from taskflow_sim.core.sensors import Reading, SensorStream
from taskflow_sim.screw.params import ScrewWorldParams
from taskflow_sim.screw.perception import PoseNoise, RenderedDetector, visible

from taskflow.messages import Image, MarkerPose
from taskflow.spatial import rotation_angle

GRAVITY = 9.81


def perception_error(measured: NDArray[np.float64], truth: NDArray[np.float64]) -> tuple[float, float, float]:
    """A marker pose's error against the truth, both ``T_camera_object``: (m across the view, m along
    it, rad)."""
    d = measured[:3, 3] - truth[:3, 3]
    R = measured[:3, :3] @ truth[:3, :3].T
    return math.hypot(d[0], d[1]), abs(d[2]), rotation_angle(R)


@dataclass
class MarkerCamera:
    """The marker camera's pipeline: the true marker pose (``truth``: ``T_camera_object`` now) and the
    camera's world pose (``T_world_camera``), the pose-mode ``noise``, the rendered ``detector`` (None in
    the pose mode); what it learns: ``errors`` (per detection: m across the view, m along it, rad),
    ``image`` (rendered mode: the latest processed frame) and ``numbered`` (detections so far)."""

    camera: CameraParams
    truth: Callable[[], NDArray[np.float64]]
    T_world_camera: Callable[[], NDArray[np.float64]]
    noise: PoseNoise
    detector: RenderedDetector | None
    K: NDArray[np.float64]
    errors: list[tuple[float, float, float]] = field(default_factory=list)
    image: Image | None = None
    numbered: int = 0

    def _numbered(self, stamp: float, T_camera_object: NDArray[np.float64]) -> MarkerPose:
        self.numbered += 1
        return MarkerPose(stamp=stamp, frame="camera", T_camera_object=T_camera_object, seq=self.numbered)

    def read(self, stamp: float, _state: object) -> MarkerPose | None:
        """One frame: the rendered detector's pose, or the true pose when the marker is visible (the
        pose mode's noise comes after the dropout, in :meth:`corrupt`)."""
        det = self.detector
        if det is None:
            T = self.truth()
            return MarkerPose(stamp=stamp, frame="camera", T_camera_object=T, seq=0) \
                if visible(self.camera, T, K=self.K) else None
        found = det(self.T_world_camera(), stamp)
        img = det.last_image  # what this frame's detection was run on (set by every call)
        if img is not None:
            img.setflags(write=False)
            self.image = Image(stamp=stamp, frame="camera", pixels=img)
        return None if found.H_co is None else self._numbered(stamp, found.H_co)

    def corrupt(self, m: MarkerPose, stamp: float, _rng: np.random.Generator) -> MarkerPose:
        """The pose mode's calibrated noise on a visible marker (its generator is ``noise``'s, the stream's)."""
        return self._numbered(stamp, self.noise.apply(m.T_camera_object, stamp))

    def on_capture(self, reading: Reading[MarkerPose]) -> None:
        """The perception error of a detection against the truth at its capture."""
        if reading.value is not None:
            self.errors.append(perception_error(reading.value.T_camera_object, self.truth()))


def marker_stream(cam: MarkerCamera, wp: ScrewWorldParams, rng: np.random.Generator,
                  occlusions: IntervalFault) -> SensorStream[MarkerPose]:
    """The marker camera's stream at the camera's rate, with the world's latency, dropout, occlusions and
    lost/found events (module docstring)."""
    rendered = cam.detector is not None
    return SensorStream(cam.read, cam.camera.rate_hz, latency=wp.latency, delivery="each",
                        corrupt=None if rendered else cam.corrupt, rng=rng, dropout=wp.dropout,
                        dropout_first=rendered, faults=occlusions, events=("target_found", "target_lost"),
                        lost_after=wp.lost_after, on_capture=cam.on_capture, poll="physics_step")


@dataclass
class WrenchSensor:
    """The F/T sensor on the fixed tool joint, gravity-compensated for the screwdriver (``weight`` N,
    centre of mass ``com`` in the tool frame), with white force noise of std ``noise`` N."""

    noise: float
    com: NDArray[np.float64]
    weight: float

    @classmethod
    def for_tool(cls, tool: ToolParams, noise: float) -> WrenchSensor:
        return cls(noise, np.array([0.0, 0.0, 0.5 * (tool.length - tool.bit_length)]), tool.mass * GRAVITY)

    def compensate(self, reading: NDArray[np.float64], R_world_tool: NDArray[np.float64]) -> NDArray[np.float64]:
        """The contact wrench (force N, torque N·m about the tool joint, tool frame) from the joint's
        ``reading`` (force of the flange on the tool) and the tool's orientation."""
        w = R_world_tool[2] * -self.weight  # the tool's weight in the tool frame (Rᵀ [0, 0, −mg])
        f = -reading[:3] - w
        c = self.com
        m = -reading[3:] - np.array([c[1] * w[2] - c[2] * w[1], c[2] * w[0] - c[0] * w[2], c[0] * w[1] - c[1] * w[0]])
        return np.concatenate([f, m])

    def corrupt(self, wrench: NDArray[np.float64], _stamp: float, rng: np.random.Generator) -> NDArray[np.float64]:
        """White force noise (none drawn when ``noise`` is 0)."""
        if self.noise <= 0.0:
            return wrench
        return np.concatenate([wrench[:3] + rng.normal(0.0, self.noise, 3), wrench[3:]])


def wrench_stream(sensor: WrenchSensor, read: Callable[[float, object], NDArray[np.float64] | None],
                  rng: np.random.Generator, rate_hz: float) -> SensorStream[NDArray[np.float64]]:
    """The F/T sensor's stream: read at the end of every ``advance`` (``rate_hz``: the physics rate, so
    every control tick is due), no latency."""
    return SensorStream(read, rate_hz, corrupt=sensor.corrupt, rng=rng, poll="advance")
