"""Ground truth of how close the car came to the ViKi object: the distance between their footprints.

The car's **footprint** is the rectangle, in the robot frame, that covers every collision shape of its
body at rest with the steering straight (:func:`measure_footprint`: the body's own model loaded at the
origin of a scratch PyBullet client, the union of its links' bounding boxes on the floor).  It stands
for the car's body: the PyBullet racecar has no collision shape on its chassis, so the distance between
the collision shapes themselves (``getClosestPoints``) would let an object pass under the chassis
between the wheels untouched.  The object's footprint is its base outline: a circle for a cylinder, its
turned rectangle for a box (:mod:`taskflow_sim.viki_objects`).

:func:`footprint_clearance` is a few lines of float arithmetic (microseconds): the world evaluates it once per control
tick, not per physics step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p
from taskflow_sim.core.bodies import GroundBody
from taskflow_sim.viki_objects import PlacedObject


@dataclass(frozen=True)
class Footprint:
    """The rectangle ``[x_min, x_max] x [y_min, y_max]`` (m) in the robot frame (x ahead, y left)."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


def measure_footprint(body: GroundBody) -> Footprint:
    """The footprint of ``body`` (not spawned yet, or a fresh copy): it is spawned with its robot frame at
    the origin of a scratch DIRECT client, and the floor projection of every link's bounding box is united."""
    client = p.connect(p.DIRECT)
    try:
        body.spawn(client, (0.0, 0.0, 0.0))
        uid = body.body
        boxes = [p.getAABB(uid, link, physicsClientId=client)
                 for link in range(-1, p.getNumJoints(uid, physicsClientId=client))]
    finally:
        p.disconnect(physicsClientId=client)
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return Footprint(float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def footprint_clearance(car: Footprint, robot_pose: tuple[float, float, float], obj: PlacedObject) -> float:
    """Distance (m) between the car's footprint at ``robot_pose`` (world ``x, y, yaw``) and the object's
    base outline; 0 when they touch or overlap."""
    x, y, yaw = robot_pose
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = obj.x - x, obj.y - y
    ox, oy = c * dx + s * dy, -s * dx + c * dy  # the object's base centre in the robot frame
    shape = obj.shape
    car_box = (car.x_min, car.x_max, car.y_min, car.y_max)
    if shape.shape == "cylinder":
        return max(0.0, _to_box(ox, oy, car_box) - shape.size[0])
    # two rectangles: the box's corners in the robot frame, the car's corners in the box's frame
    a = obj.yaw - yaw
    ca, sa = math.cos(a), math.sin(a)
    hx, hy = 0.5 * shape.size[0], 0.5 * shape.size[1]
    box = (-hx, hx, -hy, hy)
    box_corners = [(ox + ca * u - sa * v, oy + sa * u + ca * v) for u in (-hx, hx) for v in (-hy, hy)]
    car_corners = [(ca * (u - ox) + sa * (v - oy), -sa * (u - ox) + ca * (v - oy))
                   for u in car_box[:2] for v in car_box[2:]]
    if not (_separates(box_corners, car_box) or _separates(car_corners, box)):
        return 0.0  # no separating axis among the four edge directions: they overlap
    # disjoint convex polygons: the nearest pair has a corner of one of them
    return min(min(_to_box(u, v, car_box) for u, v in box_corners), min(_to_box(u, v, box) for u, v in car_corners))


def _to_box(u: float, v: float, box: tuple[float, float, float, float]) -> float:
    """Distance from the point ``(u, v)`` to the axis-aligned rectangle ``(u_min, u_max, v_min, v_max)``."""
    return math.hypot(max(box[0] - u, 0.0, u - box[1]), max(box[2] - v, 0.0, v - box[3]))


def _separates(corners: list[tuple[float, float]], box: tuple[float, float, float, float]) -> bool:
    """An axis of the rectangle ``box`` separates it from the polygon ``corners`` (same frame)."""
    us, vs = [u for u, _ in corners], [v for _, v in corners]
    return max(us) < box[0] or min(us) > box[1] or max(vs) < box[2] or min(vs) > box[3]
