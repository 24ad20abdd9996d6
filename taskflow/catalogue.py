"""The catalogue of what is registered: every task, robot, world and sensor stream, as data.

An :class:`Entry` holds what a mission author needs to know about one registered name — its parameters
(type, default, unit, bounds, description), the profile slots ``bind:`` fills, the metrics a guard can
read (with units), the events ``on:`` can name, a world's actions, the observation entries a task
requires and who provides them, a robot's command interface, a world's ground-truth keys — built from
the classes' own declarations (:mod:`taskflow.api`) and the registries (:mod:`taskflow.registry`),
never written by hand.  ``sensor`` entries are the ``sensors.*`` observation streams: each lists the
worlds (and robots) that provide it and the tasks that read it.

:func:`entry_to_json` is the JSON form (``--json``; :func:`entry_from_json` reads it back);
:mod:`taskflow.catalogue_render` renders entries as terminal text (``taskflow list`` / ``taskflow
describe``) and markdown (``taskflow describe --all --markdown``, the generated ``docs/reference.md``).

A parameter's unit is read from its declaration, first found: ``Field(json_schema_extra={"unit": "m"})``;
the field's description (``"(m)"``, ``"(m/s), paper: 1.0"``, a leading ``"s without ..."``, a trailing
``"... m, m, rad"``); its model's docstring (``"``max_age`` (s)"``); its name's suffix (``_px``, ``_s``,
``_hz``, ``_m``, ``_rad``).  No unit found is shown as nothing, never guessed further.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import inspect
import json
import math
import re
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal, Union

import annotated_types
import numpy as np
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import to_jsonable_python

from . import api
from .api import ObsSpec, Robot, Task, World, required_specs
from .contracts import hosts, task_problem
from .fidelity import Fidelity
from .registry import ROBOTS, TASKS, WORLDS, Registry, RegistryError, describe_choices
from .units import UNITS, suffix_unit

Kind = Literal["task", "robot", "world", "sensor"]
KINDS: tuple[Kind, ...] = ("task", "robot", "world", "sensor")
PLURAL: dict[str, Kind] = {"tasks": "task", "robots": "robot", "worlds": "world", "sensors": "sensor"}
SENSOR_PREFIX = "sensors."


# -- the data model ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Param:
    """One field of a parameter, profile or robot-parameter model: ``type`` as a mission writes it
    (``float``, ``[float, float]``, ``"front" | "rear"``, a model's name), ``default`` as JSON (None with
    ``required``), ``unit`` (empty: none declared), ``bounds`` (``"> 0, ≤ 100"``)."""

    name: str
    type: str
    required: bool
    default: Any = None
    unit: str = ""
    bounds: str = ""
    description: str = ""


@dataclass(frozen=True)
class Model:
    """A pydantic model (or message class) a parameter's type names: its name, summary and fields."""

    name: str
    summary: str
    fields: tuple[Param, ...] = ()


@dataclass(frozen=True)
class Slot:
    """A profile slot: ``bind: {name: PROFILE}`` names a profile of ``profiles.<profile_kind>`` (or gives
    the fields inline); ``required``: the model has no defaults for every field, so a binding is needed."""

    name: str
    profile_kind: str
    model: str
    required: bool
    summary: str
    fields: tuple[Param, ...] = ()


@dataclass(frozen=True)
class Metric:
    """A metric guards can read, in its base ``unit`` (``""``: dimensionless), with the range its values
    take where the task or world declares one (``bounds`` ``"≥ 0"``, empty: none; ``reason``: why)."""

    name: str
    unit: str
    bounds: str = ""
    reason: str = ""


def _metrics(declared: dict[str, str]) -> tuple[Metric, ...]:
    """The catalogue's view of a ``metrics`` declaration (plain unit strings or :class:`taskflow.api.Metric`)."""
    return tuple(Metric(k, str(u), u.bounds(), u.reason) if isinstance(u, api.Metric) else Metric(k, str(u))
                 for k, u in declared.items())


