"""The PyBullet racecar (``pybullet_data/racecar/racecar.urdf``): Ackermann steering, rear-wheel drive.

Hardware side of the ``racecar`` robot.  ``apply(v, psi)`` takes the bicycle-model command (forward
speed of the rear-axle midpoint, steering angle), clips it to the robot's limits, passes it through an
optional first-order actuator lag, then steers both hinges with Ackermann angles and drives the rear
wheels with an electronic differential (SIMULATOR_NOTES.md: the yaw rate then follows the bicycle model).

Facts this module relies on (measured, see the module's tests):

* joints are looked up by name — ``getNumJoints`` counts the URDF's fixed joints too;
* every joint starts with a velocity motor: the free ones (front wheels) are zeroed with ``force=0``;
* wheels are loaded as implicit cylinders (``URDF_USE_IMPLICIT_CYLINDER``): the default convex-hull
  cylinder is a polygon that makes the car bounce (±0.03 m/s vertical jitter) and its speed 2 % high;
* the URDF base frame (``base_link``) is the rear-axle midpoint on the ground; poses are read through
  the base's inertial frame and corrected with ``getDynamicsInfo`` (identity for this URDF, kept so a
  different car model cannot silently shift the pose).

Geometry used for the Ackermann/differential split (wheelbase, track, wheel radius) is read from the
loaded URDF, not from the robot parameters: the hardware is what it is; the controller's belief about it
lives in ``Racecar.Params``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import pybullet as p
import pybullet_data
from numpy.typing import NDArray
from taskflow_robots.racecar_kinematics import (
    ackermann_wheel_angles,
    bicycle_from_wheel_angles,
    differential_wheel_speeds,
)
from taskflow_sim.ground.base_frame import BaseFrame, Frame

URDF = os.path.join(pybullet_data.getDataPath(), "racecar", "racecar.urdf")

REAR_WHEELS = ("left_rear_wheel_joint", "right_rear_wheel_joint")
HINGES = ("left_steering_hinge_joint", "right_steering_hinge_joint")
FRONT_WHEELS = ("left_front_wheel_joint", "right_front_wheel_joint")


@dataclass(frozen=True)
class Geometry:
    """Car geometry as loaded (m).

    ``track`` is the distance between the steering hinges (the Ackermann angles are exact for it, since
    each wheel's contact is offset along its own axis); ``drive_track`` the distance between the rear
    wheels' contact centres, which the URDF offsets 2.25 cm outward from the wheel joints (0.245 m):
    the electronic differential must use it or the rear wheels fight each other.
    """

    wheelbase: float
    track: float
    drive_track: float
    wheel_radius: float


@dataclass(frozen=True)
class Actuation:
    """Limits and actuator response of the car.

    ``v_max`` (m/s) and ``psi_max`` (rad) clip every command; ``speed_tau`` / ``steer_tau`` (s) are the
    time constants of a first-order response of speed and steering to the command (0: immediate).
    ``wheel_torque`` / ``steer_torque`` (N m) bound the joint motors.
    """

    v_max: float
    psi_max: float
    speed_tau: float = 0.0
    steer_tau: float = 0.0
    wheel_torque: float = 10.0
    steer_torque: float = 10.0

    def __post_init__(self) -> None:
        for name in ("v_max", "psi_max", "wheel_torque", "steer_torque"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"Actuation.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("speed_tau", "steer_tau"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"Actuation.{name} must be >= 0, got {getattr(self, name)!r}")


class RacecarBody:
    """One racecar in a PyBullet client.  Call :meth:`update` once per physics step before stepping."""

    def __init__(
        self,
        client: int,
        start: tuple[float, float, float],
        actuation: Actuation,
        tire_friction: float = 1.0,
    ) -> None:
        self.client = client
        self.actuation = actuation
        x, y, yaw = (float(s) for s in start)
        self.body = p.loadURDF(
            URDF,
            [0.0, 0.0, 0.0],
            flags=p.URDF_USE_IMPLICIT_CYLINDER,
            physicsClientId=client,
        )
        self.joints = self._joint_map()
        missing = [n for n in REAR_WHEELS + HINGES + FRONT_WHEELS if n not in self.joints]
        if missing:
            raise ValueError(f"{URDF}: joints {missing} not found; has {sorted(self.joints)}")
        self.base = BaseFrame(client, self.body)
        self.geometry = self._read_geometry()
        for j in self.joints.values():
            p.setJointMotorControl2(
                self.body, j, p.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0, physicsClientId=client
            )
        for name in REAR_WHEELS + FRONT_WHEELS:
            p.changeDynamics(
                self.body, self.joints[name], lateralFriction=tire_friction, physicsClientId=client
            )
        self.set_pose(x, y, yaw)
        self._cmd = (0.0, 0.0)  # commanded (v, psi), clipped
        self._act = (0.0, 0.0)  # actuator state after the first-order response
        self._send(0.0, 0.0)

    # --- set-up --------------------------------------------------------------------------------
    def _joint_map(self) -> dict[str, int]:
        n = p.getNumJoints(self.body, physicsClientId=self.client)
        return {p.getJointInfo(self.body, j, physicsClientId=self.client)[1].decode(): j for j in range(n)}

    def _read_geometry(self) -> Geometry:
        """Wheelbase and track from the hinge/wheel joint origins, radius from the wheel collision shape."""

        def origin(name: str) -> tuple[float, ...]:
            return tuple(p.getJointInfo(self.body, self.joints[name], physicsClientId=self.client)[14])

        rl = origin(REAR_WHEELS[0])
        hl, hr = origin(HINGES[0]), origin(HINGES[1])
        inv = p.invertTransform(*self._base_frame())
        cl, cr = (
            p.multiplyTransforms(
                *inv, p.getLinkState(self.body, self.joints[n], physicsClientId=self.client)[0], (0, 0, 0, 1)
            )[0]
            for n in REAR_WHEELS
        )  # rear wheel contact centres (link centres of mass) in the base frame
        shape = p.getCollisionShapeData(self.body, self.joints[REAR_WHEELS[0]], physicsClientId=self.client)
        radius = float(shape[0][3][1]) if shape and shape[0][2] == p.GEOM_CYLINDER else 0.05
        return Geometry(
            wheelbase=hl[0] - rl[0], track=hl[1] - hr[1], drive_track=cl[1] - cr[1], wheel_radius=radius
        )

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        """Teleport the base frame (rear-axle midpoint on the ground) to ``(x, y, yaw)``, at rest."""
        self.base.place(x, y, yaw)
        p.resetBaseVelocity(self.body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=self.client)
        for j in self.joints.values():
            p.resetJointState(self.body, j, 0.0, 0.0, physicsClientId=self.client)

    # --- command -------------------------------------------------------------------------------
    def apply(self, v: float, psi: float) -> None:
        """Command forward speed ``v`` (m/s) and bicycle steering ``psi`` (rad), clipped to the limits."""
        if not (math.isfinite(v) and math.isfinite(psi)):
            raise ValueError(f"racecar command must be finite, got v={v!r}, psi={psi!r}")
        a = self.actuation
        self._cmd = (min(max(v, -a.v_max), a.v_max), min(max(psi, -a.psi_max), a.psi_max))
        if a.speed_tau == 0.0 and a.steer_tau == 0.0:
            self._act = self._cmd
            self._send(*self._act)

    def update(self, h: float) -> None:
        """Advance the actuator response by one physics step of ``h`` seconds (no-op when immediate)."""
        a = self.actuation
        if a.speed_tau == 0.0 and a.steer_tau == 0.0:
            return
        v, psi = self._act
        v += (self._cmd[0] - v) * (1.0 - math.exp(-h / a.speed_tau) if a.speed_tau > 0 else 1.0)
        psi += (self._cmd[1] - psi) * (1.0 - math.exp(-h / a.steer_tau) if a.steer_tau > 0 else 1.0)
        self._act = (v, psi)
        self._send(v, psi)

    def _send(self, v: float, psi: float) -> None:
        g, a, c = self.geometry, self.actuation, self.client
        left, right = ackermann_wheel_angles(psi, g.wheelbase, g.track)
        wl, wr = differential_wheel_speeds(v, psi, g.wheelbase, g.drive_track, g.wheel_radius)
        p.setJointMotorControlArray(self.body, [self.joints[n] for n in HINGES], p.POSITION_CONTROL,
                                    targetPositions=[left, right], forces=[a.steer_torque] * 2, physicsClientId=c)
        p.setJointMotorControlArray(self.body, [self.joints[n] for n in REAR_WHEELS], p.VELOCITY_CONTROL,
                                    targetVelocities=[wl, wr], forces=[a.wheel_torque] * 2, physicsClientId=c)

    # --- state (ground truth) ------------------------------------------------------------------
    def pose(self) -> NDArray[np.float64]:
        """Ground-truth ``(x, y, yaw)`` of the base frame (rear-axle midpoint on the ground)."""
        return self.base.pose()

    def _base_frame(self) -> Frame:
        """``(position, quaternion)`` of the base frame (the ViKi-HyCo scene mounts its sensors on it)."""
        return self.base.frame()

    def speed(self) -> float:
        """Ground-truth signed forward speed (m/s) of the base frame along its heading."""
        return self.base.twist()[0]

    def steering(self) -> float:
        """Measured bicycle-equivalent steering angle (rad) from the two hinge joint angles."""
        ql, qr = (p.getJointState(self.body, self.joints[n], physicsClientId=self.client)[0] for n in HINGES)
        g = self.geometry
        return bicycle_from_wheel_angles(ql, qr, g.wheelbase, g.track)
