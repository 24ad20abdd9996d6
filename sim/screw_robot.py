"""The mobile iiwa in PyBullet: the run-time URDF loaded with a fixed base that is moved kinematically.

The platform is holonomic and velocity-commanded: a command takes effect after the platform's
transport delay (:class:`CommandDelay`, ``base_delay``; none by default), then its twist follows it through a
first-order lag (``platform_tau``, 0.1 s by default) with an acceleration limit, and its pose is integrated exactly for a constant twist over each physics
step, then written with ``resetBasePositionAndOrientation`` (the base link ``platform`` has its
inertial frame at its link frame, so no inertial offset to correct).  The arm joints are servoed by
``POSITION_CONTROL`` (gain 0.3, SIMULATOR_NOTES.md) to a reference that is ramped over each control
tick.  A force/torque sensor on the fixed ``tool_joint`` measures the screwdriver's load.

Safe stop (:meth:`MobileIiwaBody.brake` and :meth:`MobileIiwaBody.hold`): the platform decelerates to
exactly zero at the robot's ``brake_decel``, and the arm's reference stops where its ramp is, so the
position servo brings the joints to rest there.

Joints and links are found by name, never by index.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_robots.iiwa_urdf import ARM_JOINTS, CAMERA_LINK, TOOL_JOINT, TOOL_TIP, write_urdf
from taskflow_robots.mobile_iiwa import MobileIiwa
from taskflow_sim.core.command_delay import CommandDelay

from taskflow.spatial import quaternion_from_yaw, rotation_from_quaternion, transform_from_pose, transform_xyz_yaw


@dataclass
class PlatformState:
    """Planar pose ``(x, y, yaw)`` in the world and body-frame twist ``(v_x, v_y, ω_z)``."""

    pose: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    twist: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


def integrate_planar(pose: tuple[float, float, float] | NDArray[np.float64], twist: tuple[float, float, float],
                     h: float) -> tuple[float, float, float]:
    """Exact pose after ``h`` seconds of a constant body-frame twist."""
    x, y, th = float(pose[0]), float(pose[1]), float(pose[2])
    vx, vy, wz = twist
    dth = wz * h
    if abs(dth) < 1e-12:
        dx, dy = vx * h, vy * h
    else:
        s, c = math.sin(dth), math.cos(dth)
        dx = (vx * s - vy * (1.0 - c)) / wz
        dy = (vx * (1.0 - c) + vy * s) / wz
    ct, st = math.cos(th), math.sin(th)
    return (x + ct * dx - st * dy, y + st * dx + ct * dy, th + dth)


class MobileIiwaBody:
    """The robot's PyBullet multibody, the platform's kinematic motion and the arm's position servo."""

    def __init__(self, client: int, robot: MobileIiwa, start: tuple[float, float, float], q0: NDArray[np.float64],
                 *, platform_tau: float = 0.1, base_delay: float = 0.0, position_gain: float = 0.3,
                 max_force: float = 300.0) -> None:
        self.client = client
        self.robot = robot
        rp = robot.params
        self.path = write_urdf(robot.urdf_text)
        self.id = p.loadURDF(str(self.path), basePosition=[start[0], start[1], 0.0], baseOrientation=quaternion_from_yaw(start[2]),
                             useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
        names = {}
        links = {}
        for j in range(p.getNumJoints(self.id, physicsClientId=client)):
            info = p.getJointInfo(self.id, j, physicsClientId=client)
            names[info[1].decode()] = j
            links[info[12].decode()] = j
        self.arm = [names[n] for n in ARM_JOINTS]
        self.tool_joint = names[TOOL_JOINT]
        self.tool_link = links["screwdriver"]
        self.tip_link = links[TOOL_TIP]
        self.camera_link = links[CAMERA_LINK]
        self.platform = PlatformState(np.array(start, dtype=np.float64), np.zeros(3))
        self._pose = (float(start[0]), float(start[1]), float(start[2]))
        self._tw = (0.0, 0.0, 0.0)
        self._cmd = (0.0, 0.0, 0.0)
        self._braking = False
        self.tau = platform_tau
        # the command's transport delay (None: a command acts from the next physics step, as without one)
        self._delay = CommandDelay(base_delay, (0.0, 0.0, 0.0)) if base_delay > 0.0 else None
        self.v_max, self.w_max, self.a_max = rp.v_max, rp.w_max, rp.accel_max
        self.brake_decel = rp.brake_decel
        self.gain = position_gain
        self.max_force = max_force
        self.q_ref = np.array(q0, dtype=np.float64)
        self.q_ref_target = self.q_ref.copy()
        self._ramp = np.zeros(7)
        self._left = 0
        self._gains = [position_gain] * 7
        self._forces = [max_force] * 7
        for j, q in zip(self.arm, self.q_ref, strict=True):
            p.resetJointState(self.id, j, float(q), 0.0, physicsClientId=client)
        # the platform's fixed-joint links must not be driven; arm motors on position control
        p.enableJointForceTorqueSensor(self.id, self.tool_joint, True, physicsClientId=client)
        self._servo()

    # -- platform -------------------------------------------------------------------------------
    def command_base(self, twist: NDArray[np.float64], t: float = 0.0) -> None:
        """Command the platform's twist ``(v_x, v_y, ω_z)`` (clipped to the speed limits) at time ``t``
        (s); it takes effect after the transport delay."""
        self._braking = False
        vx, vy, wz = (float(v) for v in twist)
        s = math.hypot(vx, vy)
        if s > self.v_max:
            vx, vy = vx * self.v_max / s, vy * self.v_max / s
        cmd = (vx, vy, max(-self.w_max, min(self.w_max, wz)))
        if self._delay is None:
            self._cmd = cmd
        else:
            self._delay.push(t, cmd)

    def brake(self) -> None:
        """Safe stop of the platform: decelerate to rest at the robot's ``brake_decel`` and stay there.

        Unlike a zero twist command (which the first-order lag approaches but never reaches), the twist
        falls linearly to exactly zero along its own direction: the linear speed at ``brake_decel`` and
        the yaw rate at ``brake_decel · w_max / v_max`` (a full yaw rate stops as fast as the full
        speed), so the platform is at rest after ``max(v, |ω| v_max / w_max) / brake_decel`` seconds —
        0.5 s from the paper's 1 m/s with the default 2 m/s².  A new :meth:`command_base` ends it.
        """
        self._braking = True
        self._cmd = (0.0, 0.0, 0.0)
        if self._delay is not None:
            self._delay.clear(self._cmd)

    def _brake_twist(self, h: float) -> tuple[float, float, float]:
        tw = self._tw
        t_stop = max(math.hypot(tw[0], tw[1]), abs(tw[2]) * self.v_max / self.w_max) / self.brake_decel
        if t_stop <= h:
            return (0.0, 0.0, 0.0)
        k = 1.0 - h / t_stop
        return (tw[0] * k, tw[1] * k, tw[2] * k)

    def _step_platform(self, h: float, t: float) -> None:
        tw = self._tw
        if self._delay is not None and not self._braking:
            self._cmd = self._delay.at(t)  # type: ignore[assignment]
        if self._braking:
            new = self._brake_twist(h)
        else:
            cx, cy, cw = self._cmd
            k = 1.0 / max(self.tau, h)
            ax, ay, aw = (cx - tw[0]) * k, (cy - tw[1]) * k, (cw - tw[2]) * k
            lin = math.hypot(ax, ay)
            if lin > self.a_max:
                ax, ay = ax * self.a_max / lin, ay * self.a_max / lin
            new = (tw[0] + ax * h, tw[1] + ay * h, tw[2] + aw * h)
        if new == tw == (0.0, 0.0, 0.0):
            return
        mean = (0.5 * (tw[0] + new[0]), 0.5 * (tw[1] + new[1]), 0.5 * (tw[2] + new[2]))
        self._pose = integrate_planar(self._pose, mean, h)
        self._tw = new
        x, y, th = self._pose
        p.resetBasePositionAndOrientation(self.id, [x, y, 0.0], quaternion_from_yaw(th), physicsClientId=self.client)

    def sync_state(self) -> None:
        """Publish the platform's pose and twist as arrays (once per control tick, not per step)."""
        self.platform.pose = np.array(self._pose)
        self.platform.twist = np.array(self._tw)

    # -- arm ------------------------------------------------------------------------------------
    def command_arm(self, dq: NDArray[np.float64], n_steps: int) -> None:
        """Move the joint reference by ``dq`` (clipped to the joint limits), ramped over ``n_steps``."""
        k = self.robot.kinematics
        target = np.clip(self.q_ref_target + np.asarray(dq, dtype=np.float64), k.lower, k.upper)
        if np.array_equal(target, self.q_ref_target) and self._left == 0:
            return
        self.q_ref_target = target
        self._left = max(1, n_steps)
        self._ramp = (self.q_ref_target - self.q_ref) / self._left

    def _servo(self) -> None:
        p.setJointMotorControlArray(self.id, self.arm, p.POSITION_CONTROL, targetPositions=self.q_ref.tolist(),
                                    positionGains=self._gains, forces=self._forces, physicsClientId=self.client)

    def before_step(self, h: float, t: float = 0.0) -> None:
        """Advance the platform and the arm reference by one physics step of ``h`` s starting at time
        ``t`` (s; call before stepSimulation)."""
        self._step_platform(h, t)
        if self._left > 0:
            self._left -= 1
            self.q_ref = self.q_ref_target.copy() if self._left == 0 else self.q_ref + self._ramp
            self._servo()

    def hold(self) -> None:
        """Stop ramping: the reference stays where it is."""
        self.q_ref_target = self.q_ref.copy()
        self._ramp = np.zeros(7)
        self._left = 0

    def set_joints(self, q: NDArray[np.float64]) -> None:
        """Teleport the arm (tests): joints, reference and servo target all to ``q``."""
        self.q_ref = np.array(q, dtype=np.float64)
        self.q_ref_target = self.q_ref.copy()
        self._ramp = np.zeros(7)
        self._left = 0
        for j, qq in zip(self.arm, self.q_ref, strict=True):
            p.resetJointState(self.id, j, float(qq), 0.0, physicsClientId=self.client)
        self._servo()

    def set_platform(self, pose: tuple[float, float, float] | NDArray[np.float64]) -> None:
        self._pose = (float(pose[0]), float(pose[1]), float(pose[2]))
        self.platform.pose = np.array(self._pose)
        x, y, th = self._pose
        p.resetBasePositionAndOrientation(self.id, [x, y, 0.0], quaternion_from_yaw(th), physicsClientId=self.client)

    # -- sensing --------------------------------------------------------------------------------
    def joints(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        st = p.getJointStates(self.id, self.arm, physicsClientId=self.client)
        return np.array([s[0] for s in st]), np.array([s[1] for s in st])

    def link_pose(self, link: int, fk: bool = True) -> NDArray[np.float64]:
        """World pose of a link's URDF frame (``getLinkState`` [4], [5], not the centre of mass);
        ``fk=False`` reads the poses of the last ``stepSimulation`` (cheaper)."""
        ls = p.getLinkState(self.id, link, computeForwardKinematics=fk, physicsClientId=self.client)
        return transform_from_pose(ls[4], ls[5])

    def tip_pose(self) -> NDArray[np.float64]:
        return self.link_pose(self.tip_link)

    def camera_pose(self) -> NDArray[np.float64]:
        return self.link_pose(self.camera_link)

    def base_pose(self) -> NDArray[np.float64]:
        x, y, th = self._pose
        return transform_xyz_yaw(x, y, 0.0, th)

    def link_rotation(self, link: int) -> NDArray[np.float64]:
        """World rotation of a link's URDF frame as of the last ``stepSimulation``."""
        ls = p.getLinkState(self.id, link, physicsClientId=self.client)
        return rotation_from_quaternion(ls[5])

    def sim_base_planar(self) -> tuple[float, float, float]:
        """The platform's planar pose ``(x, y, yaw)`` as PyBullet has it (ground truth, not the
        integrator's state)."""
        pos, orn = p.getBasePositionAndOrientation(self.id, physicsClientId=self.client)
        yaw = p.getEulerFromQuaternion(orn)[2]
        return (float(pos[0]), float(pos[1]), float(yaw))

    def tool_joint_wrench(self) -> NDArray[np.float64]:
        """Reaction wrench of the fixed ``tool_joint`` (PyBullet's F/T sensor, in the joint frame)."""
        return np.array(p.getJointState(self.id, self.tool_joint, physicsClientId=self.client)[2])
