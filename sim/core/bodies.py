"""Robot bodies: the simulator half of a robot, found by robot name, so a world never names a robot.

A robot is a description (``robots/``: parameters, limits, command interface, declared observations)
plus a **body** here: the object that loads its model into a PyBullet client, turns a validated command
into joint motor targets and reads the ground truth back.  Worlds that host "any wheeled robot"
(``flat_ground``, ``viki_ground``) build the body with :func:`make_body`, which looks the robot's name up
in the ``taskflow.bodies`` registry (entry points in ``pyproject.toml``, or :func:`register_body`).

Lifecycle, driven by the world::

    body = make_body(robot, BodyOptions(...))    # no simulator yet
    body.spawn(client, (x, y, yaw))              # load the model, at rest
    loop: body.apply(command)                    # once per control tick (a command checked by the world)
          body.update(h); stepSimulation         # once per physics step
    body.pose(), body.twist()                    # ground truth, any time
    body.stop()                                  # the robot's stop command
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from taskflow.api import Command, Robot
from taskflow.registry import BODIES, register_body

__all__ = ["BodyOptions", "GroundBody", "make_body", "register_body"]


@dataclass(frozen=True)
class BodyOptions:
    """What the world decides about a body: tyre ``friction`` (lateral, against its floor) and the
    first-order response times (s) of the actuators, ``speed_tau`` (forward speed / wheel speeds) and
    ``steer_tau`` (steering, or yaw rate for a robot without a steering joint).  0 = immediate."""

    friction: float = 1.0
    speed_tau: float = 0.0
    steer_tau: float = 0.0


class GroundBody(ABC):
    """One wheeled robot on a floor in a PyBullet client.  Subclasses implement the four abstract methods.

    ``pose()`` is the ground-truth ``[x, y, yaw]`` (m, rad) of the robot's base frame (the point its
    description calls the robot frame, on the ground), ``twist()`` the ground-truth ``[v, w]``: signed
    forward speed of that point along the heading (m/s) and yaw rate (rad/s).  ``uid`` is the PyBullet
    body id once spawned.  ``robot_cls`` is the robot description the body simulates; the base class
    refuses any other.
    """

    robot_cls: ClassVar[type[Robot]] = Robot

    def __init__(self, robot: Robot, options: BodyOptions) -> None:
        if not isinstance(robot, self.robot_cls):
            raise TypeError(f"the {self.robot_cls.name or self.robot_cls.__name__} body needs a "
                            f"{self.robot_cls.__name__}, got {type(robot).__name__}")
        self.robot = robot
        self.options = options
        self.client = -1
        self.uid = -1

    @property
    def body(self) -> int:
        """The PyBullet body id under the name the racecar body uses (scenes read ``scene.car.body``)."""
        return self.uid

    @abstractmethod
    def spawn(self, client: int, pose: tuple[float, float, float]) -> None:
        """Load the model into ``client`` with its base frame at ``pose``, at rest."""

    @abstractmethod
    def apply(self, command: Command) -> None:
        """Take a command with exactly the robot's ``command_keys`` (the world has checked them)."""

    def update(self, h: float) -> None:  # noqa: B027 - an optional hook, not abstract
        """Advance actuator dynamics by one physics step of ``h`` s, before the solver (default: none)."""

    @abstractmethod
    def pose(self) -> NDArray[np.float64]:
        """Ground truth ``[x, y, yaw]`` of the base frame."""

    @abstractmethod
    def twist(self) -> NDArray[np.float64]:
        """Ground truth ``[v, w]``: forward speed (m/s) and yaw rate (rad/s)."""

    def proprioception(self) -> dict[str, Any]:
        """The ``state`` entries of an observation (keys of the robot's declared ``state.*`` observations);
        default: ``pose`` and forward speed ``v``.  The world adds its noise model to them."""
        return {"pose": self.pose(), "v": float(self.twist()[0])}

    def stop(self) -> None:
        """Command the robot's stop command."""
        self.apply(self.robot.stop_command())


def make_body(robot: Robot, options: BodyOptions) -> GroundBody:
    """The registered body of ``robot`` (by its registry name), not yet spawned."""
    cls = BODIES.get(robot.name)
    if not (isinstance(cls, type) and issubclass(cls, GroundBody)):
        raise TypeError(f"body of robot {robot.name!r} must be a GroundBody subclass, got {cls!r}")
    return cls(robot, options)
