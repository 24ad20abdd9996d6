"""Registries: duplicates refused, unknown names answered with the valid ones, entry points load,
and one conformance check over every registered task, robot and world."""

from __future__ import annotations

import pytest
from pydantic import BaseModel

from taskflow.api import ObsSpec, Robot, Task, World
from taskflow.registry import ROBOTS, TASKS, WORLDS, Registry, RegistryError, UnknownName
from taskflow.units import UNITS


def test_duplicate_name_is_refused():
    reg: Registry = Registry("task", Task, "taskflow.tests.none")

    class A(Task):
        pass

    class B(Task):
        pass

    reg.add("law", A)
    reg.add("law", A)  # the same class again is harmless (module re-import)
    with pytest.raises(RegistryError, match="already registered"):
        reg.add("law", B)


def test_wrong_base_class_is_refused():
    reg: Registry = Registry("task", Task, "taskflow.tests.none")
    with pytest.raises(RegistryError, match="not a subclass of Task"):
        reg.add("law", int)


def test_unknown_name_lists_valid_names_and_the_closest():
    with pytest.raises(UnknownName) as exc:
        TASKS.get("car_got")
    assert "did you mean 'car_goto'" in str(exc.value)
    assert "car_goto" in exc.value.valid


def test_shipped_entry_points_resolve():
    assert TASKS.get("car_goto").__name__ == "CarGoto"
    assert ROBOTS.get("racecar").__name__ == "Racecar"
    assert WORLDS.get("flat_ground").__name__ == "FlatGround"


@pytest.mark.parametrize("name", TASKS.names())
def test_task_conformance(name):
    cls = TASKS.get(name)
    assert issubclass(cls, Task) and cls.name == name
    assert issubclass(cls.Params, BaseModel)
    assert all(issubclass(m, BaseModel) for m in cls.slots.values())
    assert all(unit in UNITS for unit in cls.metrics.values()), cls.metrics
    assert all(e.isidentifier() for e in cls.events)
    assert all(isinstance(s, ObsSpec) for s in cls.requires.values()), cls.requires
    assert all(k.split(".", 1)[0] in ("state", "sensors") for k in cls.requires), cls.requires
    assert cls.step is not Task.step, "a task must implement step()"


@pytest.mark.parametrize("name", ROBOTS.names())
def test_robot_conformance(name):
    cls = ROBOTS.get(name)
    assert issubclass(cls, Robot) and cls.name == name
    robot = cls(cls.Params())  # every robot has a usable default
    stop = robot.stop_command()
    assert set(stop) == set(cls.command_keys)
    assert all(len(v) == cls.command_keys[k] for k, v in stop.items())


@pytest.mark.parametrize("name", WORLDS.names())
def test_world_conformance(name):
    cls = WORLDS.get(name)
    assert issubclass(cls, World) and cls.name == name
    assert issubclass(cls.Params, BaseModel)
    assert all(unit in UNITS for unit in cls.metrics.values())
    assert all(e.isidentifier() for e in cls.events)
    for action, ends in cls.actions.items():
        assert action.isidentifier() and ends and all(e.isidentifier() for e in ends)
    assert all(isinstance(s, ObsSpec) for s in cls.observations.values()), cls.observations
    for m in ("observe", "apply", "advance"):
        assert getattr(cls, m) is not getattr(World, m), f"{name} must implement {m}()"


def test_a_plugin_still_declaring_robot_names_is_refused_with_what_replaced_them():
    class OldTask(Task):
        robots = ("racecar",)

    class OldWorld(World):
        robots = ("racecar",)

    tasks, worlds = Registry("task", Task, "none.tasks"), Registry("world", World, "none.worlds")
    with pytest.raises(RegistryError, match=r"task 'old_task' .* declares `robots`.*`command_interface`, `requires`"):
        tasks.add("old_task", OldTask)
    with pytest.raises(RegistryError, match=r"world 'old_world' .* declares `robots`.*`needs` \(a RobotNeeds"):
        worlds.add("old_world", OldWorld)
