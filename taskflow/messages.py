"""Typed sensor messages: what a world (the producer, in ``sim/``) puts in ``Observation.sensors`` and a
task (the consumer, in ``tasks/``) reads.  Part of the public API: ``tasks/``, ``robots/`` and ``sim/``
import it; it imports numpy only.

Every message is a frozen dataclass with

* ``stamp`` — the simulation time (s) the measurement was taken at (a camera frame's capture time, not
  the control tick that reads it: a latency shows as ``obs.t - stamp``);
* ``frame`` — the name of the coordinate frame its geometry is expressed in, the robot's mount name for
  a camera (``"front_camera"``: its optical frame, x right, y down, z along the axis), ``"tool"`` for
  the wrist F/T sensor, ``"odom"`` for odometry.  Pixel messages are in the image of that camera.

Producers declare each entry with :func:`taskflow.api.message` (``"sensors.marker": message(MarkerPose)``)
and tasks list the ones they read in ``requires``; the compiler matches the two by class and
:mod:`taskflow.catalogue.conformance` checks real observations against the declaration.  Arrays handed over in
messages are read-only where the producer keeps them (keyframe images, landmark views); consumers never
write into them.  Field names of transforms follow :mod:`taskflow.spatial`: ``T_a_b`` maps coordinates in
``b`` to ``a`` (the pose of ``b`` in ``a``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Box = tuple[float, float, float, float]
"""``(u0, v0, u2, v2)`` = (left, top, right, bottom), px."""


@dataclass(frozen=True, kw_only=True)
class Message:
    """Base of every sensor message: ``stamp`` (sim time, s) and ``frame`` (frame name)."""

    stamp: float
    frame: str


@dataclass(frozen=True, kw_only=True)
class Image(Message):
    """One camera image: ``pixels`` (H, W, 3) uint8 RGB, or (H, W) uint8 grey, in camera ``frame``."""

    pixels: NDArray[np.uint8]

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])


@dataclass(frozen=True, kw_only=True)
class Depth(Message):
    """One depth image: ``z`` (H, W) float, the camera-axis coordinate Z (m) of each pixel's return in
    camera ``frame``; 0 where there is none (beyond the sensor's range)."""

    z: NDArray[np.float64]


def _no_depth(u: float, v: float) -> float | None:
    return None


def _no_box_depth(box: Box) -> float | None:
    return None


@dataclass(frozen=True, kw_only=True)
class Detection(Message):
    """One camera frame's object detection (ViKi-HyCo section II-D), in the image of camera ``frame``.

    ``camera`` is the camera's short name (``"front"``, the mount ``front_camera``), ``seq`` the frame's
    index in the world's stream.  ``bbox`` is ``(u0, v0, u2, v2)`` = (left, top, right, bottom) in pixels,
    OpenCV convention (pixel centres at integer coordinates, so a box covering pixel columns ``a..b`` spans
    ``a - 0.5 .. b + 0.5``), or ``None`` when the object is not detected in this frame (out of view,
    occluded, or dropped by the detector).  ``depth`` is ``Z_o`` of eq. 17 (camera-axis depth, m) or
    ``None``.  ``intrinsics`` are ``(fx, fy, cu, cv)`` in pixels for an image of ``width x height``.
    ``fresh`` is true only on the first control tick that sees this frame (the camera runs at its own
    rate, 15 Hz by default, the control at the mission's rate).
    ``depth_at(u, v)`` returns the depth image value (camera Z, m) at a pixel, or ``None`` where there is
    no depth (outside the image, no return) — eq. 19's ``Z_d`` at the desired centre.
    ``depth_in(box)`` applies eq. 16–17 (mean of the valid depths in the box shrunk by 40 %) to any box
    ``(u0, v0, u2, v2)`` of the same depth image: ``Z_d`` read with the rule that gives ``Z_o``.
    """

    camera: str
    seq: int
    bbox: Box | None
    depth: float | None
    intrinsics: tuple[float, float, float, float]
    width: int
    height: int
    fresh: bool = True
    depth_at: Callable[[float, float], float | None] = field(default=_no_depth, repr=False, compare=False)
    depth_in: Callable[[Box], float | None] = field(default=_no_box_depth, repr=False, compare=False)

    @property
    def detected(self) -> bool:
        """A usable detection: a box and a valid object depth."""
        return self.bbox is not None and self.depth is not None and self.depth > 0.0

    def stale(self) -> Detection:
        """The same frame seen again on a later control tick (``fresh = False``)."""
        return self if not self.fresh else dataclasses.replace(self, fresh=False)


@dataclass(frozen=True, kw_only=True)
class FeatureView(Message):
    """Point features seen in one image of camera ``frame``: ``ids`` (N,) int, sorted, the features'
    identities (two views correspond where their ids are equal), and ``uv`` (N, 2) their pixel
    coordinates (px, OpenCV convention)."""

    ids: NDArray[np.int64]
    uv: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True, kw_only=True)
class Silhouette(Message):
    """An obstacle's silhouette on the middle row of the image of camera ``frame``: its left and right
    edges ``u_left < u_right`` (px) and whether it touches the image border (so an edge is not its own)."""

    u_left: float
    u_right: float
    touches_border: bool


@dataclass(frozen=True, kw_only=True)
class MarkerPose(Message):
    """A fiducial marker's pose measured in camera ``frame``: ``T_camera_object`` (4x4, m) maps object
    (marker) coordinates to the camera's optical frame; ``stamp`` is the capture time (the message
    arrives after the detector's latency) and ``seq`` counts the detections delivered (1, 2, ...), so a
    consumer sees a new measurement when it changes."""

    T_camera_object: NDArray[np.float64]
    seq: int


@dataclass(frozen=True, kw_only=True)
class Wrench(Message):
    """A force/torque reading in ``frame`` (about its origin): ``force`` (3,) N, ``torque`` (3,) N·m."""

    force: NDArray[np.float64]
    torque: NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class JointState(Message):
    """Joint positions (rad or m) and velocities (rad/s or m/s) of the joints ``names``, in their order."""

    names: tuple[str, ...]
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class Odometry(Message):
    """A planar pose ``(x, y, yaw)`` (m, m, rad) of the robot in ``frame`` (``"odom"``) and its body
    twist ``(v_x, v_y, w_z)`` (m/s, m/s, rad/s) in the robot frame."""

    pose: tuple[float, float, float]
    twist: tuple[float, float, float] = (0.0, 0.0, 0.0)


__all__ = ["Box", "Depth", "Detection", "FeatureView", "Image", "JointState", "MarkerPose", "Message", "Odometry",
           "Silhouette", "Wrench"]