@dataclass(frozen=True)
class Action:
    """A world's asynchronous action (``action: {name, params}``) and the events it ends with."""

    name: str
    ends_with: tuple[str, ...]
    params: tuple[Param, ...] = ()


@dataclass(frozen=True)
class FidelityValue:
    """One parameter a world's fidelity level sets (``world.params.fidelity: LEVEL``) and its source."""

    param: str
    value: Any
    source: str


@dataclass(frozen=True)
class FidelityLevel:
    """A named fidelity level of a world (:mod:`taskflow.fidelity`): the parameters it sets."""

    name: str
    values: tuple[FidelityValue, ...]


@dataclass(frozen=True)
class Stream:
    """An observation entry as one component declares it (``type``: the :class:`ObsSpec`, ``?`` when
    optional); ``by``: the other side — the providers of a requirement, the readers of a provision, as
    ``"world viki_ground"`` / ``"task viki_hyco"``."""

    key: str
    type: str
    by: tuple[str, ...] = ()


@dataclass(frozen=True)
class Entry:
    """What one registered name offers a mission (fields that do not apply to its kind are empty).

    ``summary`` is the first sentence of ``doc`` (the class docstring, with its module's when it refers
    there; for a sensor: its type, providers and readers), ``source`` the ``module:Class``.  ``params`` are
    the ``params:`` keys (``params_doc`` the Params model's docstring), ``slots`` the profile slots (tasks),
    ``metrics`` / ``events`` what guards and ``on:`` can name, ``actions`` a world's.  ``requires`` are the
    observation entries a task reads, each with its providers; ``provides`` those a robot or world adds,
    each with its readers; for a sensor, one :class:`Stream` per provider (``provides``) and per reader
    (``requires``).  ``command_interface``: a task's or robot's interface, the ones a world actuates
    (``a | b``; empty: any); ``command_keys`` a robot's commands (type ``array[N]``); ``robot_params`` the
    robot parameters a task reads; ``sensors`` the mounts a robot carries or a world needs (type = the
    sensor kind); ``needs_body``: the world needs a simulator body for its robot.  ``works_with``: the
    ``"ROBOT on WORLD"`` pairs a task runs on, the worlds hosting and tasks driving a robot, the robots a
    world hosts.  ``types`` are the models (or the message class) the fields above name, recursively."""

    kind: Kind
    name: str
    summary: str
    doc: str = ""
    source: str = ""
    params_doc: str = ""
    params: tuple[Param, ...] = ()
    slots: tuple[Slot, ...] = ()
    metrics: tuple[Metric, ...] = ()
    events: tuple[str, ...] = ()
    actions: tuple[Action, ...] = ()
    requires: tuple[Stream, ...] = ()
    provides: tuple[Stream, ...] = ()
    command_interface: str = ""
    command_keys: tuple[Param, ...] = ()
    robot_params: tuple[Param, ...] = ()
    sensors: tuple[Param, ...] = ()
    needs_body: bool = False
    ground_truth_keys: tuple[str, ...] = ()
    fidelity: tuple[FidelityLevel, ...] = ()
    works_with: tuple[str, ...] = ()
    types: tuple[Model, ...] = ()


class UnknownEntry(LookupError):
    """A name no entry has (or several have, without ``kind``); the message names the valid ones."""


# -- reading declarations -----------------------------------------------------------------------------
def _own_doc(obj: object) -> str:
    """The object's own docstring, dedented ('' when it only inherits one)."""
    doc = vars(obj).get("__doc__") if isinstance(obj, type) else getattr(obj, "__doc__", None)
    return inspect.cleandoc(doc) if isinstance(doc, str) else ""


def _class_doc(cls: type) -> str:
    """A registered class's docstring, followed by its module's when it refers the reader there."""
    doc = _own_doc(cls)
    if "module docstring" in doc:
        module = inspect.getmodule(cls)
        if module is not None and module.__doc__:
            doc += "\n\n" + inspect.cleandoc(module.__doc__)
    return doc


