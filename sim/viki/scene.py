"""``viki_ground``'s scene: where the object stands, its PyBullet body, the cameras' models and the ground truth
of the object seen from the robot.

The object (:mod:`taskflow_sim.viki.objects`: ``can``, ``bottle`` or ``carton``) is placed relative to the
start pose (``object_distance`` / ``object_bearing`` from the rear-axle midpoint, heading-relative) or at world
``object_xy`` (:func:`object_position`).  The cameras are the robot's mounts with the world's ``image_size`` and
``camera_rate_hz`` overrides (:func:`camera_models`).  Everything here reads the scene; nothing is drawn at random.
"""

from __future__ import annotations

import math

from taskflow_robots.racecar import CameraMount
from taskflow_sim.viki.camera import CameraModel
from taskflow_sim.viki.objects import SHAPES, PlacedObject, create_body
from taskflow_sim.viki.params import VikiGroundParams

from taskflow.api import Marker
from taskflow.spatial import planar_apply_inverse

#: the cameras of ``viki_ground``, in the order their models are built
CAMERAS = ("front", "rear")


def object_position(wp: VikiGroundParams) -> tuple[float, float]:
    """Where the object is placed: ``object_xy``, or ``object_distance`` / ``object_bearing`` from the start
    pose (heading-relative)."""
    if wp.object_xy is not None:
        return float(wp.object_xy[0]), float(wp.object_xy[1])
    sx, sy, syaw = wp.start
    a = syaw + wp.object_bearing
    return sx + wp.object_distance * math.cos(a), sy + wp.object_distance * math.sin(a)


def object_marker(wp: VikiGroundParams) -> Marker:
    """The object as placed, with its footprint radius (the scene a viewer draws before the run)."""
    x, y = object_position(wp)
    return Marker.point("object", f"object ({wp.object_kind})", x, y, radius=SHAPES[wp.object_kind].footprint_radius())


def place_object(client: int, wp: VikiGroundParams) -> tuple[PlacedObject, int]:
    """The object of ``wp`` and its static PyBullet body in ``client``."""
    ox, oy = object_position(wp)
    obj = PlacedObject(SHAPES[wp.object_kind], float(ox), float(oy), float(wp.object_yaw))
    return obj, create_body(client, obj)


def camera_models(wp: VikiGroundParams, mounts: dict[str, CameraMount]) -> dict[str, CameraModel]:
    """The front and rear camera models: the robot's mounts with ``image_size`` / ``camera_rate_hz`` applied."""
    cameras: dict[str, CameraModel] = {}
    for name in CAMERAS:
        m = mounts[name]
        if wp.image_size is not None:
            m = m.model_copy(update={"width": int(wp.image_size[0]), "height": int(wp.image_size[1])})
        if wp.camera_rate_hz is not None:
            m = m.model_copy(update={"rate_hz": float(wp.camera_rate_hz)})
        cameras[name] = CameraModel(name, m, m.width, m.height, wp.depth_max)
    return cameras


def object_in_robot_frame(obj: PlacedObject, pose: tuple[float, float, float]) -> tuple[float, float]:
    """Ground truth: the object's base centre in the robot frame (m) for the robot's planar pose ``T_world_robot``."""
    ox, oy = planar_apply_inverse(pose, (obj.x, obj.y))
    return float(ox), float(oy)
