"""The racecar-family cameras shared by worlds (``sim/``) and tasks (``tasks/``): their names and how a
task selects the active one.  No simulator code here.

The messages the cameras produce are :mod:`taskflow.messages`' (ViKi-HyCo perception fills one
:class:`taskflow.messages.Detection` per frame).

Which camera a world runs is chosen by the task through its command: a key ``camera_<name>`` with value
``1`` (see :func:`camera_command`).  A command without such keys leaves the active camera unchanged
(a state without a task, or the runtime's stop command, keeps watching); a command whose camera keys are
all ``0`` switches every camera off (no rendering).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

CAMERA_PREFIX = "camera_"
"""Command keys ``camera_<name>`` select the active camera (value > 0.5 = active)."""

CAMERAS = ("front", "rear")
"""Camera names of the racecar (``Racecar.Params.front_camera`` / ``rear_camera``)."""


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


__all__ = ["CAMERAS", "CAMERA_PREFIX", "active_camera_from_command", "camera_command"]
