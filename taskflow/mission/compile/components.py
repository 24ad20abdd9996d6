"""Compile pass: the robot and the world — registered names, their parameters (world distributions
drawn with the mission's seed and checked at the edges of their range), the pairing (the robot offers
what the world needs, :func:`taskflow.mission.contracts.world_problem`), the control
rate against the world's physics rate, and the mission parameters the world checks against itself."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from taskflow.api import World
from taskflow.mission.compile.context import Compilation
from taskflow.mission.contracts import world_problem
from taskflow.mission.distributions import DistributionError, distributions_in, replaced, sample, support, world_rng
from taskflow.mission.model import YPath, with_model_defaults
from taskflow.registry import ROBOTS, WORLDS, RegistryError, UnknownName, describe_choices


def resolve_components(c: Compilation) -> None:
    robot_cls, robot_raw, rpath = _component(c, "robot", ROBOTS)
    world_cls, world_raw, wpath = _component(c, "world", WORLDS)
    c.world_params_raw = world_raw
    if robot_cls is not None:
        c.robot_cls = robot_cls
        c.robot_params = c.validate_model(robot_cls.Params, robot_raw, rpath)
    if world_cls is None:
        return
    c.world_cls = world_cls
    mismatch = world_problem(world_cls, robot_cls) if robot_cls is not None else None
    if mismatch is not None:
        c.err(("world",), *mismatch)
    try:
        drawn = sample(world_raw, world_rng(c.spec.seed))
    except DistributionError as exc:
        c.err(wpath + exc.path, str(exc))
        return
    wparams = c.validate_model(world_cls.Params, drawn, wpath)
    if wparams is not None:
        _check_rates(c, world_cls, wparams, wpath)
        _check_support(c, world_cls, world_raw, drawn, wpath)
        _check_parameters(c, world_cls, wparams)


def _check_parameters(c: Compilation, world_cls: type[World], wparams: BaseModel) -> None:
    """The mission's parameters the world checks against itself (:meth:`World.parameter_problems`), reported at the
    parameter (at its ``--set`` when one changed it, else at a ``--set`` of the world's parameters, if any)."""
    for name, problem, valid in world_cls.parameter_problems(wparams, dict(c.spec.parameters)):
        mine = [p for p in c.smap.overrides if p[:2] == ("parameters", name)]
        sets = [p for p in c.smap.overrides if p[:1] == ("world",)]
        c.err(mine[-1] if mine else sets[-1] if sets else ("parameters", name), problem, valid)


def _component(c: Compilation, key: str, registry: Any) -> tuple[Any, dict[str, Any], YPath]:
    ref = getattr(c.spec, key)
    name, params, ppath = (ref, {}, (key,)) if isinstance(ref, str) else (ref.name, ref.params, (key, "params"))
    npath = (key,) if isinstance(ref, str) else (key, "name")
    try:
        return registry.get(name), params, ppath
    except UnknownName as exc:
        c.err(npath, f"unknown {exc.kind} {name!r}",
              f"{describe_choices(name, exc.valid)}; `taskflow list {exc.kind}s` says what each is")
    except RegistryError as exc:
        c.err(npath, str(exc))
    return None, params, ppath


def _check_support(c: Compilation, world_cls: type[World], raw: dict[str, Any], drawn: dict[str, Any],
                   wpath: YPath) -> None:
    """Every value a distribution can draw must be a valid parameter, not just the default seed's draw."""
    model = world_cls.Params
    for path, spec in distributions_in(raw):
        for value, what in support(spec):
            try:
                model.model_validate(with_model_defaults(model, replaced(drawn, path, value)))
            except ValidationError as exc:
                why = exc.errors()[0]["msg"].removeprefix("Value error, ")
            except (TypeError, ValueError) as exc:
                why = str(exc)
            else:
                continue
            c.err(wpath + path, f"{what} is not a valid value here ({why}): some seeds would draw it",
                  "keep the distribution inside the parameter's valid range")
            break


def _check_rates(c: Compilation, world_cls: type[World], wparams: BaseModel, wpath: YPath) -> None:
    """The control period must be a whole number of physics steps, so every tick lasts the same, and a rate
    the world can honour (:meth:`World.rate_problem`, reported at ``rate_hz``)."""
    physics = float(getattr(wparams, "physics_hz", world_cls.physics_hz))
    rate = float(c.spec.rate_hz)
    ratio = physics / rate
    if ratio >= 1.0 - 1e-9 and abs(ratio - round(ratio)) <= 1e-9 * ratio:
        problem = world_cls.rate_problem(wparams, c.robot_params, rate)
        if problem is not None:  # blame a --set of the world's or robot's parameters when rate_hz is the file's
            sets = [p for p in c.smap.overrides if p[:1] in (("world",), ("robot",))]
            c.err(sets[-1] if sets and ("rate_hz",) not in c.smap.overrides else ("rate_hz",), *problem)
        return
    world_raw = c.data.get("world")
    given = isinstance(world_raw, dict) and "physics_hz" in (world_raw.get("params") or {})
    # point at what the author wrote last: the world's physics_hz, unless rate_hz came from a --set
    where = wpath + ("physics_hz",) if given and ("rate_hz",) not in c.smap.overrides else ("rate_hz",)
    divisors = [f"{physics / k:g}" for k in range(1, 41) if abs(physics / k - round(physics / k, 6)) < 1e-9][:8]
    c.err(where, f"control rate_hz {rate:g} Hz does not divide the physics rate {physics:g} Hz of world "
          f"{world_cls.name!r} ({ratio:.4g} physics steps per tick): ticks would last unequal times",
          f"rate_hz values that divide {physics:g} Hz: {', '.join(divisors)}")
