"""The contracts between the framework, control laws (tasks), robots and worlds.

These are the only types a task, robot or world author needs.  ``tasks/`` and ``robots/`` may import
this module; they never import ``sim/`` or pybullet.

Data flow of one control tick (see docs/design.md)::

    world.observe()                      -> Observation
    task.step(obs)                       -> StepResult(command, metrics, events)
    world.apply(command); world.advance(dt)
    guards(metrics, events, time-in-state) -> transition?

Units: every metric a task or world publishes declares its unit (``"m"``, ``"rad"``, ``"px"``,
``"s"``, ``"m/s"``, ``"N"``, ``""`` for dimensionless).  Values are always in that SI base unit; guard
expressions may write ``2 cm`` or ``3 deg`` and are converted when the mission loads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict

Command = dict[str, NDArray[np.float64]]
"""Robot command: named arrays (e.g. ``{"v": [0.3], "steer": [0.1]}``); keys are the robot's."""


class StrictModel(BaseModel):
    """Base for every parameter/profile model: unknown keys are an error, values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)


class NoParams(StrictModel):
    """Parameter model of a task, robot or world that takes none."""


@dataclass
class Observation:
    """What the robot knows at one control tick.

    ``state`` is proprioception (odometry pose, joint positions ...), ``sensors`` the latest sensor
    outputs (detections, marker poses, images), ``events`` the names emitted since the last tick and
    ``metrics`` sensor-side values (never ground truth) that guards may read.  ``timings`` is the
    wall-clock seconds the world spent producing this observation, by part (e.g. ``{"render": 0.02}``):
    it goes to ``timing.json`` only — never to guards, the trace or the summary.
    """

    t: float
    state: dict[str, Any] = field(default_factory=dict)
    sensors: dict[str, Any] = field(default_factory=dict)
    events: tuple[str, ...] = ()
    metrics: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)


@dataclass
class StepResult:
    """What a task returns each tick: the command, its named errors, and events it raises.

    ``timings`` is the wall-clock seconds of this step by part (e.g. ``{"perception": 0.008,
    "control": 0.0004}``); it goes to ``timing.json`` only.  Wall-clock values never belong in
    ``metrics``: a guard or the trace would then depend on the machine's speed."""

    command: Command
    metrics: dict[str, float] = field(default_factory=dict)
    events: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)


@dataclass
class TaskContext:
    """Everything a task gets when its state is entered.

    ``params`` is the task's validated parameter model (``$name`` references already resolved
    against mission parameters and ``foreach`` items), ``profiles`` maps each profile slot to its
    validated model, ``memory`` is a mission-wide blackboard shared by all tasks of one run (e.g. a
    target fixed by the first detection and used by later states), ``robot`` the robot model,
    ``items`` the current ``foreach`` items and ``dt`` the control period.
    """

    t: float
    params: BaseModel
    profiles: Mapping[str, BaseModel]
    memory: dict[str, Any]
    robot: "Robot"
    items: Mapping[str, Any] = field(default_factory=dict)
    dt: float = 0.0  # the control period (1 / rate_hz), s


class Task:
    """A control law bound to a state: ``on_enter`` → ``step`` every tick → ``on_exit``.

    Class attributes declare what the loader checks a mission against:

    * ``name`` — the name used in YAML (set by :func:`taskflow.registry.register_task`);
    * ``Params`` — pydantic model of ``task.params``;
    * ``slots`` — profile slot → pydantic model of the profile bound to it (``bind:`` in YAML);
    * ``metrics`` — metric name → unit of every metric ``step`` publishes;
    * ``events`` — events ``step`` may raise;
    * ``robots`` — robot names this task can drive (empty: any).
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {}
    metrics: ClassVar[dict[str, str]] = {}
    events: ClassVar[tuple[str, ...]] = ()
    robots: ClassVar[tuple[str, ...]] = ()

    def __init__(self, ctx: TaskContext) -> None:
        self.ctx = ctx

    def step(self, obs: Observation) -> StepResult:  # pragma: no cover - interface
        raise NotImplementedError

    def on_exit(self, t: float) -> None:
        """Called once when the state is left (default: nothing)."""


class Robot:
    """A robot description: parameters, limits, command layout.  No simulator code here.

    ``command_keys`` maps each command name to its length; :meth:`stop_command` is what the runtime
    sends for a safe stop.  A robot instance is built from its validated ``Params``.
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    command_keys: ClassVar[dict[str, int]] = {}

    def __init__(self, params: BaseModel) -> None:
        self.params = params

    def stop_command(self) -> Command:
        return {k: np.zeros(n) for k, n in self.command_keys.items()}


class World:
    """The hardware: a PyBullet scene with the robot in it (implementations live in ``sim/``).

    Class attributes declare what validation checks: ``Params`` (pydantic, may hold distributions
    resolved with the seed), ``events`` it emits, ``metrics`` (sensor-side values, with units) it
    publishes in observations, ``ground_truth_keys`` the scalar columns of :meth:`ground_truth`,
    ``actions`` (asynchronous action name → events it ends with), ``action_params`` (action name → pydantic
    model of its parameters, checked for every state and ``foreach`` item at load), ``robots`` it
    accepts, and ``physics_hz`` (or a ``physics_hz`` parameter): the mission's ``rate_hz`` must divide it.
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    events: ClassVar[tuple[str, ...]] = ()
    metrics: ClassVar[dict[str, str]] = {}
    ground_truth_keys: ClassVar[tuple[str, ...]] = ()
    actions: ClassVar[dict[str, tuple[str, ...]]] = {}
    action_params: ClassVar[dict[str, type[BaseModel]]] = {}
    robots: ClassVar[tuple[str, ...]] = ()

    physics_hz: float = 240.0

    def __init__(self, robot: Robot, params: BaseModel, seed: int, gui: bool = False) -> None:
        self.robot = robot
        self.params = params
        self.seed = seed
        self.gui = gui

    # --- lifecycle -------------------------------------------------------------------------
    def reset(self) -> None:
        """Build the scene; called once before the first observation.  The clock restarts at 0."""

    def close(self) -> None:
        """Release the simulator."""

    # --- the loop --------------------------------------------------------------------------
    def observe(self) -> Observation:  # pragma: no cover - interface
        raise NotImplementedError

    def apply(self, command: Command) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def advance(self, dt: float) -> None:  # pragma: no cover - interface
        """Advance simulated time by ``dt`` (whole physics steps)."""
        raise NotImplementedError

    def ground_truth(self) -> dict[str, float]:
        """Scalars measured from the simulator (never from the robot's belief)."""
        return {}

    def summary_metrics(self) -> dict[str, Any]:
        """Extra end-of-run metrics for ``summary.json`` (ground-truth errors ...)."""
        return {}

    # --- asynchronous actions ---------------------------------------------------------------
    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        raise KeyError(name)

    def cancel_action(self, name: str) -> None:
        """Abort a running action (state left before it finished)."""

    def safe_stop(self) -> None:
        """Bring the robot to rest; default: send the robot's stop command."""
        self.apply(self.robot.stop_command())
