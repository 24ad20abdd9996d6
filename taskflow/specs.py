"""Observation specs: the declared type of each observation entry, and what a world needs from a robot.

Robots and worlds declare what they provide (``"state.pose": array(3)``, ``"sensors.detection":
message(Detection)``), tasks what they require; the compiler matches the two (:mod:`taskflow.contracts`)
and :mod:`taskflow.conformance` checks real observations against them.  Re-exported by
:mod:`taskflow.api`, where task, robot and world authors import them from.

A task names what it reads with :class:`ObsKey` s: ``MARKER = ObsKey("sensors.marker", MarkerPose,
optional=True)`` goes in its ``requires`` (``requires = (POSE, MARKER)``, checked at load against what
the robot and world provide) and reads the observation (``MARKER(obs)``: the typed value; ``None`` for an
absent optional entry; a :class:`MissingObservation` naming the key for an absent required one).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, MutableMapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, Literal, Protocol, TypeVar, cast, overload

import numpy as np


@dataclass(frozen=True)
class ObsSpec:
    """The declared type of one observation entry, named ``"state.<key>"`` or ``"sensors.<key>"``.

    ``kind`` is ``"array"`` (a numpy float/int array of ``shape``; ``None`` in the shape matches any
    length), ``"scalar"`` (a real number), ``"flag"`` (a bool), ``"text"`` (a string), ``"message"`` (an instance of ``cls``,
    e.g. :class:`taskflow.messages.Detection`) or ``"sequence"`` (a tuple or list; of instances of ``cls``
    when it is set, e.g. the keyframes' :class:`taskflow.messages.Image`) or ``"mapping"`` (a dict).  ``optional``
    entries may be absent or ``None`` on a tick (a camera between frames, a perception mode that does
    not produce them).  Robots and worlds declare what they provide, tasks what they require; the
    compiler matches the two and :mod:`taskflow.conformance` checks real observations against them.
    """

    kind: Literal["array", "scalar", "flag", "text", "message", "sequence", "mapping"]
    shape: tuple[int | None, ...] = ()
    cls: type | None = None
    optional: bool = False

    def __str__(self) -> str:
        base = {"array": f"array{list(self.shape)}", "message": self.cls.__name__ if self.cls else "message",
                "sequence": f"sequence[{self.cls.__name__}]" if self.cls else "sequence"}
        return base.get(self.kind, self.kind) + ("?" if self.optional else "")

    def satisfies(self, required: ObsSpec) -> bool:
        """Whether a provided entry of this type can serve a consumer that ``required`` it."""
        if self.kind != required.kind:
            return False
        if self.kind == "array":
            return len(self.shape) == len(required.shape) and all(
                r is None or s == r for s, r in zip(self.shape, required.shape))
        if self.kind == "message":
            return self.cls is not None and required.cls is not None and issubclass(self.cls, required.cls)
        if self.kind == "sequence" and required.cls is not None:
            return self.cls is not None and issubclass(self.cls, required.cls)
        return True

    def problem(self, value: Any) -> str | None:
        """Why ``value`` does not conform to this spec, or None."""
        if value is None:
            return None if self.optional else "is None"
        if self.kind == "array":
            if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiub":
                return f"is {type(value).__name__}, not a numeric numpy array"
            if len(value.shape) != len(self.shape) or any(s is not None and n != s for n, s in zip(value.shape, self.shape)):
                return f"has shape {value.shape}, declared {self.shape}"
            return None
        if self.kind == "scalar":
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            return None if ok else f"is {type(value).__name__}, not a real number"
        if self.kind == "flag":
            return None if isinstance(value, (bool, np.bool_)) else f"is {type(value).__name__}, not a bool"
        if self.kind == "text":
            return None if isinstance(value, str) else f"is {type(value).__name__}, not a string"
        if self.kind == "sequence":
            if not isinstance(value, (tuple, list)):
                return f"is {type(value).__name__}, not a tuple or list"
            for i, x in enumerate(value):
                if self.cls is not None and not isinstance(x, self.cls):
                    return f"has element {i} of type {type(x).__name__}, not {self.cls.__name__}"
            return None
        if self.kind == "mapping":
            return None if isinstance(value, Mapping) else f"is {type(value).__name__}, not a mapping"
        assert self.cls is not None
        return None if isinstance(value, self.cls) else f"is {type(value).__name__}, not {self.cls.__name__}"


def array(*shape: int | None, optional: bool = False) -> ObsSpec:
    """An array entry of ``shape`` (``None``: any length on that axis)."""
    return ObsSpec("array", tuple(shape), optional=optional)


def scalar(optional: bool = False) -> ObsSpec:
    return ObsSpec("scalar", optional=optional)


def flag(optional: bool = False) -> ObsSpec:
    """A bool entry."""
    return ObsSpec("flag", optional=optional)


def text(optional: bool = False) -> ObsSpec:
    return ObsSpec("text", optional=optional)


def sequence(optional: bool = False, of: type | None = None) -> ObsSpec:
    """A tuple or list entry; ``of``: the class every element is an instance of (e.g. a message type)."""
    return ObsSpec("sequence", cls=of, optional=optional)


def mapping(optional: bool = False) -> ObsSpec:
    return ObsSpec("mapping", optional=optional)


def message(cls: type, optional: bool = True) -> ObsSpec:
    """A typed sensor message (optional by default: a sensor may have no frame yet)."""
    return ObsSpec("message", cls=cls, optional=optional)


def instance(cls: type, optional: bool = False) -> ObsSpec:
    """Any object of class ``cls`` that is not a sensor message: a controller's state kept in mission data
    (:class:`taskflow.api.MemoryKey`), e.g. ``instance(PidState)``."""
    return ObsSpec("message", cls=cls, optional=optional)


class ObservationLike(Protocol):
    """What :class:`ObsKey` reads: an :class:`taskflow.api.Observation` (its two sections)."""

    state: dict[str, Any]
    sensors: dict[str, Any]


class MissingObservation(KeyError):
    """A required observation entry is absent on this tick (the error names it)."""


T = TypeVar("T")


class ObsKey(Generic[T]):
    """One observation entry a task reads: its whole name (``"state.pose"``, ``"sensors.marker"``) and its
    :class:`ObsSpec`, declared in the task's ``requires`` and called to read it.

    ``ObsKey("sensors.marker", MarkerPose, optional=True)`` — a message class: ``message(cls)``, typed
    ``ObsKey[MarkerPose | None]``; ``POSE: ObsKey[NDArray[np.float64]] = ObsKey("state.pose", array(3))``
    — a spec (its ``optional`` unless given here).  ``key(obs)`` is one dict lookup: the value; ``None``
    when an optional entry is absent; :class:`MissingObservation` when a required one is."""

    __slots__ = ("entry", "name", "optional", "sensors", "spec")

    @overload
    def __init__(self: ObsKey[T | None], name: str, of: type[T], *, optional: Literal[True]) -> None: ...
    @overload
    def __init__(self: ObsKey[T], name: str, of: type[T], *, optional: Literal[False] = ...) -> None: ...
    @overload
    def __init__(self, name: str, of: ObsSpec, *, optional: bool | None = None) -> None: ...

    def __init__(self, name: str, of: ObsSpec | type, *, optional: bool | None = None) -> None:
        section, _, entry = name.partition(".")
        if section not in ("state", "sensors") or not entry:
            raise ValueError(f"an observation key is 'state.<entry>' or 'sensors.<entry>', got {name!r}")
        if isinstance(of, ObsSpec):
            spec = of if optional is None else dataclasses.replace(of, optional=optional)
        else:
            spec = ObsSpec("message", cls=of, optional=bool(optional))
        self.name = name
        self.spec = spec
        self.entry = entry
        self.sensors = section == "sensors"
        self.optional = spec.optional

    def __call__(self, obs: ObservationLike) -> T:
        try:
            return (obs.sensors if self.sensors else obs.state)[self.entry]  # type: ignore[no-any-return]  # the declared type, checked by the conformance check
        except KeyError:
            if self.optional:
                return None  # type: ignore[return-value]  # T is X | None for an optional key (the overloads)
            raise MissingObservation(f"observation has no {self.name!r} (required, {self.spec})") from None

    def __repr__(self) -> str:
        return f"ObsKey({self.name!r}, {self.spec})"


Requires = Mapping[str, ObsSpec] | Sequence[ObsKey[Any]]
"""A task's ``requires``: observation keys (``(POSE, MARKER)``) or the older mapping ``{"state.pose": array(3)}``."""


def required_specs(requires: Requires) -> dict[str, ObsSpec]:
    """``requires`` in its mapping form (name → spec), whichever form it was declared in; a key declared
    twice with different specs is a ``ValueError``."""
    if isinstance(requires, Mapping):
        return dict(requires)
    out: dict[str, ObsSpec] = {}
    for k in requires:
        if not isinstance(k, ObsKey):
            raise TypeError(f"requires holds ObsKey objects (or is a mapping name → ObsSpec), got {k!r}")
        if out.get(k.name, k.spec) != k.spec:
            raise ValueError(f"observation key {k.name!r} required twice, as {out[k.name]} and {k.spec}")
        out[k.name] = k.spec
    return out


class Metric(str):
    """The unit of a published metric (or mission-data key) with the range its values can take.

    It *is* the unit string (``Metric("m", low=0.0) == "m"``), so ``metrics = {"speed": "m/s"}`` and
    ``{"pos_error": Metric("m", low=0.0, reason="a distance")}`` declare alike; ``low``/``high`` bound every
    value the metric can have (inclusive, in the unit; None: unbounded on that side) and ``reason`` says why
    (``"a distance"``, ``"an angle wrapped to [-π, π]"``).  The loader refuses a guard comparison that no
    value in ``[low, high]`` satisfies (``pos_error < -1 mm``; ``abs(x)`` reads ``[0, max(|low|, |high|)]``).
    """

    low: float | None
    high: float | None
    reason: str

    def __new__(cls, unit: str = "", low: float | None = None, high: float | None = None, reason: str = "") -> Metric:
        if low is not None and high is not None and not low <= high:
            raise ValueError(f"Metric range needs low <= high, got [{low}, {high}]")
        self = super().__new__(cls, unit)
        self.low, self.high, self.reason = low, high, reason
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        return (Metric, (str(self), self.low, self.high, self.reason))

    def bounds(self) -> str:
        """The range as the catalogue writes it, without the unit: ``"≥ 0"``, ``"in [-3.14159, 3.14159]"``
        (empty: unbounded)."""
        if self.low is None and self.high is None:
            return ""
        if self.high is None:
            return f"≥ {self.low:g}"
        if self.low is None:
            return f"≤ {self.high:g}"
        return f"in [{self.low:g}, {self.high:g}]"


DISTANCE = Metric("m", low=0.0, reason="a distance")
SPEED = Metric("m/s", low=0.0, reason="a speed |v|")
WRAPPED_ANGLE = Metric("rad", low=-math.pi, high=math.pi, reason="a wrapped angle")
ROTATION_ANGLE = Metric("rad", low=0.0, high=math.pi, reason="the angle of a rotation")
FORCE = Metric("N", low=0.0, reason="the magnitude of a force")
AGE = Metric("s", low=0.0, reason="the time since an earlier instant")
FLAG = Metric("", low=0.0, high=1.0, reason="1 when true, 0 when false")
COUNT = Metric("", low=0.0, reason="a count")
WEIGHT = Metric("", low=0.0, high=1.0, reason="a task weight")
"""Ranged units of the kinds of metric the shipped tasks publish (declare ``{"pos_error": DISTANCE}``)."""


ValueT = TypeVar("ValueT")


class _NoDefault:
    """The default of a :class:`MemoryKey` that has none (the key must be written before it is read)."""

    def __repr__(self) -> str:
        return "NO_DEFAULT"


NO_DEFAULT: Any = _NoDefault()


@dataclass(frozen=True, eq=False)
class MemoryKey(Generic[ValueT]):
    """One entry of a run's mission data (:attr:`TaskContext.memory`), defined once by the module that
    owns it and declared by every task that writes it (:attr:`Task.writes`) or needs it (:attr:`Task.reads`):

    * ``name`` — its whole name, the owner's namespace and the entry (``"viki.object"``); missions name it
      so (``data:`` defaults, ``data.viki.object[0]`` in guards, ``$data.viki.object`` in parameters);
    * ``spec`` — the type of its value, in the observation-spec vocabulary (``array(2)``, ``scalar()``,
      ``flag()``, ``text()``, ``mapping()``, ``sequence()``, ``instance(PidState)``); every write is checked
      against it, and it decides what a mission may do with the key (guards read ``scalar``/``flag`` keys
      and the components of fixed-shape 1-D ``array`` keys; an ``instance`` cannot be given in YAML);
    * ``unit`` — the SI base unit of its numbers (``"m"``), for guards (``data.viki.object[0] < 2 cm``);
    * ``default`` — the value it holds from the start of every run (copied), or :data:`NO_DEFAULT`;
    * ``doc`` — what it holds, for ``docs/missions.md``;
    * ``output`` — whether the run summary lists its final value under ``outputs`` (False for a
      controller's internal state — integrators, histories — that would only bloat the summary).

    Through its type parameter it types the accessors: ``MEM_OBJECT: MemoryKey[NDArray[np.float64]]``;
    ``key(memory)`` reads an entry that must exist (the error names it), ``key.get``, ``key.set``,
    ``key.setdefault``, ``key.present`` the rest."""

    name: str
    spec: ObsSpec
    unit: str = ""
    default: Any = NO_DEFAULT
    doc: str = ""
    output: bool = True

    @property
    def has_default(self) -> bool:
        return self.default is not NO_DEFAULT

    def get(self, memory: Mapping[str, Any]) -> ValueT | None:
        return cast("ValueT | None", memory.get(self.name))

    def __call__(self, memory: Mapping[str, Any]) -> ValueT:
        """The entry, which must be there (a clear error names it otherwise)."""
        try:
            return cast(ValueT, memory[self.name])
        except KeyError:
            raise KeyError(f"shared memory has no {self.name!r} yet (written by an earlier state)") from None

    def set(self, memory: MutableMapping[str, Any], value: ValueT) -> None:
        memory[self.name] = value

    def setdefault(self, memory: MutableMapping[str, Any], default: ValueT) -> ValueT:
        return cast(ValueT, memory.setdefault(self.name, default))

    def present(self, memory: Mapping[str, Any]) -> bool:
        return self.name in memory


@dataclass(frozen=True)
class RobotNeeds:
    """What a world needs from the robot it hosts (:attr:`World.needs`).

    ``interfaces``: the command interfaces it can actuate (empty: any); ``sensors``: mount name → sensor
    kind the world renders from the robot's description (``{"front_camera": "rgbd_camera"}``);
    ``body``: the world builds the robot from a registered simulator body (``taskflow.bodies`` entry
    point named after the robot), so the robot needs one.
    """

    interfaces: tuple[str, ...] = ()
    sensors: Mapping[str, str] = field(default_factory=dict)
    body: bool = False
