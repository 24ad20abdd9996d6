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
expressions may write ``2 cm`` or ``3 deg`` and are converted when the mission loads.  A metric with a
range declares it with :class:`Metric` (``"pos_error": Metric("m", low=0.0, reason="a distance")``): a guard
whose threshold lies outside it can never hold, and the loader refuses it.
"""

from __future__ import annotations

from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, ValidationError

from taskflow.markers import ControlPoint, Marker, TaskScene
from taskflow.specs import (
    AGE,
    COUNT,
    DISTANCE,
    FLAG,
    FORCE,
    NO_DEFAULT,
    ROTATION_ANGLE,
    SPEED,
    WEIGHT,
    WRAPPED_ANGLE,
    MemoryKey,
    Metric,
    MissingObservation,
    ObsKey,
    ObsSpec,
    Requires,
    RobotNeeds,
    array,
    flag,
    instance,
    mapping,
    message,
    required_specs,
    scalar,
    sequence,
    text,
)

__all__ = ["AGE", "COUNT", "DISTANCE", "FLAG", "FORCE", "ROTATION_ANGLE", "SPEED", "WEIGHT", "WRAPPED_ANGLE", "Command", "ControlPoint", "Marker", "MemoryKey", "Metric", "MissingObservation", "NO_DEFAULT", "NoParams", "ObsKey", "ObsSpec", "Observation", "Robot",
           "RobotNeeds", "StepResult", "StrictModel", "Task", "TaskContext", "TaskScene", "World", "array", "flag",
           "instance", "mapping", "message", "required_specs", "scalar", "sequence", "text"]

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
    ``metrics``: a guard or the trace would then depend on the machine's speed.

    ``sensors`` names the robot's sensor mounts (keys of :attr:`Robot.sensors`) this task needs the world
    to run from now on — ViKi-HyCo's ``("rear_camera",)``, ``()`` for none; ``None`` (the default) leaves
    the world's choice as it is.  The runtime hands it to :meth:`World.select_sensors` before the command
    is applied, when it differs from the last selection, so a world that renders on demand processes only what the active state reads."""

    command: Command
    metrics: dict[str, float] = field(default_factory=dict)
    events: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    sensors: tuple[str, ...] | None = None


ParamsT = TypeVar("ParamsT", bound=BaseModel)
RobotParamsT = TypeVar("RobotParamsT", bound=BaseModel)
ProfileT = TypeVar("ProfileT", bound=BaseModel)
KinematicsT = TypeVar("KinematicsT")


@dataclass
class TaskContext(Generic[ParamsT, RobotParamsT]):
    """Everything a task gets when its state is entered, typed over the task's models.

    ``params`` is the task's validated parameter model (``$name`` references already resolved
    against mission parameters and ``foreach`` items), ``profiles`` maps each profile slot to its
    validated model, ``memory`` is the run's mission data as this task may use it (e.g. a target fixed
    by the first detection and used by later states): it reads the keys it declares in
    :attr:`Task.reads` or :attr:`Task.writes` and writes those of :attr:`Task.writes`, any other access
    being an error that names the task and the key; ``cache`` is a per-run memo shared by the run's
    tasks for values *derived* from the run's constant inputs (keyframe features) — not mission data:
    undeclared, unchecked, never in the summary, and a task behaves the same with it empty, only
    slower (keys are namespaced by their owner, ``"visual_path.keyframe_features"``); ``robot`` the robot model,
    ``robot_params`` the robot parameters the task declared it reads (:attr:`Task.robot_params`, built
    from the robot's own), ``items`` the current ``foreach`` items and ``dt`` the control period.

    The framework has checked every one of them against the task's declarations when the mission was
    loaded (parameters for every ``foreach`` item, each slot's profile, the robot's parameters), so a
    task reads them without checking their types again.
    """

    t: float
    params: ParamsT
    profiles: Mapping[str, BaseModel]
    memory: MutableMapping[str, Any]
    robot: Robot
    items: Mapping[str, Any] = field(default_factory=dict)
    dt: float = 0.0  # the control period (1 / rate_hz), s
    robot_params: RobotParamsT = None  # type: ignore[assignment]  # None when the task declares none
    cache: dict[str, Any] = field(default_factory=dict)  # per-run memo of derived values, not mission data

    def profile(self, slot: str, model: type[ProfileT]) -> ProfileT:
        """The profile bound to ``slot``, typed as ``model`` (the slot's declared model, which the loader
        checked it against).  A slot the mission binds nothing to holds its model's defaults when the
        model has them (bound by the loader, :meth:`Task.default_profiles`)."""
        return cast(ProfileT, self.profiles[slot])

    def optional_profile(self, slot: str, model: type[ProfileT]) -> ProfileT | None:
        """The profile bound to ``slot``, or None when the mission binds none and the model has no
        defaults (an optional slot)."""
        return cast("ProfileT | None", self.profiles.get(slot))

    def kinematics(self, model: type[KinematicsT]) -> KinematicsT:
        """The robot's kinematics, typed as ``model`` (the task's :attr:`Task.kinematics`, which the loader
        checked the robot's :attr:`Robot.kinematics_model` against); a ``TypeError`` names the robot
        otherwise."""
        kin = getattr(self.robot, "kinematics", None)
        if not isinstance(kin, model):
            raise TypeError(f"robot {self.robot.name!r} has no {model.__name__} kinematics (got {type(kin).__name__})")
        return kin


