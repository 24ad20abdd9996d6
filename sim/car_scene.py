"""Building blocks shared by the worlds: a PyBullet client and a box floor.

``flat_ground`` is a floor and a robot body; a ViKi-HyCo world adds the object, cameras and LiDAR on top
of it (subclass :class:`taskflow_sim.ground.flat_ground.FlatGround` and override its ``_populate`` hook);
``screw_conveyor`` uses the client (:func:`connect`) with its own conveyor scene.
"""

from __future__ import annotations

import pybullet as p

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
