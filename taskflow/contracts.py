"""The contract checks between a task, a robot and a world: command interface, observations, needs.

Used by the compiler (``compile/components.py``, ``compile/tree.py``: one ``FILE:LINE:COL`` problem per
mismatch) and by :mod:`taskflow.conformance` (which robots each world can host).  Each check returns
``None`` or ``(message, hint)``.  Names are never compared: a robot is accepted for what it declares
(:attr:`~taskflow.api.Robot.command_interface`, :attr:`~taskflow.api.Robot.observations`,
:attr:`~taskflow.api.Robot.sensors`), so a new robot needs no edit to any task or world that fits it.
"""

from __future__ import annotations

from pydantic import BaseModel

from .api import ObsSpec, Robot, Task, World, required_specs
from .registry import BODIES, ROBOTS, TASKS, WORLDS, RegistryError

Problem = tuple[str, str]


def provided(robot: type[Robot], world: type[World]) -> dict[str, ObsSpec]:
    """Every observation entry a run of ``robot`` on ``world`` carries: the robot's, then the world's."""
    return {**robot.observations, **world.observations}


def _listing(specs: dict[str, ObsSpec]) -> str:
    return ", ".join(f"{k} ({v})" for k, v in specs.items()) or "(none)"


def interface_label(robot: type[Robot]) -> str:
    keys = ", ".join(robot.command_keys)
    return f"{robot.command_interface or '(none)'} ({keys})" if keys else robot.command_interface or "(none)"


def _names_where(registry: object, pred: object) -> list[str]:
    """Registered names whose class satisfies ``pred`` (entry points that fail to load are skipped)."""
    out = []
    for n in registry.names():  # type: ignore[attr-defined]
        try:
            if pred(registry.get(n)):  # type: ignore[attr-defined, operator]
                out.append(n)
        except RegistryError:
            continue
    return out


def hosts(world: type[World], robot: type[Robot]) -> bool:
    """Whether ``world`` can host ``robot``."""
    return world_problem(world, robot, hint=False) is None


def world_problem(world: type[World], robot: type[Robot], hint: bool = True) -> Problem | None:
    """Why ``world`` cannot host ``robot`` (None: it can); the hint names the worlds that do host it, then
    what would make this one host it."""
    why = _unhosted(world, robot)
    if why is None or not hint:
        return None if why is None else (why, "")
    needs = world.needs
    if needs.interfaces and robot.command_interface not in needs.interfaces:
        fix = f"robots it can host: {', '.join(_names_where(ROBOTS, lambda r: hosts(world, r))) or '(none)'}"
    elif any(robot.sensors.get(m) != k for m, k in needs.sensors.items()):
        fix = f"the robot carries: {', '.join(f'{m} ({k})' for m, k in robot.sensors.items()) or 'none'}"
    else:
        fix = (f"or register a body under the entry point group 'taskflow.bodies' named {robot.name!r} "
               f"(robots with a body: {', '.join(BODIES.names()) or '(none)'})")
    elsewhere = _names_where(WORLDS, lambda w: hosts(w, robot))
    return why, f"worlds that host it: {', '.join(elsewhere) or '(none)'}; {fix}"


def _unhosted(world: type[World], robot: type[Robot]) -> str | None:
    """The reason ``world`` cannot host ``robot``, without hints (None: it can)."""
    needs = world.needs
    if needs.interfaces and robot.command_interface not in needs.interfaces:
        return (f"world {world.name!r} cannot host robot {robot.name!r}: it actuates "
                f"{', '.join(needs.interfaces)} commands, the robot takes {interface_label(robot)}")
    missing = {m: k for m, k in needs.sensors.items() if robot.sensors.get(m) != k}
    if missing:
        want = ", ".join(f"{m} ({k})" for m, k in missing.items())
        return (f"world {world.name!r} cannot host robot {robot.name!r}: it renders sensors {want} the robot "
                f"does not carry")
    if needs.body and robot.name not in BODIES:
        return (f"world {world.name!r} cannot host robot {robot.name!r}: it simulates the bodies registered "
                "under 'taskflow.bodies', and the robot has none")
    return None