class Task(Generic[ParamsT, RobotParamsT]):
    """A control law bound to a state: ``on_enter`` → ``step`` every tick → ``on_exit``.

    Typed over its parameter model and the robot parameters it reads: ``class CarGoto(Task[CarGotoParams,
    CarGeometry])`` gets ``ctx.params: CarGotoParams`` and ``ctx.robot_params: CarGeometry``.

    Class attributes declare what the loader checks a mission against:

    * ``name`` — the name used in YAML (set by :func:`taskflow.registry.register_task`);
    * ``Params`` — pydantic model of ``task.params``;
    * ``slots`` — profile slot → pydantic model of the profile bound to it (``bind:`` in YAML);
    * ``metrics`` — metric name → unit of every metric ``step`` publishes (a :class:`Metric` where the
      values have a range: errors and norms ≥ 0, wrapped angles in [-π, π], ratios in [0, 1]);
    * ``events`` — events ``step`` may raise;
    * ``command_interface`` — the robot command interface its commands are in (``"ackermann"``,
      ``"unicycle"`` ...; empty: it commands no motion), checked against the mission's robot;
    * ``requires`` — observation entries ``step`` reads: :class:`ObsKey` s (``(POSE, MARKER)``, the keys
      ``step`` reads with, ``POSE(obs)``) or the older mapping ``{"state.pose": array(3)}``, checked
      against what the robot and the world provide (the class keeps it as the mapping, name → spec);
    * ``robot_params`` — a pydantic model of the robot parameters the law reads (geometry, limits,
      camera mounts).  The robot is accepted for its fields, not its name: the loader checks that the
      robot's ``Params`` has each field with a compatible type, and the framework builds this model from
      the robot's parameters as ``ctx.robot_params``;
    * ``kinematics`` — the class of the robot kinematics the law computes with (e.g. a Pinocchio model),
      or None: the loader checks the robot's :attr:`Robot.kinematics_model` is it (or a subclass) and
      the task reads it typed with ``ctx.kinematics(Model)``;
    * ``writes`` — the mission-data keys (:class:`MemoryKey`) it may write (and read, whether written yet
      or not); ``reads`` — the keys it needs written before its state is entered.  The loader checks that
      every key a state reads is written on every path into it or has a default
      (:mod:`taskflow.mission.compile.dataflow`); at run time ``ctx.memory`` refuses any other key.
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {}
    metrics: ClassVar[dict[str, str]] = {}
    events: ClassVar[tuple[str, ...]] = ()
    command_interface: ClassVar[str] = ""
    requires: ClassVar[Requires] = {}
    robot_params: ClassVar[type[BaseModel] | None] = None
    kinematics: ClassVar[type | None] = None
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = ()
    reads: ClassVar[tuple[MemoryKey[Any], ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "requires" in cls.__dict__:
            cls.requires = required_specs(cls.requires)

    @classmethod
    def default_profiles(cls, bound: Mapping[str, BaseModel] | None = None) -> dict[str, BaseModel]:
        """``bound`` (slot → profile) with every other slot whose model builds from its defaults filled
        with them — what the loader binds when a mission binds nothing to a slot."""
        out = dict(bound or {})
        for slot, model in cls.slots.items():
            if slot not in out:
                try:
                    out[slot] = model()
                except ValidationError:
                    continue
        return out

    def __init__(self, ctx: TaskContext[ParamsT, RobotParamsT]) -> None:
        self.ctx = ctx

    def step(self, obs: Observation) -> StepResult:  # pragma: no cover - interface
        raise NotImplementedError

    def on_exit(self, t: float) -> None:
        """Called once when the state is left (default: nothing)."""

    @classmethod
    def scene(cls, params: BaseModel, profiles: Mapping[str, BaseModel], robot_params: BaseModel | None) -> TaskScene:
        """What this task with these parameters draws in figures and viewers: the goal it drives to, the
        point of the robot its metrics measure (:class:`~taskflow.markers.ControlPoint`).  ``params``,
        ``profiles`` and ``robot_params`` are those its context would get.  Default: nothing."""
        return TaskScene()


class Robot:
    """A robot description: parameters, limits, command layout.  No simulator code here.

    ``command_interface`` names the kind of command it takes (every robot of one interface has the same
    ``command_keys``: ``"ackermann"`` = ``v`` + ``steer``, ``"unicycle"`` = ``v`` + ``w``); ``command_keys``
    maps each command name to its length; :meth:`stop_command` is what the runtime sends for a safe stop.
    ``observations`` are the entries its proprioception puts in every observation on any world that hosts
    it (``"state.pose": array(3)``), ``sensors`` the sensors it carries (mount name → kind) for worlds to
    render.  A robot instance is built from its validated ``Params`` (the base class refuses any other model).
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    command_interface: ClassVar[str] = ""
    command_keys: ClassVar[dict[str, int]] = {}
    command_units: ClassVar[dict[str, tuple[tuple[str, str], ...]]] = {}
    """Per command key, each component's (name, unit): ``{"base_twist": (("v_x", "m/s"), ("v_y", "m/s"),
    ("w_z", "rad/s"))}`` — what figures and exports label the trace's ``cmd.KEY.i`` columns with."""
    observations: ClassVar[dict[str, ObsSpec]] = {}
    sensors: ClassVar[dict[str, str]] = {}
    kinematics_model: ClassVar[type | None] = None
    """The class of the robot's ``kinematics`` attribute (what a task's :attr:`Task.kinematics` names), or None."""

    def __init__(self, params: BaseModel) -> None:
        if not isinstance(params, self.Params):
            raise TypeError(f"robot {self.name or type(self).__name__!r} needs {self.Params.__name__} parameters, "
                            f"got {type(params).__name__}")
        self.params = params

    def stop_command(self) -> Command:
        return {k: np.zeros(n) for k, n in self.command_keys.items()}