def summary_of(doc: str) -> str:
    """The first sentence of a docstring's first paragraph, on one line."""
    para = " ".join(doc.split("\n\n", 1)[0].split())
    m = re.search(r"(?<![.\w]\w)(?<!e\.g)(?<!i\.e)(?<!eq)(?<!eqs)\.(\s|$)", para)
    return para[: m.start() + 1] if m else para


_EXTRA_UNITS = ("m/s²", "rad/s²", "N·m", "N/m", "N·s/m", "kg", "1/s", "m²")
_UNIT_WORDS = {u for u in UNITS if u} | set(_EXTRA_UNITS)
_UNIT = "|".join(re.escape(u) for u in sorted(_UNIT_WORDS, key=len, reverse=True))
_UNIT_LIST = rf"(?:{_UNIT})(?:,\s*(?:{_UNIT}))*"
_PAREN_UNIT = re.compile(rf"\(({_UNIT_LIST})(?:[);,]|\s*$)")
_LEADING_UNIT = re.compile(rf"^({_UNIT})(?=[\s:,])")
_TRAILING_UNIT = re.compile(rf"\)\s+({_UNIT_LIST})\s*$")


def param_unit(name: str, info: FieldInfo, model_doc: str = "") -> str:
    """The unit field ``name`` declares: explicitly, in its description, in its model's docstring
    ``model_doc`` or by its name's suffix (in that order; '' when none does)."""
    extra = info.json_schema_extra
    if isinstance(extra, dict) and isinstance(extra.get("unit"), str):
        return str(extra["unit"])
    text = info.description or ""
    for pattern in (_PAREN_UNIT, _LEADING_UNIT, _TRAILING_UNIT):
        m = pattern.search(text)
        if m:
            return m.group(1)
    m = re.search(rf"``{re.escape(name)}``\s*\(({_UNIT_LIST})[);,]", model_doc)
    if m:
        return m.group(1)
    return suffix_unit(name) or ""


