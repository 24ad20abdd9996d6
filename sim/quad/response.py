"""How the quadcopter's on-board controller executes ``[vx, vy, vz, wz]`` commands, and how late.

Two responses (``quad_room``'s ``command_response``):

* ``velocity`` — the body velocity tracks the command through a first-order lag (robot ``tau``): an
  ideal low-level velocity loop, as the paper's eq. (1) assumes.
* ``relative_move`` — the Parrot Bebop 2 under ViSP: ``vpRobotBebop2::setVelocity(v, Δt)`` does not
  send a velocity; it sends ``setPosition(exp(v Δt))``, the ARSDK relative move ``moveBy(dX, dY, dZ,
  dψ)`` of ``v·Δt`` from where the drone is, non-blocking (ViSP ``modules/robot/src/real-robot/bebop2/
  vpRobotBebop2.cpp``; the paper, §5, sends its commands with ``drone.setVelocity``).  The drone's
  position loop then approaches that target with time constant ``move_tau`` until the next command
  replaces it with a new one, again relative to where the drone is by then: the part of each move not
  done within a command period is lost.

:class:`taskflow_sim.core.command_delay.CommandDelay` holds commands for a transport delay before they act.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from taskflow.spatial import planar_apply

Vec = NDArray[np.float64]

__all__ = ["move_target", "relative_move_step"]


def move_target(pose: Vec, nu: Vec, dt: float) -> Vec:
    """Target ``[x, y, z, yaw]`` of the relative move ``nu·dt`` (``nu = [vx, vy, vz, wz]``, body frame
    FLU) started at ``pose`` (world frame): translation turned by the current yaw, yaw added."""
    x, y, z, yaw = (float(v) for v in pose)
    vx, vy, vz, wz = (float(v) * dt for v in nu)
    px, py = planar_apply((x, y, yaw), (vx, vy))
    return np.array([px, py, z + vz, yaw + wz])


def relative_move_step(pose: Vec, target: Vec, h: float, tau: float) -> Vec:
    """One step ``h`` of the position loop toward ``target``: ``pose += (1 − e^(−h/τ)) (target − pose)``
    (yaw by the shorter way, wrapped to (−π, π]); returns the new pose."""
    a = 1.0 - math.exp(-h / tau) if tau > 0.0 else 1.0
    d = np.asarray(target, dtype=np.float64) - pose
    d[3] = math.remainder(d[3], 2.0 * math.pi)
    out = pose + a * d
    out[3] = math.remainder(out[3], 2.0 * math.pi)
    return out
