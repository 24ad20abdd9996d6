"""Conformance check over the registries, in the manner of Gymnasium's ``check_env``.

For every registered world and every registered robot it can host (:func:`taskflow.mission.contracts.hosts`):

1. **build** the world with the robot's default parameters and the world's (plus the caller's
   ``params`` for that world, e.g. a fast perception mode), and ``reset()`` it;
2. **reset twice with one seed**: the first observations after each reset must be equal;
3. **observation spec**: every ``state`` / ``sensors`` entry must be declared (by the robot's
   ``observations`` or the world's) and match its :class:`~taskflow.api.ObsSpec`; every declared
   non-optional entry must be present; ``ground_truth()`` must give exactly ``ground_truth_keys``;
4. **stop**: ``apply(robot.stop_command())`` then ``advance`` one control period: the clock moves by it;
5. **seeded rollouts**: two rollouts of a few ticks with one seed and one command sequence (small
   seeded commands) give equal observations and ground truth, tick by tick.

It only uses the :class:`~taskflow.api.World` API (no simulator import), so it runs against any plugin.
``taskflow check`` prints the same report.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from taskflow.api import Observation, ObsSpec, Robot, World
from taskflow.mission.contracts import hosts, provided, world_problem
from taskflow.registry import ROBOTS, WORLDS, RegistryError

MAX_STEPS = 10_000
"""Ticks a seeded rollout of ``taskflow check`` may take (a conformance check is a short rollout)."""


@dataclass
class PairResult:
    """The outcome of the checks on one world hosting one robot."""

    world: str
    robot: str
    problems: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.problems

    def __str__(self) -> str:
        head = f"{self.world} x {self.robot}: {'ok' if self.ok else 'FAILED'} ({self.seconds:.1f} s)"
        return "\n".join([head, *(f"  - {p}" for p in self.problems)])


def equal(a: Any, b: Any) -> bool:
    """Deep equality of observation values: arrays by dtype, shape and bytes (NaN equal to NaN),
    dataclasses by their compared fields, mappings and sequences element-wise."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype
                and a.shape == b.shape and a.tobytes() == b.tobytes())
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        return type(a) is type(b) and all(equal(getattr(a, f.name), getattr(b, f.name))
                                          for f in dataclasses.fields(a) if f.compare)
    if isinstance(a, Mapping):
        return isinstance(b, Mapping) and a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def _observation_equal(a: Observation, b: Observation) -> bool:
    """Everything but ``timings`` (wall clock)."""
    return (a.t == b.t and equal(a.state, b.state) and equal(a.sensors, b.sensors) and a.events == b.events
            and equal(a.metrics, b.metrics))


def spec_problems(obs: Observation, specs: Mapping[str, ObsSpec]) -> list[str]:
    """Entries of ``obs`` that are undeclared, missing or of the wrong type."""
    out = []
    seen = {f"state.{k}": v for k, v in obs.state.items()} | {f"sensors.{k}": v for k, v in obs.sensors.items()}
    for key, value in seen.items():
        spec = specs.get(key)
        if spec is None:
            out.append(f"observation {key} is not declared by the robot or the world")
            continue
        why = spec.problem(value)
        if why is not None:
            out.append(f"observation {key} {why} (declared {spec})")
    out += [f"observation {k} ({s}) is declared but missing" for k, s in specs.items()
            if not s.optional and k not in seen]
    return out


def _command(robot: Robot, rng: np.random.Generator, scale: float) -> dict[str, np.ndarray]:
    return {k: scale * rng.uniform(-1.0, 1.0, n) for k, n in robot.command_keys.items()}


def _control_period(world: World, dt: float) -> float:
    """``dt`` rounded to a whole number (>= 1) of the world's physics steps."""
    hz = float(world.physics_hz)
    return max(1, round(dt * hz)) / hz