def type_label(t: Any) -> str:
    """A field's type as a mission author reads it."""
    origin, args = typing.get_origin(t), typing.get_args(t)
    if t is type(None):
        return "null"
    if origin is typing.Annotated:
        return type_label(args[0])
    if origin is Literal:
        return " | ".join(json.dumps(a) for a in args)
    if origin in (Union, types.UnionType):
        return " | ".join(type_label(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"[{type_label(args[0])}, ...]"
        return "[" + ", ".join(type_label(a) for a in args) + "]"
    if origin in (list, typing.Sequence, set, frozenset):
        return f"list[{type_label(args[0])}]" if args else "list"
    if origin in (dict, typing.Mapping):
        return f"map[{type_label(args[0])}, {type_label(args[1])}]" if args else "map"
    if origin is np.ndarray:
        dtype = typing.get_args(args[1]) if len(args) == 2 else ()
        return f"array[{dtype[0].__name__}]" if dtype and isinstance(dtype[0], type) else "array"
    if origin is collections.abc.Callable:
        return f"({', '.join(type_label(a) for a in args[0])}) -> {type_label(args[1])}" if args else "callable"
    if t is typing.Any:
        return "any"
    if isinstance(t, type):
        return t.__name__
    return str(t).replace("typing.", "")


def _models_in(t: Any) -> list[type[BaseModel]]:
    """Pydantic models a type names (inside unions, lists, tuples, Annotated)."""
    if isinstance(t, type) and issubclass(t, BaseModel):
        return [t]
    return [m for a in typing.get_args(t) for m in _models_in(a)]


_BOUNDS = ((annotated_types.Gt, "gt", ">"), (annotated_types.Ge, "ge", "≥"), (annotated_types.Lt, "lt", "<"),
           (annotated_types.Le, "le", "≤"), (annotated_types.MinLen, "min_length", "length ≥"),
           (annotated_types.MaxLen, "max_length", "length ≤"))


def _bounds(info: FieldInfo) -> str:
    out = []
    for meta in info.metadata:
        for cls, attr, sym in _BOUNDS:
            if isinstance(meta, cls):
                out.append(f"{sym} {getattr(meta, attr):g}")
    return ", ".join(out)


def _default(info: FieldInfo) -> Any:
    """The field's default as strict JSON (non-finite numbers as the strings ``"inf"``, ``"-inf"``, ``"nan"``)."""
    return _strict_json(to_jsonable_python(info.get_default(call_default_factory=True), fallback=repr))


def _strict_json(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, list):
        return [_strict_json(x) for x in v]
    if isinstance(v, dict):
        return {k: _strict_json(x) for k, x in v.items()}
    return v


def params_of(model: type[BaseModel] | None) -> tuple[Param, ...]:
    """Every field of ``model`` (by its YAML key: the alias when it has one)."""
    if model is None:
        return ()
    doc = _own_doc(model)
    out = []
    for name, info in model.model_fields.items():
        required = info.is_required()
        out.append(Param(name=info.alias or name, type=type_label(info.annotation), required=required,
                         default=None if required else _default(info), unit=param_unit(name, info, doc),
                         bounds=_bounds(info), description=" ".join((info.description or "").split())))
    return tuple(out)


def _nested_models(roots: Iterable[type[BaseModel] | None]) -> tuple[Model, ...]:
    """The models the fields of ``roots`` name, recursively, each once, in order of first mention."""
    seen: dict[type[BaseModel], None] = {}
    todo = [r for r in roots if r is not None]
    top = set(todo)
    while todo:
        model = todo.pop(0)
        for info in model.model_fields.values():
            for m in _models_in(info.annotation):
                if m not in seen and m not in top:
                    seen[m] = None
                    todo.append(m)
    return tuple(Model(m.__name__, summary_of(_own_doc(m)), params_of(m)) for m in seen)


def _slot_required(model: type[BaseModel]) -> bool:
    return any(info.is_required() for info in model.model_fields.values())


def _source(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _loaded(registry: Registry[Any], broken: dict[str, str]) -> dict[str, type]:
    """The registry's classes by name; an entry point that fails to load is noted in ``broken``."""
    out = {}
    for name in registry.names():
        try:
            out[name] = registry.get(name)
        except RegistryError as exc:
            broken[f"{registry.kind} {name}"] = str(exc)
    return out


# -- building the catalogue ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Catalogue:
    """Every entry, by kind then name; ``broken``: registered names whose class could not be loaded."""

    entries: tuple[Entry, ...]
    broken: dict[str, str] = dataclasses.field(default_factory=dict)

    def of_kind(self, kind: Kind) -> tuple[Entry, ...]:
        return tuple(e for e in self.entries if e.kind == kind)

    def find(self, name: str, kind: Kind | None = None) -> Entry:
        """The entry called ``name`` (a sensor also by its short name: ``detection``)."""
        pool = [e for e in self.entries if kind is None or e.kind == kind]
        hits = [e for e in pool if e.name == name] or [e for e in pool if e.kind == "sensor"
                                                          and e.name == SENSOR_PREFIX + name]
        if len(hits) == 1:
            return hits[0]
        if hits:
            kinds = ", ".join(e.kind for e in hits)
            raise UnknownEntry(f"{name!r} is a {kinds}: choose one with --kind")
        what = f"{kind} name" if kind else "name"
        valid = sorted({e.name for e in pool})
        raise UnknownEntry(f"unknown {what} {name!r} — {describe_choices(name, valid)}")


def build() -> Catalogue:
    """The catalogue of everything registered now (entry points are imported)."""
    broken: dict[str, str] = {}
    tasks, robots, worlds = _loaded(TASKS, broken), _loaded(ROBOTS, broken), _loaded(WORLDS, broken)
    entries = [task_entry(t, robots, worlds) for t in tasks.values()]
    entries += [robot_entry(r, tasks, worlds) for r in robots.values()]
    entries += [world_entry(w, tasks, robots) for w in worlds.values()]
    entries += sensor_entries(tasks, robots, worlds)
    return Catalogue(tuple(entries), broken)


def _providers(key: str, need: ObsSpec, robots: dict[str, type], worlds: dict[str, type]) -> tuple[str, ...]:
    out = [f"robot {n}" for n, r in robots.items() if key in r.observations and r.observations[key].satisfies(need)]
    out += [f"world {n}" for n, w in worlds.items() if key in w.observations and w.observations[key].satisfies(need)]
    return tuple(out)


def _readers(key: str, spec: ObsSpec, tasks: dict[str, type]) -> tuple[str, ...]:
    return tuple(f"task {n}" for n, t in tasks.items() if key in t.requires and spec.satisfies(t.requires[key]))


def _worlds_for(task: type[Task], robot: type[Robot], worlds: dict[str, type]) -> tuple[str, ...]:
    """The worlds on which ``task`` can run with ``robot``: each hosts the robot, and the task's interface,
    the robot parameters it reads and the observations it requires are there (the compiler's rule,
    :func:`taskflow.contracts.task_problem`)."""
    return tuple(n for n, w in worlds.items() if hosts(w, robot) and task_problem(task, robot, w) is None)


def task_entry(task: type[Task], robots: dict[str, type], worlds: dict[str, type]) -> Entry:
    doc = _class_doc(task)
    slots = tuple(Slot(name=s, profile_kind=getattr(m, "kind", None) or s, model=m.__name__,
                       required=_slot_required(m), summary=summary_of(_own_doc(m)), fields=params_of(m))
                  for s, m in task.slots.items())
    works = tuple(f"{r.name} on {w}" for r in robots.values() for w in _worlds_for(task, r, worlds))
    return Entry(
        kind="task", name=task.name, summary=summary_of(doc), doc=doc, source=_source(task),
        params_doc=_own_doc(task.Params), params=params_of(task.Params), slots=slots,
        metrics=_metrics(task.metrics), events=tuple(task.events),
        requires=tuple(Stream(k, str(s), _providers(k, s, robots, worlds)) for k, s in required_specs(task.requires).items()),
        command_interface=task.command_interface, robot_params=params_of(task.robot_params),
        works_with=works, types=_nested_models([task.Params, *task.slots.values(), task.robot_params]))


def robot_entry(robot: type[Robot], tasks: dict[str, type], worlds: dict[str, type]) -> Entry:
    doc = _class_doc(robot)
    drivers = [f"task {n}" for n, t in tasks.items() if _worlds_for(t, robot, worlds)]
    hosting = [f"world {n}" for n, w in worlds.items() if hosts(w, robot)]
    return Entry(
        kind="robot", name=robot.name, summary=summary_of(doc), doc=doc, source=_source(robot),
        params_doc=_own_doc(robot.Params), params=params_of(robot.Params),
        command_interface=robot.command_interface,
        command_keys=tuple(Param(k, f"array[{n}]", True) for k, n in robot.command_keys.items()),
        provides=tuple(Stream(k, str(s), _readers(k, s, tasks)) for k, s in robot.observations.items()),
        sensors=tuple(Param(m, k, True) for m, k in robot.sensors.items()),
        works_with=tuple(hosting + drivers), types=_nested_models([robot.Params]))


def world_entry(world: type[World], tasks: dict[str, type], robots: dict[str, type]) -> Entry:
    doc = _class_doc(world)
    action_models = [world.action_params.get(a) for a in world.actions]
    needs = world.needs
    return Entry(
        kind="world", name=world.name, summary=summary_of(doc), doc=doc, source=_source(world),
        params_doc=_own_doc(world.Params), params=params_of(world.Params),
        metrics=_metrics(world.metrics), events=tuple(world.events),
        actions=tuple(Action(a, tuple(ends), params_of(world.action_params.get(a)))
                      for a, ends in world.actions.items()),
        provides=tuple(Stream(k, str(s), _readers(k, s, tasks)) for k, s in world.observations.items()),
        command_interface=" | ".join(needs.interfaces),
        sensors=tuple(Param(m, k, True) for m, k in needs.sensors.items()), needs_body=needs.body,
        ground_truth_keys=tuple(world.ground_truth_keys), fidelity=fidelity_levels(world.Params),
        works_with=tuple(f"robot {n}" for n, r in robots.items() if hosts(world, r)),
        types=_nested_models([world.Params, *action_models]))


def fidelity_levels(params: type) -> tuple[FidelityLevel, ...]:
    """The named fidelity levels of a world parameter model (none unless it derives from :class:`Fidelity`)."""
    if not (isinstance(params, type) and issubclass(params, Fidelity)):
        return ()
    def value(v: Any) -> Any:
        return _strict_json(to_jsonable_python(v, fallback=repr))

    return tuple(FidelityLevel(name, tuple(FidelityValue(k, value(v.value), v.source) for k, v in level.items()))
                 for name, level in params.FIDELITY.items())


def _message_model(cls: type | None) -> tuple[Model, ...]:
    if cls is None or not dataclasses.is_dataclass(cls):
        return ()
    hints = typing.get_type_hints(cls)
    fields = tuple(Param(f.name, type_label(hints.get(f.name, f.type)), True) for f in dataclasses.fields(cls))
    return (Model(cls.__name__, summary_of(_own_doc(cls)), fields),)


def sensor_entries(tasks: dict[str, type], robots: dict[str, type], worlds: dict[str, type]) -> list[Entry]:
    """One entry per ``sensors.*`` observation entry any robot or world provides or any task reads."""
    declared: dict[str, list[tuple[str, ObsSpec]]] = {}
    for kind, table in (("robot", robots), ("world", worlds)):
        for n, c in table.items():
            for key, spec in c.observations.items():
                if key.startswith(SENSOR_PREFIX):
                    declared.setdefault(key, []).append((f"{kind} {n}", spec))
    readers: dict[str, list[tuple[str, ObsSpec]]] = {}
    for n, t in tasks.items():
        for key, spec in t.requires.items():
            if key.startswith(SENSOR_PREFIX):
                readers.setdefault(key, []).append((f"task {n}", spec))
    out = []
    for key in sorted(set(declared) | set(readers)):
        specs = [s for _, s in declared.get(key, [])] + [s for _, s in readers.get(key, [])]
        cls = next((s.cls for s in specs if s.cls is not None), None)
        by = [who for who, _ in declared.get(key, [])]
        read = [who for who, _ in readers.get(key, [])]
        summary = (f"{_type_phrase(specs[0])} — from {', '.join(by) or '(nothing registered)'}; "
                   f"read by {', '.join(read) or '(no task)'}")
        out.append(Entry(
            kind="sensor", name=key, summary=summary,
            provides=tuple(Stream(key, str(s), (who,)) for who, s in declared.get(key, [])),
            requires=tuple(Stream(key, str(s), (who,)) for who, s in readers.get(key, [])),
            types=_message_model(cls)))
    return out


def _type_phrase(spec: ObsSpec) -> str:
    name = spec.cls.__name__ if spec.cls else spec.kind
    return f"sequence of {name}" if spec.kind == "sequence" else name


# -- JSON ---------------------------------------------------------------------------------------------
def entry_to_json(entry: Entry) -> dict[str, Any]:
    return dataclasses.asdict(entry)


def _from(cls: type, data: Any) -> Any:
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue
        t, v = hints[f.name], data[f.name]
        args = typing.get_args(t)
        if typing.get_origin(t) is tuple and args and dataclasses.is_dataclass(args[0]):
            v = tuple(_from(args[0], x) for x in v)
        elif typing.get_origin(t) is tuple:
            v = tuple(v)
        kwargs[f.name] = v
    return cls(**kwargs)


def entry_from_json(data: dict[str, Any]) -> Entry:
    """The :class:`Entry` a :func:`entry_to_json` dict describes (``--json`` output read back)."""
    return _from(Entry, data)  # type: ignore[no-any-return]
