"""Sensor messages shared by worlds (producers, in ``sim/``) and tasks (consumers, in ``tasks/``).

No simulator code here: a task imports these types to read ``Observation.sensors`` without importing
``sim/`` or pybullet.

ViKi-HyCo perception (paper section II-C/D) produces, per camera frame, one :class:`Detection`: the
object's bounding box (or ``None``), its depth ``Z_o`` (eq. 16–17, mean of the valid depths inside the
box shrunk by 40 %), and a way to read the depth image at any pixel (``depth_at``) — eq. 19 needs the
depth ``Z_d`` at the *desired* centre pixel every frame.  Both perception modes of the ``viki_ground``
world (``geometric`` projection and ``rendered`` pixels) fill the same message.

Which camera a world runs is chosen by the task through its command: a key ``camera_<name>`` with value
``1`` (see :func:`camera_command`).  A command without such keys leaves the active camera unchanged
(a state without a task, or the runtime's stop command, keeps watching); a command whose camera keys are
all ``0`` switches every camera off (no rendering).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

CAMERA_PREFIX = "camera_"
"""Command keys ``camera_<name>`` select the active camera (value > 0.5 = active)."""

CAMERAS = ("front", "rear")
"""Camera names of the racecar (``Racecar.Params.front_camera`` / ``rear_camera``)."""

Box = tuple[float, float, float, float]


def camera_command(name: str | None) -> dict[str, np.ndarray]:
    """Command entries that make ``name`` the active camera (``None``: no camera at all)."""
    if name is not None and name not in CAMERAS:
        raise ValueError(f"unknown camera {name!r}; valid: {', '.join(CAMERAS)}")
    return {f"{CAMERA_PREFIX}{c}": np.array([1.0 if c == name else 0.0]) for c in CAMERAS}


def active_camera_from_command(command: Mapping[str, object], current: str | None) -> str | None:
    """The camera a command selects: the ``camera_<name>`` key with the largest value above 0.5.

    No camera keys at all: ``current`` (unchanged).  Camera keys all at or below 0.5: ``None``.
    (Blended commands mix two cameras' keys; the larger weight wins.)
    """
    best, best_val, seen = None, 0.5, False
    for key, val in command.items():
        if not key.startswith(CAMERA_PREFIX):
            continue
        seen = True
        x = float(np.asarray(val, dtype=float).reshape(-1)[0])
        if x > best_val:
            best, best_val = key[len(CAMERA_PREFIX):], x
    return best if seen else current


def _no_depth(u: float, v: float) -> float | None:
    return None


def _no_box_depth(box: Box) -> float | None:
    return None


@dataclass(frozen=True)
class Detection:
    """One camera frame's object detection (ViKi-HyCo section II-D).

    ``bbox`` is ``(u0, v0, u2, v2)`` = (left, top, right, bottom) in pixels, OpenCV convention (pixel
    centres at integer coordinates, so a box covering pixel columns ``a..b`` spans ``a - 0.5 .. b + 0.5``),
    or ``None`` when the object is not detected in this frame (out of view, occluded, or dropped by the
    detector).  ``depth`` is ``Z_o`` of eq. 17 (camera-axis depth, m) or ``None``.  ``intrinsics`` are
    ``(fx, fy, cu, cv)`` in pixels for an image of ``width x height``.  ``t`` is the frame's capture time
    and ``frame`` its index; ``fresh`` is true only on the first control tick that sees this frame (the
    camera runs at its own rate, 15 Hz by default, the control at the mission's rate).
    ``depth_at(u, v)`` returns the depth image value (camera Z, m) at a pixel, or ``None`` where there is
    no depth (outside the image, no return) — eq. 19's ``Z_d`` at the desired centre.
    ``depth_in(box)`` applies eq. 16–17 (mean of the valid depths in the box shrunk by 40 %) to any box
    ``(u0, v0, u2, v2)`` of the same depth image: ``Z_d`` read with the rule that gives ``Z_o``.
    """

    camera: str
    t: float
    frame: int
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

    def stale(self) -> "Detection":
        """The same frame seen again on a later control tick (``fresh = False``)."""
        if not self.fresh:
            return self
        return Detection(self.camera, self.t, self.frame, self.bbox, self.depth, self.intrinsics, self.width,
                         self.height, False, self.depth_at, self.depth_in)
