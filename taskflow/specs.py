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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, Literal, Protocol, TypeVar, overload

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
