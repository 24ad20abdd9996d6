"""What a leaf's task is given when its state is entered: its :class:`~taskflow.api.TaskContext`.

Its parameters are resolved (``$name`` against the mission's parameters, the ``foreach`` items in scope and the
mission data) and validated by the task's ``Params`` model — once per leaf when they hold no reference; its
view of the robot's parameters (``Task.robot_params``) and of the mission data (``Task.reads`` /
``Task.writes``) are built once per task class for the run.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydantic import BaseModel

from taskflow.api import Robot, Task, TaskContext
from taskflow.mission.contracts import build_robot_params
from taskflow.mission.data import DataAccess
from taskflow.mission.model import CompiledMission, StateNode, UnknownRef, has_refs, resolve_refs

__all__ = ["AnyTask", "Contexts", "TaskFactory"]

AnyTask = Task[Any, Any]
"""A task of any parameter and robot-parameter models (the executor holds tasks of every kind)."""

TaskFactory = Callable[[type[AnyTask], TaskContext[Any, Any]], AnyTask | None]
"""Builds a leaf's task from its class and context (None: the leaf runs no task — a test's stand-in)."""


class Contexts:
    """The task contexts of one run: ``memory`` is its mission data, ``cache`` its memo of derived values."""

    def __init__(self, mission: CompiledMission, robot: Robot, memory: dict[str, Any], cache: dict[str, Any]) -> None:
        self.params = mission.spec.parameters
        self.robot, self.cache = robot, cache
        self.memory = memory
        self.dt = 1.0 / float(mission.spec.rate_hz)
        tasks = {n.task_cls for n in mission.states.values() if n.task_cls is not None}
        # per task class of the mission: its view of the robot's parameters (Task.robot_params), built once
        self.robot_params: dict[type[AnyTask], BaseModel | None] = {c: build_robot_params(c, robot) for c in tasks}
        # per task class: its checked view of the mission data (Task.reads / Task.writes)
        self.data_access: dict[type[AnyTask], DataAccess] = {c: DataAccess(memory, c) for c in tasks}
        # per leaf: its validated parameter model when its params hold no $reference
        self.static_params: dict[str, BaseModel] = {}

    def context(self, node: StateNode, task_cls: type[AnyTask], t: float, items: dict[str, Any]) -> TaskContext[Any, Any]:
        """The context of ``node``'s task (class ``task_cls``) entered at sim time ``t`` with ``items`` in scope."""
        params = self.static_params.get(node.path)
        if params is None:
            try:
                raw = resolve_refs(node.task_params, self.params, items, data=self.memory)
            except UnknownRef as exc:  # declared written on every path, but the writer did not write it
                raise RuntimeError(f"state {node.path!r}: parameter ${exc.name} has no value yet (its "
                                   "writer declares it but did not write it)") from None
            params = task_cls.Params.model_validate(raw)
            if not has_refs(node.task_params):
                self.static_params[node.path] = params
        return TaskContext(t=t, params=params, profiles=node.profiles, memory=self.data_access[task_cls],
                           robot=self.robot, items=items, dt=self.dt, robot_params=self.robot_params[task_cls],
                           cache=self.cache)