def check_pair(world_cls: type[World], robot_cls: type[Robot], params: Mapping[str, Any] | None = None,
               seed: int = 7, steps: int = 5, dt: float = 0.05, command_scale: float = 0.05) -> PairResult:
    """Run the checks of the module docstring on one pairing; problems are collected, never raised."""
    res = PairResult(world_cls.name, robot_cls.name)
    t0 = time.perf_counter()
    specs = provided(robot_cls, world_cls)
    try:
        robot = robot_cls(robot_cls.Params())
        wparams = world_cls.Params.model_validate(dict(params or {}))
    except Exception as exc:
        res.problems.append(f"default parameters do not build: {type(exc).__name__}: {exc}")
        return res

    def build() -> World:
        w = world_cls(robot, wparams, seed)
        w.reset()
        return w

    try:
        world = build()
        try:
            first = world.observe()
            world.reset()
            again = world.observe()
            if not _observation_equal(first, again):
                res.problems.append("two resets with one seed give different first observations")
            res.problems += spec_problems(first, specs)
            gt = world.ground_truth()
            if set(gt) != set(world_cls.ground_truth_keys):
                res.problems.append(f"ground_truth() keys {sorted(gt)} differ from ground_truth_keys "
                                    f"{sorted(world_cls.ground_truth_keys)}")
            h = _control_period(world, dt)
            world.apply(robot.stop_command())
            world.advance(h)
            after = world.observe()
            if not math.isclose(after.t - again.t, h, rel_tol=1e-9, abs_tol=1e-12):
                res.problems.append(f"advance({h:g}) after the stop command moved the clock by {after.t - again.t:g} s")
            res.problems += [f"after stop: {p}" for p in spec_problems(after, specs)]
        finally:
            world.close()

        def rollout() -> list[tuple[Observation, dict[str, float]]]:
            w = build()
            rng = np.random.default_rng(seed)
            try:
                out = []
                for _ in range(steps):
                    obs = w.observe()
                    out.append((obs, w.ground_truth()))
                    w.apply(_command(robot, rng, command_scale))
                    w.advance(_control_period(w, dt))
                return out
            finally:
                w.close()

        a, b = rollout(), rollout()
        for k, ((oa, ga), (ob, gb)) in enumerate(zip(a, b)):
            if not (_observation_equal(oa, ob) and equal(ga, gb)):
                res.problems.append(f"two seeded rollouts differ at tick {k}")
                break
        for k, (obs, _) in enumerate(a):
            res.problems += [f"rollout tick {k}: {p}" for p in spec_problems(obs, specs)]
    except Exception as exc:
        res.problems.append(f"raised {type(exc).__name__}: {exc}")
    res.problems = list(dict.fromkeys(res.problems))
    res.seconds = time.perf_counter() - t0
    return res


def pairs(worlds: list[str] | None = None, robots: list[str] | None = None) -> list[tuple[type[World], type[Robot]]]:
    """Every (world, robot) of the registries (or of the names given) where the world hosts the robot."""
    out = []
    for wname in worlds or WORLDS.names():
        wcls = WORLDS.get(wname)
        for rname in robots or ROBOTS.names():
            rcls = ROBOTS.get(rname)
            if hosts(wcls, rcls):
                out.append((wcls, rcls))
    return out


def check_all(params: Mapping[str, Mapping[str, Any]] | None = None, worlds: list[str] | None = None,
              robots: list[str] | None = None, **kw: Any) -> list[PairResult]:
    """:func:`check_pair` over :func:`pairs`; ``params`` maps a world name to parameter overrides."""
    params = params or {}
    try:
        todo = pairs(worlds, robots)
    except RegistryError as exc:
        return [PairResult("(registry)", "", [str(exc)])]
    return [check_pair(w, r, params.get(w.name), **kw) for w, r in todo]


def param_problem(world: str, values: Mapping[str, Any]) -> tuple[str, str, str] | None:
    """``(key, message, hint)`` of the first of ``values`` that world ``world``'s parameters refuse (None: they
    take them all); an unknown world raises :class:`~taskflow.registry.UnknownName`."""
    from pydantic import ValidationError

    from taskflow.mission.diagnostics import pydantic_problems
    from taskflow.mission.yamlsrc import SourceMap

    params = WORLDS.get(world).Params
    try:
        params.model_validate(dict(values))
    except ValidationError as exc:
        key = str(exc.errors()[0]["loc"][0]) if exc.errors() and exc.errors()[0]["loc"] else ""
        p = pydantic_problems(exc, SourceMap("--param"), (), params)[0]
        return key, p.message, p.hint
    return None


def no_pair_reason(worlds: list[str], robots: list[str]) -> str:
    """Why no pairing of ``worlds`` x ``robots`` (registered names; empty: every one) is checked: what keeps
    the first world from hosting the first robot, and where that robot can go."""
    for wname in worlds or WORLDS.names():
        for rname in robots or ROBOTS.names():
            why = world_problem(WORLDS.get(wname), ROBOTS.get(rname))
            if why is not None:
                return f"{why[0]} — {why[1]}"
    return "no registered world hosts a registered robot"
