"""The racecar as a :class:`~taskflow_sim.core.bodies.GroundBody`: an adapter over
:class:`~taskflow_sim.racecar_body.RacecarBody` (no behaviour of its own).

Attributes it does not define are the wrapped car's (``body``, ``joints``, ``_base_frame`` ...), so code
written against the racecar body (the ViKi-HyCo scene's LiDAR and camera poses) keeps working.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from taskflow_robots.racecar import Racecar
from taskflow_sim.core.bodies import BodyOptions, GroundBody
from taskflow_sim.racecar_body import Actuation, RacecarBody

from taskflow.api import Command, Robot


class RacecarGround(GroundBody):
    """``racecar`` body: ``apply({"v", "steer"})`` → Ackermann hinges and electronic differential."""

    robot: Racecar
    robot_cls: ClassVar[type[Robot]] = Racecar

    def __init__(self, robot: Robot, options: BodyOptions) -> None:
        super().__init__(robot, options)
        rp = robot.params
        self.actuation = Actuation(v_max=rp.v_max, psi_max=rp.psi_max, speed_tau=options.speed_tau,
                                   steer_tau=options.steer_tau)

    def spawn(self, client: int, pose: tuple[float, float, float]) -> None:
        self.car = RacecarBody(client, pose, self.actuation, tire_friction=self.options.friction)
        self.client, self.uid = client, self.car.body

    def __getattr__(self, name: str) -> Any:
        car = self.__dict__.get("car")
        if car is None:
            raise AttributeError(name)
        return getattr(car, name)

    def apply(self, command: Command) -> None:
        self.car.apply(float(command["v"][0]), float(command["steer"][0]))

    def update(self, h: float) -> None:
        self.car.update(h)

    def pose(self) -> NDArray[np.float64]:
        return self.car.pose()

    def twist(self) -> NDArray[np.float64]:
        _, ang = p.getBaseVelocity(self.uid, physicsClientId=self.client)
        return np.array([self.car.speed(), float(ang[2])])

    def proprioception(self) -> dict[str, Any]:
        car = self.car
        return {"pose": car.pose(), "v": car.speed(), "steer": car.steering()}