def task_problem(task: type[Task], robot: type[Robot], world: type[World]) -> Problem | None:
    """Why ``task`` cannot run with ``robot`` on ``world`` (None: it can)."""
    if task.command_interface and task.command_interface != robot.command_interface:
        drivers = _names_where(TASKS, lambda t: t.command_interface == robot.command_interface)
        return (f"task {task.name!r} commands the {task.command_interface!r} interface but robot {robot.name!r} "
                f"takes {interface_label(robot)}",
                f"tasks for {robot.command_interface!r}: {', '.join(drivers) or '(none)'}")
    geometry = robot_params_problem(task, robot) or kinematics_problem(task, robot)
    if geometry is not None:
        return geometry
    have = provided(robot, world)
    for key, need in required_specs(task.requires).items():
        got = have.get(key)
        if got is None:
            return (f"task {task.name!r} reads observation {key} ({need}), which neither robot {robot.name!r} "
                    f"nor world {world.name!r} provides", f"provided here: {_listing(have)}")
        if not got.satisfies(need):
            return (f"task {task.name!r} reads observation {key} as {need}, but it is {got} with robot "
                    f"{robot.name!r} on world {world.name!r}", f"provided here: {_listing(have)}")
    return None


def _fits(have: object, need: object) -> bool:
    """Whether a robot parameter annotated ``have`` can fill a task's field annotated ``need``."""
    if have == need:
        return True
    return isinstance(have, type) and isinstance(need, type) and issubclass(have, need)


def _robot_params_misfit(task: type[Task], robot: type[Robot]) -> list[str]:
    """What ``robot``'s parameters lack of those ``task`` reads (empty: nothing)."""
    model = task.robot_params
    if model is None:
        return []
    fields = robot.Params.model_fields
    missing = [f for f in model.model_fields if f not in fields]
    wrong = [f for f, info in model.model_fields.items()
             if f in fields and not _fits(fields[f].annotation, info.annotation)]
    why = []
    if missing:
        why.append(f"has no {', '.join(missing)}")
    if wrong:
        why.append("has " + ", ".join(f"{f} as {_type_name(fields[f].annotation)}, not "
                                       f"{_type_name(model.model_fields[f].annotation)}" for f in wrong))
    return why


def robot_params_problem(task: type[Task], robot: type[Robot]) -> Problem | None:
    """Why ``robot``'s parameters cannot give ``task`` the robot parameters it reads (None: they can)."""
    why = _robot_params_misfit(task, robot)
    if not why:
        return None
    model = task.robot_params
    assert model is not None
    fits = _names_where(ROBOTS, lambda r: not _robot_params_misfit(task, r))
    return (f"task {task.name!r} reads robot parameters {', '.join(model.model_fields)} ({model.__name__}); robot "
            f"{robot.name!r} {' and '.join(why)}", f"robots that have them: {', '.join(fits) or '(none)'}")


def kinematics_problem(task: type[Task], robot: type[Robot]) -> Problem | None:
    """Why ``robot`` cannot give ``task`` the kinematics it computes with (None: it can, or the task needs none)."""
    need = task.kinematics
    have = robot.kinematics_model
    if need is None or (have is not None and issubclass(have, need)):
        return None
    fits = _names_where(ROBOTS, lambda r: r.kinematics_model is not None and issubclass(r.kinematics_model, need))
    return (f"task {task.name!r} computes with {need.__name__} kinematics; robot {robot.name!r} provides "
            f"{have.__name__ if have is not None else 'none'}", f"robots that provide them: {', '.join(fits) or '(none)'}")


def _type_name(t: object) -> str:
    return t.__name__ if isinstance(t, type) else str(t).replace("typing.", "")


def build_robot_params(task: type[Task], robot: Robot) -> BaseModel | None:
    """The task's :attr:`~taskflow.api.Task.robot_params` model filled from ``robot``'s parameters."""
    model = task.robot_params
    if model is None:
        return None
    return model.model_validate({f: getattr(robot.params, f) for f in model.model_fields})
