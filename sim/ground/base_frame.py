"""The base frame of a wheeled URDF body, one definition for the racecar and the Husky.

PyBullet reports a body's base at its centre of mass (the inertial frame), but a ground robot's pose,
odometry and commands are about its base link frame (the racecar's rear-axle midpoint, the Husky's
``base_footprint``).  :class:`BaseFrame` converts: it places the body by its base frame and reads the
base frame's pose ``T_world_base = (x, y, yaw)`` and planar twist (forward speed of the base frame's
origin, yaw rate) back.
"""

from __future__ import annotations

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from taskflow.spatial import planar_apply_inverse, yaw_from_quaternion

Frame = tuple[tuple[float, ...], tuple[float, ...]]


class BaseFrame:
    """The base link frame of body ``uid`` in PyBullet client ``client``."""

    def __init__(self, client: int, uid: int) -> None:
        self.client, self.uid = client, uid
        dyn = p.getDynamicsInfo(uid, -1, physicsClientId=client)
        self.inertial: Frame = (tuple(dyn[3]), tuple(dyn[4]))  # base frame → inertial frame
        self.inertial_inv: Frame = p.invertTransform(*self.inertial)

    def place(self, x: float, y: float, yaw: float) -> None:
        """Teleport the body so that its base frame is at ``(x, y, 0)`` with heading ``yaw``."""
        pos, q = p.multiplyTransforms([x, y, 0.0], p.getQuaternionFromEuler([0.0, 0.0, yaw]), *self.inertial)
        p.resetBasePositionAndOrientation(self.uid, pos, q, physicsClientId=self.client)

    def frame(self) -> Frame:
        """``(position, quaternion)`` of the base frame in the world."""
        com_pos, com_q = p.getBasePositionAndOrientation(self.uid, physicsClientId=self.client)
        frame: Frame = p.multiplyTransforms(com_pos, com_q, *self.inertial_inv)
        return frame

    def pose(self) -> NDArray[np.float64]:
        """Ground-truth planar pose ``T_world_base = (x, y, yaw)`` (m, m, rad)."""
        pos, q = self.frame()
        return np.array([pos[0], pos[1], yaw_from_quaternion(q)])

    def twist(self) -> tuple[float, float]:
        """Ground truth ``(v, w)``: the signed forward speed (m/s) of the base frame's origin along its
        heading (the centre of mass' velocity moved to the origin, turned into the base's axes) and the
        yaw rate (rad/s)."""
        lin, ang = p.getBaseVelocity(self.uid, physicsClientId=self.client)
        com_pos, _ = p.getBasePositionAndOrientation(self.uid, physicsClientId=self.client)
        pos, q = self.frame()
        vel = np.asarray(lin) + np.cross(ang, np.subtract(pos, com_pos))
        v_base = planar_apply_inverse((0.0, 0.0, yaw_from_quaternion(q)), vel[:2])  # world → base axes
        return float(v_base[0]), float(ang[2])

