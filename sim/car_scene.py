"""Building blocks shared by the car worlds: a PyBullet client, a box floor and the racecar on it.

``flat_ground`` is just this scene; a ViKi-HyCo world adds the object, cameras and LiDAR on top of it
(subclass :class:`taskflow_sim.flat_ground.FlatGround` and override its ``_populate`` hook, or build a
:class:`CarScene` directly).
"""

from __future__ import annotations

from dataclasses import dataclass

import pybullet as p

from taskflow_sim.racecar_body import Actuation, RacecarBody

FLOOR_THICKNESS = 0.02


def connect(gui: bool, physics_hz: float) -> int:
    """A new PyBullet client (DIRECT, or GUI) with gravity and a fixed time step ``1 / physics_hz``."""
    client = p.connect(p.GUI if gui else p.DIRECT)
    if client < 0:
        raise RuntimeError("pybullet.connect failed (a second GUI client is not allowed)")
    p.resetSimulation(physicsClientId=client)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
    p.setTimeStep(1.0 / physics_hz, physicsClientId=client)
    p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=client)
    if gui:
        p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=client)
    return client


def add_floor(
    client: int,
    half_size: float,
    friction: float,
    rgba: tuple[float, float, float, float] = (0.55, 0.55, 0.5, 1.0),
) -> int:
    """A static thin box whose top face is the plane ``z = 0`` (cheaper to render than plane.urdf)."""
    half = [half_size, half_size, 0.5 * FLOOR_THICKNESS]
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba), physicsClientId=client)
    floor = p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=col,
        baseVisualShapeIndex=vis,
        basePosition=[0.0, 0.0, -0.5 * FLOOR_THICKNESS],
        physicsClientId=client,
    )
    p.changeDynamics(floor, -1, lateralFriction=friction, physicsClientId=client)
    return floor


@dataclass
class CarScene:
    """A floor and one racecar in a fresh client."""

    client: int
    floor: int
    car: RacecarBody

    @classmethod
    def build(
        cls,
        *,
        gui: bool,
        physics_hz: float,
        start: tuple[float, float, float],
        actuation: Actuation,
        floor_half_size: float = 25.0,
        friction: float = 1.0,
    ) -> CarScene:
        client = connect(gui, physics_hz)
        floor = add_floor(client, floor_half_size, friction)
        car = RacecarBody(client, start, actuation, tire_friction=friction)
        return cls(client=client, floor=floor, car=car)

    def step(self, h: float) -> None:
        """One physics step of ``h`` seconds (actuator response, then the solver)."""
        self.car.update(h)
        p.stepSimulation(physicsClientId=self.client)

    def close(self) -> None:
        if p.isConnected(physicsClientId=self.client):
            p.disconnect(physicsClientId=self.client)
