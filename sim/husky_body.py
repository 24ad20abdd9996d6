"""The Husky body: PyBullet's ``husky/husky.urdf`` driven by skid-steer wheel velocity control.

``apply({"v", "w"})`` clips the unicycle command to the robot's limits; every physics step
:meth:`HuskyBody.update` moves the actuated ``(v, w)`` toward it within the acceleration limits and
through the world's first-order lags (``speed_tau`` on ``v``, ``steer_tau`` on ``w``), then sets both
wheels of each side to

    w_left = (v - w B / 2) / r,   w_right = (v + w B / 2) / r,   B = track_multiplier * track

with velocity motors bounded by ``wheel_torque``.  Motion comes from the wheels' contact with the floor
only (nothing pushes the chassis), so slip, skid and the chassis' inertia are the simulator's.

Facts this module relies on (see ``tests/sim/test_husky_body.py``):

* the base link is ``base_footprint``, on the ground between the four wheels (wheel joints at
  ``z = 0.17775`` = wheel radius); its inertial frame is read and corrected as for the racecar;
* the wheels are loaded as implicit cylinders (``URDF_USE_IMPLICIT_CYLINDER``), not convex hulls;
* joints are looked up by name and every joint's default velocity motor is released first.
"""

from __future__ import annotations

import ctypes
import math
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, ClassVar

import numpy as np
import pybullet as p
import pybullet_data
from numpy.typing import NDArray
from taskflow_robots.husky import Husky
from taskflow_sim.core.bodies import BodyOptions, GroundBody

from taskflow.api import Command, Robot
from taskflow.spatial import yaw_from_quaternion

URDF = os.path.join(pybullet_data.getDataPath(), "husky", "husky.urdf")
LEFT = ("front_left_wheel", "rear_left_wheel")
RIGHT = ("front_right_wheel", "rear_right_wheel")


@contextmanager
def _quiet() -> Iterator[None]:
    """The URDF's massless links make Bullet print a warning per link on the C streams: silence them."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            yield
            ctypes.CDLL(None).fflush(None)
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])


def _toward(x: float, target: float, step: float) -> float:
    return x + min(max(target - x, -step), step)


class HuskyBody(GroundBody):
    """``husky`` body (see module doc)."""

    robot: Husky
    robot_cls: ClassVar[type[Robot]] = Husky

    def __init__(self, robot: Robot, options: BodyOptions) -> None:
        super().__init__(robot, options)
        self._cmd = (0.0, 0.0)  # commanded (v, w), clipped
        self._ramp = (0.0, 0.0)  # after the acceleration limits
        self._act = (0.0, 0.0)  # after the first-order lags: what the wheels are set to

    def spawn(self, client: int, pose: tuple[float, float, float]) -> None:
        self.client = client
        with _quiet():
            self.uid = p.loadURDF(URDF, [0.0, 0.0, 0.0], flags=p.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=client)
        n = p.getNumJoints(self.uid, physicsClientId=client)
        joints = {p.getJointInfo(self.uid, j, physicsClientId=client)[1].decode(): j for j in range(n)}
        missing = [w for w in LEFT + RIGHT if w not in joints]
        if missing:
            raise ValueError(f"{URDF}: joints {missing} not found; has {sorted(joints)}")
        self.joints = joints
        self.wheels = [joints[w] for w in LEFT + RIGHT]
        dyn = p.getDynamicsInfo(self.uid, -1, physicsClientId=client)
        self._inertial = (tuple(dyn[3]), tuple(dyn[4]))  # base frame → inertial frame
        self._inertial_inv = p.invertTransform(*self._inertial)
        for j in joints.values():
            p.setJointMotorControl2(self.uid, j, p.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0,
                                    physicsClientId=client)
        for j in self.wheels:
            p.changeDynamics(self.uid, j, lateralFriction=self.options.friction, physicsClientId=client)
        x, y, yaw = (float(s) for s in pose)
        pos, q = p.multiplyTransforms([x, y, 0.0], p.getQuaternionFromEuler([0.0, 0.0, yaw]), *self._inertial)
        p.resetBasePositionAndOrientation(self.uid, pos, q, physicsClientId=client)
        self._cmd = self._ramp = self._act = (0.0, 0.0)
        self._send()

    # --- command -------------------------------------------------------------------------------
    def apply(self, command: Command) -> None:
        v, w = float(command["v"][0]), float(command["w"][0])
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"husky command must be finite, got v={v!r}, w={w!r}")
        rp = self.robot.params
        self._cmd = (min(max(v, -rp.v_max), rp.v_max), min(max(w, -rp.w_max), rp.w_max))

    def update(self, h: float) -> None:
        rp, o = self.robot.params, self.options
        v = _toward(self._ramp[0], self._cmd[0], rp.a_max * h)
        w = _toward(self._ramp[1], self._cmd[1], rp.alpha_max * h)
        self._ramp = (v, w)
        av, aw = self._act
        av += (v - av) * (1.0 - math.exp(-h / o.speed_tau) if o.speed_tau > 0.0 else 1.0)
        aw += (w - aw) * (1.0 - math.exp(-h / o.steer_tau) if o.steer_tau > 0.0 else 1.0)
        self._act = (av, aw)
        self._send()

    def _send(self) -> None:
        rp = self.robot.params
        v, w = self._act
        half = 0.5 * rp.track_multiplier * rp.track * w
        wl, wr = (v - half) / rp.wheel_radius, (v + half) / rp.wheel_radius
        p.setJointMotorControlArray(self.uid, self.wheels, p.VELOCITY_CONTROL, targetVelocities=[wl, wl, wr, wr],
                                    forces=[rp.wheel_torque] * 4, physicsClientId=self.client)

    # --- ground truth --------------------------------------------------------------------------
    def _base_frame(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        com_pos, com_q = p.getBasePositionAndOrientation(self.uid, physicsClientId=self.client)
        return p.multiplyTransforms(com_pos, com_q, *self._inertial_inv)

    def pose(self) -> NDArray[np.float64]:
        pos, q = self._base_frame()
        return np.array([pos[0], pos[1], yaw_from_quaternion(q)])

    def twist(self) -> NDArray[np.float64]:
        lin, ang = p.getBaseVelocity(self.uid, physicsClientId=self.client)
        com_pos, _ = p.getBasePositionAndOrientation(self.uid, physicsClientId=self.client)
        pos, q = self._base_frame()
        vel = np.asarray(lin) + np.cross(ang, np.subtract(pos, com_pos))
        yaw = yaw_from_quaternion(q)
        return np.array([float(vel[0] * math.cos(yaw) + vel[1] * math.sin(yaw)), float(ang[2])])

    def proprioception(self) -> dict[str, Any]:
        v, w = self.twist()
        return {"pose": self.pose(), "v": float(v), "w": float(w)}