class World:
    """The hardware: a PyBullet scene with the robot in it (implementations live in ``sim/``).

    Class attributes declare what validation checks: ``Params`` (pydantic, may hold distributions
    resolved with the seed), ``events`` it emits, ``metrics`` (sensor-side values, with units) it
    publishes in observations, ``ground_truth_keys`` the scalar columns of :meth:`ground_truth`,
    ``actions`` (asynchronous action name → events it ends with), ``action_params`` (action name → pydantic
    model of its parameters, checked for every state and ``foreach`` item at load), ``needs`` (what a
    robot must offer to be hosted, :class:`RobotNeeds`), ``observations`` (the entries the world adds to
    the robot's own, with their types) and ``physics_hz`` (or a ``physics_hz`` parameter): the mission's
    ``rate_hz`` must divide it.
    """

    name: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = NoParams
    events: ClassVar[tuple[str, ...]] = ()
    metrics: ClassVar[dict[str, str]] = {}
    ground_truth_keys: ClassVar[tuple[str, ...]] = ()
    actions: ClassVar[dict[str, tuple[str, ...]]] = {}
    action_params: ClassVar[dict[str, type[BaseModel]]] = {}
    needs: ClassVar[RobotNeeds] = RobotNeeds()
    observations: ClassVar[dict[str, ObsSpec]] = {}
    poses: ClassVar[dict[str, tuple[str, str, str | None]]] = {}
    """Planar ground-truth poses for figures and exports: body name → the :attr:`ground_truth_keys` of its
    x and y (m) and yaw (rad; None when the body has no heading).  The first is the robot's."""

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

    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """What the world's (drawn) parameters put in the scene, for figures and viewers: obstacles, the
        object, keyframes, walls, the start pose (:class:`~taskflow.markers.Marker`).  Default: nothing."""
        return []

    @classmethod
    def rate_problem(cls, params: BaseModel, robot_params: BaseModel | None, rate_hz: float) -> tuple[str, str] | None:
        """Why the mission's control rate ``rate_hz`` is one this world with these (drawn) parameters and the
        robot's cannot honour, as ``(what is wrong, what would be valid)``; None: it can.  The loader asks it
        after checking that ``rate_hz`` divides the physics rate.  Default: any rate."""
        return None

    @classmethod
    def parameter_problems(cls, params: BaseModel, parameters: Mapping[str, Any]) -> list[tuple[str, str, str]]:
        """What is wrong with the mission's own ``parameters`` (its ``parameters:`` block, as written) for this world
        with these (drawn) parameters — values a mission keeps in step with the world by hand, such as the poses
        of the part's bolts —, each as ``(parameter name, what is wrong, what would be valid)``.  The loader asks it
        once the world's parameters are valid.  Default: nothing to check."""
        return []

    # --- asynchronous actions ---------------------------------------------------------------
    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        raise KeyError(name)

    def cancel_action(self, name: str) -> None:
        """Abort a running action (state left before it finished)."""

    def safe_stop(self) -> None:
        """Bring the robot to rest; default: send the robot's stop command."""
        self.apply(self.robot.stop_command())

    def select_sensors(self, names: tuple[str, ...]) -> None:
        """Run only the robot's sensor mounts ``names`` from now on (a task's :attr:`StepResult.sensors`).
        Default: nothing to choose (the world runs every sensor it has).  A world that renders on demand
        overrides it and refuses names it does not have."""

    # --- teach-by-showing (optional) ----------------------------------------------------------
    teaches: ClassVar[bool] = False
    """Whether :meth:`teach` is implemented (``taskflow teach MISSION`` refuses worlds that do not)."""

    @classmethod
    def teach(cls, robot: Robot, params: BaseModel, out_dir: str | Path, seed: int, name: str = "") -> list[Path]:
        """Render what a mission on this world is taught (e.g. visual-path keyframes) into ``out_dir``
        and return the written paths.  ``params`` are the world's parameters drawn with ``seed``;
        ``name`` is the mission's.  Worlds that teach set :attr:`teaches` and override this."""
        raise NotImplementedError(f"world {cls.name!r} has nothing to teach")
