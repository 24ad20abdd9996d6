"""The scene of a mission: what its world and its tasks declare to draw (:mod:`taskflow.markers`).

:func:`mission_scene` asks the world for the markers of its drawn parameters
(:meth:`~taskflow.api.World.scene`) and every task state for the markers and control point of its
parameters (:meth:`~taskflow.api.Task.scene`) — once per ``foreach`` item in scope, so the car's three
``car_goto`` targets become waypoints 1, 2 and 3.  Figures (:mod:`taskflow.readers.plots`) and exports
(:mod:`taskflow.readers.telemetry`) read the result and never know a mission.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel, ValidationError

from taskflow.markers import ControlPoint, Marker
from taskflow.mission.contracts import build_robot_params
from taskflow.mission.model import CompiledMission, StateNode, UnknownRef, resolve_refs


@dataclass
class Scene:
    """``markers`` in the world frame; ``control_points``: leaf state path → the point of the robot its
    guards measure (absent: the reported pose itself); ``poses``: body → ground-truth keys of its x, y
    and yaw (:attr:`taskflow.api.World.poses`, the robot first)."""

    markers: list[Marker] = field(default_factory=list)
    control_points: dict[str, ControlPoint] = field(default_factory=dict)
    poses: dict[str, tuple[str, str, str | None]] = field(default_factory=dict)

    def control_point(self, state: str) -> ControlPoint | None:
        """The control point drawn for a trace row in ``state``: a leaf path, or the active leaves of
        parallel regions joined by ``|`` (then the first that declares one)."""
        return next((cp for leaf in state.split("|") if (cp := self.control_points.get(leaf)) is not None), None)


def _item_scopes(node: StateNode, params: dict[str, Any]) -> list[tuple[dict[str, Any], tuple[int, ...]]]:
    """Every combination of the foreach items in scope at ``node``: (items by name, their indices)."""
    scope = node.scope_items()
    lists = [list(enumerate(params.get(lst) or [])) for _, lst in scope]
    out = []
    for combo in itertools.product(*lists):
        out.append(({name: item for (name, _), (_, item) in zip(scope, combo)}, tuple(i for i, _ in combo)))
    return out


def _task_params(node: StateNode, params: dict[str, Any], items: dict[str, Any]) -> BaseModel | None:
    """The task's parameters for these items, or None when they are known only at run time."""
    assert node.task_cls is not None
    try:
        return node.task_cls.Params.model_validate(resolve_refs(node.task_params, params, items))
    except (UnknownRef, ValidationError):
        return None


def mission_scene(mission: CompiledMission, world_params: BaseModel) -> Scene:
    """The scene of ``mission`` with the world's parameters ``world_params`` (drawn for a seed)."""
    scene = Scene(markers=list(mission.world_cls.scene(world_params)), poses=dict(mission.world_cls.poses))
    robot = mission.build_robot()
    params = dict(mission.spec.parameters)
    seen: set[tuple[str, tuple[tuple[float, float], ...]]] = {(m.role, m.points) for m in scene.markers}
    for node in mission.states.values():
        if node.task_cls is None or not node.is_leaf or node.final:
            continue
        robot_params = build_robot_params(node.task_cls, robot)
        for items, index in _item_scopes(node, params):
            task_params = _task_params(node, params, items)
            if task_params is None:
                continue
            ts = node.task_cls.scene(task_params, node.profiles, robot_params)
            if ts.control_point is not None:
                scene.control_points.setdefault(node.path, ts.control_point)
            for m in ts.markers:
                if index:  # one marker per item: a goal of an item is a waypoint, numbered by the item
                    number = " ".join(str(i + 1) for i in index)
                    role = "waypoint" if m.role == "goal" else m.role
                    m = Marker(role, f"{'waypoint' if role == 'waypoint' else m.label} {number}", m.points,
                               m.closed, m.yaw, m.radius)
                key = (m.role, m.points)
                if key not in seen:
                    seen.add(key)
                    scene.markers.append(m)
    return scene
