"""Load a mission file: YAML → pydantic shape check → name resolution → a compiled machine.

Every problem is collected as a :class:`~taskflow.errors.Problem` with file, line and column and
raised together in one :class:`~taskflow.errors.MissionError`.  Nothing here runs the simulator.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import yaml
from pydantic import BaseModel, ValidationError

from .api import Robot, Task, World
from .distributions import DistributionError, distributions_in, replaced, sample, support, world_rng
from .errors import MissionError, Problem
from .guards import GuardSyntaxError, Predicate, bind_units, compile_guard, parse_guard
from .registry import ROBOTS, TASKS, WORLDS, RegistryError, UnknownName, describe_choices
from .schema import SINCE_ENTRY, SINCE_FIRST_ENTRY, Machine, Mission, State
from .units import UnitError, parse_quantity
from .yamlsrc import MissionLoader, SourceMap, load_yaml_file, load_yaml_text

YPath = tuple[Any, ...]


@dataclass(eq=False)
class CompiledTransition:
    """A transition ready to run: its trigger compiled, its target resolved."""

    index: int
    source: "StateNode"
    target: "StateNode"
    kind: str  # when | after | on (with an optional condition) | done
    label: str  # as written, for logs and diagrams
    predicate: Predicate | None = None
    dwell: float = 0.0
    after: float = 0.0
    since: "StateNode | None" = None  # `after` counts from this state's entry (the source unless `since` names another)
    since_first: bool = False  # `since: first_entry`: from the first entry, kept across re-entries and resumes
    event: str | None = None
    done: bool | str | None = None
    resume: bool = True
    blend: float = 0.0


@dataclass(eq=False)
class StateNode:
    """One state of the compiled machine."""

    name: str
    path: str  # dotted from the root; "" for the root
    parent: "StateNode | None"
    ypath: YPath
    children: dict[str, "StateNode"] = field(default_factory=dict)
    initial: str | None = None
    task_cls: type[Task] | None = None  # effective (inherited)
    task_params: dict[str, Any] = field(default_factory=dict)  # raw, may hold $refs
    task_ypath: YPath = ()
    bind: dict[str, tuple[str, Any, YPath]] = field(default_factory=dict)  # slot → (kind, name|inline, where)
    profiles: dict[str, BaseModel] = field(default_factory=dict)  # resolved for a leaf
    transitions: list[CompiledTransition] = field(default_factory=list)
    history: bool = False
    foreach: tuple[str, str, str] | None = None  # (list parameter, item name, on_failure)
    require: int = 0  # foreach: items that must succeed (the mission's `require` rule resolved against the list)
    require_text: str = ""  # the rule as written ("all", "3", "75 %")
    action: tuple[str, dict[str, Any]] | None = None
    final: str | None = None  # outcome
    depth: int = 0

    @property
    def is_leaf(self) -> bool:
        return not self.children

    def ancestors(self) -> list["StateNode"]:
        """Root first, self last."""
        out: list[StateNode] = []
        n: StateNode | None = self
        while n is not None:
            out.append(n)
            n = n.parent
        return out[::-1]

    def walk(self) -> Iterator["StateNode"]:
        yield self
        for c in self.children.values():
            yield from c.walk()

    def initial_leaf(self) -> "StateNode":
        n = self
        while n.children:
            n = n.children[n.initial]  # type: ignore[index]
        return n

    def scope_items(self) -> list[tuple[str, str]]:
        """(item name, list parameter) of every enclosing foreach, outermost first."""
        return [(a.foreach[1], a.foreach[0]) for a in self.ancestors() if a.foreach]


@dataclass
class CompiledMission:
    """A validated mission: the raw document, its shape, and the compiled machine."""

    file: str
    raw: dict[str, Any]
    spec: Mission
    root: StateNode
    states: dict[str, StateNode]  # path → node (root excluded)
    transitions: list[CompiledTransition]
    robot_cls: type[Robot]
    robot_params: BaseModel
    world_cls: type[World]
    world_params_raw: dict[str, Any]
    metric_units: dict[str, str]  # every metric any task or the world publishes
    events: set[str]

    @property
    def name(self) -> str:
        return self.spec.mission

    def world_params(self, seed: int) -> BaseModel:
        """World parameters with every distribution drawn from ``seed``."""
        drawn = sample(self.world_params_raw, world_rng(seed))
        return self.world_cls.Params.model_validate(with_model_defaults(self.world_cls.Params, drawn))

    def build_robot(self) -> Robot:
        return self.robot_cls(self.robot_params)

    def description_of(self, node: StateNode) -> str:
        """The ``description`` written on a state (empty when none)."""
        spec: Any = self.spec.machine
        for a in node.ancestors()[1:]:
            spec = spec.states[a.name]
        return getattr(spec, "description", "") or ""

    def leaves(self) -> list[StateNode]:
        return [n for n in self.states.values() if n.is_leaf]


# ---------------------------------------------------------------------------------------------
# entry points


def load_mission(path: str | Path, overrides: list[str] | None = None) -> CompiledMission:
    data, smap, _ = load_yaml_file(path)
    return compile_mission(data, smap, overrides)


def load_mission_text(text: str, file: str = "<string>", overrides: list[str] | None = None) -> CompiledMission:
    data, smap = load_yaml_text(text, file)
    return compile_mission(data, smap, overrides)


def with_model_defaults(model: type[BaseModel], values: Any) -> Any:
    """``values`` with every partial mapping given for a field whose default is a model completed
    from that default, recursively: ``front_camera: {width: 640}`` (or ``--set
    robot.params.front_camera.width=640``) changes one field of the default camera instead of
    replacing the camera by one with only a width."""
    if not isinstance(values, dict):
        return values
    out = dict(values)
    for name, field in model.model_fields.items():
        key = field.alias if field.alias is not None and field.alias in out else name
        default = field.default
        if key in out and isinstance(out[key], dict) and isinstance(default, BaseModel):
            sub = type(default)
            out[key] = {**default.model_dump(by_alias=True), **with_model_defaults(sub, out[key])}
    return out


def apply_overrides(data: Any, overrides: list[str], file: str, smap: SourceMap | None = None) -> Any:
    """``--set a.b.0.c=value``: the value is read as YAML by the same safe YAML 1.2 reader as the file
    (``on:`` stays a key, ``1e3`` is a number).

    With ``smap``, each overridden path is remembered so that a problem inside it names the
    ``--set`` that caused it instead of a line of the file."""
    data = copy.deepcopy(data)
    for item in overrides:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise MissionError([Problem(file, 0, 0, f"--set {item!r} is not KEY=VALUE", "write e.g. --set world.params.speed=0.05")])
        try:
            value = yaml.load(text, Loader=MissionLoader)  # noqa: S506 - MissionLoader is a SafeLoader (YAML 1.2 scalars)
        except yaml.YAMLError as exc:
            raise MissionError([Problem(file, 0, 0, f"--set {key}: value is not valid YAML ({exc})")]) from None
        node = data
        parts = key.split(".")
        ypath: list[Any] = []
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            if isinstance(node, list):
                try:
                    idx = int(part)
                    ypath.append(idx)
                    if last:
                        node[idx] = value
                    else:
                        node = node[idx]
                    continue
                except (ValueError, IndexError):
                    raise MissionError([Problem(file, 0, 0, f"--set {key}: {part!r} is not an index of a list of {len(node)}")]) from None
            if not isinstance(node, dict):
                raise MissionError([Problem(file, 0, 0, f"--set {key}: {'.'.join(parts[:i])} is not a mapping")])
            if not last and isinstance(node.get(part), str) and part in ("robot", "world", "task"):
                node[part] = {"name": node[part]}  # `robot: racecar` → `{name: racecar}` so params can be set
            ypath.append(part)
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        if smap is not None:
            smap.overrides[tuple(ypath)] = item
    return data


def compile_mission(data: Any, smap: SourceMap, overrides: list[str] | None = None) -> CompiledMission:
    file = smap.file
    if overrides:
        data = apply_overrides(data, overrides, file, smap)
    if not isinstance(data, dict):
        raise MissionError([smap.problem((), f"a mission is a mapping of keys, got {type(data).__name__}",
                                         "start with `mission: NAME`")])
    try:
        spec = Mission.model_validate(data)
    except ValidationError as exc:
        raise MissionError(_pydantic_problems(exc, smap, ())) from None
    return _Compiler(data, spec, smap).compile()


# ---------------------------------------------------------------------------------------------
# pydantic error → problem


_UNION_TAGS = ("str", "TaskRef", "ComponentRef", "bool", "float", "int", "list", "dict")


def _clean_loc(loc: tuple[Any, ...]) -> tuple[Any, ...]:
    """Drop pydantic's union-member tags from an error location; map aliases back."""
    out: list[Any] = []
    for part in loc:
        if isinstance(part, str) and (part in _UNION_TAGS or "[" in part or part.startswith("function-")
                                      or part in ("literal['succeeded','failed','aborted']",)):
            continue
        out.append({"for_": "for", "in_": "in", "as_": "as"}.get(part, part) if isinstance(part, str) else part)
    return tuple(out)


_UNION_NOISE = ("bool_type", "bool_parsing", "string_type", "float_type", "float_parsing", "int_type",
                "int_parsing", "dict_type", "list_type", "model_type", "model_attributes_type")


def _pydantic_problems(exc: ValidationError, smap: SourceMap, base: YPath, model: type[BaseModel] | None = None) -> list[Problem]:
    errors = [(base + _clean_loc(tuple(e["loc"])), e) for e in exc.errors()]
    # a value that fails a union (e.g. `final: crashed` against bool | Literal[...]) produces one error per
    # member: keep the most telling ones (the literal's choices) and drop the members' type noise
    informative = {p for p, e in errors if e["type"] not in _UNION_NOISE}
    problems: list[Problem] = []
    seen: set[tuple[Any, ...]] = set()
    for path, err in errors:
        etype = err["type"]
        if etype in _UNION_NOISE and path in informative:
            continue
        loc = path[len(base):]
        msg = err["msg"].removeprefix("Value error, ")
        hint = ""
        if etype == "extra_forbidden":
            key = loc[-1] if loc else "?"
            valid = _allowed_keys(model or Mission, loc[:-1])
            msg = f"unknown key {key!r}"
            hint = describe_choices(str(key), valid) if valid else ""
        elif etype == "missing":
            msg = f"missing required key {loc[-1]!r}" if loc else "missing value"
            path = path[:-1]
        elif etype.startswith("literal_error"):
            hint = msg
            msg = f"invalid value {err.get('input')!r}"
        elif etype in ("bool_type", "bool_parsing"):
            msg = f"{err.get('input')!r}: {msg[0].lower()}{msg[1:]}"
            hint = "write true or false (YAML 1.2: yes/no/on/off are strings)"
        key = (path, msg)
        if key in seen:
            continue
        seen.add(key)
        problems.append(smap.problem(path, msg, hint))
    return _dedupe(problems)


def _dedupe(problems: list[Problem]) -> list[Problem]:
    out: list[Problem] = []
    for p in problems:
        if any(q.line == p.line and q.col == p.col and q.message == p.message for q in out):
            continue
        out.append(p)
    return sorted(out, key=lambda p: (p.line, p.col))


def _allowed_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str]:
    """Field names (aliases) of the model found at ``loc`` inside ``model``."""

    current: Any = model
    for part in loc:
        if isinstance(part, int):
            continue
        fields = getattr(current, "model_fields", None)
        if fields is None:
            return []
        name = {"for": "for_", "in": "in_", "as": "as_"}.get(part, part)
        if name in fields:
            current = _inner_model(fields[name].annotation)
        else:  # dict[str, Model] value
            continue
        if current is None:
            return []
    fields = getattr(current, "model_fields", None)
    if not fields:
        return []
    return [f.alias or n for n, f in fields.items()]


def _inner_model(annotation: Any) -> Any:
    import typing

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        m = _inner_model(arg)
        if m is not None:
            return m
    if isinstance(annotation, str):
        return {"State": State}.get(annotation)
    return None


# ---------------------------------------------------------------------------------------------
# semantic compile


def profile_kind(model: type[BaseModel], slot: str) -> str:
    """The ``profiles:`` section a slot's profile comes from (the model's ``kind``, else the slot)."""
    return getattr(model, "kind", None) or slot


class _Compiler:
    def __init__(self, data: dict[str, Any], spec: Mission, smap: SourceMap) -> None:
        self.data, self.spec, self.smap = data, spec, smap
        self.problems: list[Problem] = []
        self.states: dict[str, StateNode] = {}
        self.transitions: list[CompiledTransition] = []

    def err(self, path: YPath, message: str, hint: str = "") -> None:
        self.problems.append(self.smap.problem(path, message, hint))

    def fail_if_problems(self) -> None:
        if self.problems:
            raise MissionError(_dedupe(self.problems))

    # -- components -------------------------------------------------------------------------
    def _component(self, key: str, registry: Any) -> tuple[type | None, dict[str, Any], YPath]:
        ref = getattr(self.spec, key)
        name, params, ppath = (ref, {}, (key,)) if isinstance(ref, str) else (ref.name, ref.params, (key, "params"))
        npath = (key,) if isinstance(ref, str) else (key, "name")
        try:
            return registry.get(name), params, ppath
        except UnknownName as exc:
            self.err(npath, f"unknown {exc.kind} {name!r}", describe_choices(name, exc.valid))
        except RegistryError as exc:
            self.err(npath, str(exc))
        return None, params, ppath

    def _validate_model(self, model: type[BaseModel], values: Any, path: YPath) -> BaseModel | None:
        try:
            return model.model_validate(with_model_defaults(model, values))
        except ValidationError as exc:
            self.problems.extend(_pydantic_problems(exc, self.smap, path, model))
        except (TypeError, ValueError) as exc:
            self.err(path, str(exc))
        return None

    def compile(self) -> CompiledMission:
        robot_cls, robot_params_raw, rpath = self._component("robot", ROBOTS)
        world_cls, world_params_raw, wpath = self._component("world", WORLDS)
        robot_params = None
        if robot_cls is not None:
            robot_params = self._validate_model(robot_cls.Params, robot_params_raw, rpath)
        if world_cls is not None:
            if robot_cls is not None and world_cls.robots and robot_cls.name not in world_cls.robots:
                self.err(("world",), f"world {world_cls.name!r} cannot host robot {robot_cls.name!r}",
                         f"robots it accepts: {', '.join(world_cls.robots)}")
            try:
                drawn = sample(world_params_raw, world_rng(self.spec.seed))
                wparams = self._validate_model(world_cls.Params, drawn, wpath)
            except DistributionError as exc:
                self.err(wpath + exc.path, str(exc))
            else:
                if wparams is not None:
                    self._check_rates(world_cls, wparams, wpath)
                    self._check_support(world_cls, world_params_raw, drawn, wpath)
        self.fail_if_problems()
        assert robot_cls is not None and world_cls is not None and robot_params is not None
        self.robot_cls, self.world_cls = robot_cls, world_cls

        root = StateNode("", "", None, ("machine",))
        self._build(root, self.spec.machine, ("machine",))
        self.fail_if_problems()
        metric_units, events = self._catalogue(root)
        self._bind_profiles(root)
        self._check_task_params(root)
        self._compile_transitions(root, metric_units, events)
        self.fail_if_problems()
        self._check_structure(root)
        self.fail_if_problems()
        return CompiledMission(
            file=self.smap.file, raw=self.data, spec=self.spec, root=root, states=self.states,
            transitions=self.transitions, robot_cls=robot_cls, robot_params=robot_params,
            world_cls=world_cls, world_params_raw=world_params_raw, metric_units=metric_units, events=events)

    def _check_support(self, world_cls: type[World], raw: dict[str, Any], drawn: dict[str, Any], wpath: YPath) -> None:
        """Every value a distribution can draw must be a valid parameter, not just the default seed's draw."""
        model = world_cls.Params
        for path, spec in distributions_in(raw):
            for value, what in support(spec):
                try:
                    model.model_validate(with_model_defaults(model, replaced(drawn, path, value)))
                except ValidationError as exc:
                    msg = exc.errors()[0]["msg"].removeprefix("Value error, ")
                    self.err(wpath + path, f"{what} is not a valid value here ({msg}): some seeds would draw it",
                             "keep the distribution inside the parameter's valid range")
                    break
                except (TypeError, ValueError) as exc:
                    self.err(wpath + path, f"{what} is not a valid value here ({exc}): some seeds would draw it",
                             "keep the distribution inside the parameter's valid range")
                    break

    def _check_rates(self, world_cls: type[World], wparams: BaseModel, wpath: YPath) -> None:
        """The control period must be a whole number of physics steps, so every tick lasts the same."""
        physics = float(getattr(wparams, "physics_hz", world_cls.physics_hz))
        rate = float(self.spec.rate_hz)
        ratio = physics / rate
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            world_raw = self.data.get("world")
            given = isinstance(world_raw, dict) and "physics_hz" in (world_raw.get("params") or {})
            # point at what the author wrote last: the world's physics_hz, unless rate_hz came from a --set
            where = wpath + ("physics_hz",) if given and ("rate_hz",) not in self.smap.overrides else ("rate_hz",)
            divisors = [f"{physics / k:g}" for k in range(1, 41) if abs(physics / k - round(physics / k, 6)) < 1e-9][:8]
            self.err(where, f"control rate_hz {rate:g} Hz does not divide the physics rate {physics:g} Hz of world "
                     f"{world_cls.name!r} ({ratio:.4g} physics steps per tick): ticks would last unequal times",
                     f"rate_hz values that divide {physics:g} Hz: {', '.join(divisors)}")

    # -- the tree ---------------------------------------------------------------------------
    def _build(self, node: StateNode, spec: State | Machine, ypath: YPath) -> None:
        parent = node.parent
        # task: inherited unless given
        if spec.task is not None:
            tname, tparams = (spec.task, {}) if isinstance(spec.task, str) else (spec.task.name, spec.task.params)
            tpath = ypath + ("task",) if isinstance(spec.task, str) else ypath + ("task", "name")
            try:
                cls = TASKS.get(tname)
                if cls.robots and self.robot_cls.name not in cls.robots:
                    self.err(tpath, f"task {tname!r} cannot drive robot {self.robot_cls.name!r}",
                             f"robots it drives: {', '.join(cls.robots)}")
                node.task_cls, node.task_params = cls, dict(tparams)
                node.task_ypath = ypath + ("task",)
            except UnknownName as exc:
                self.err(tpath, f"unknown task {tname!r}", describe_choices(tname, exc.valid))
            except RegistryError as exc:
                self.err(tpath, str(exc))
        elif parent is not None:
            node.task_cls, node.task_params, node.task_ypath = parent.task_cls, parent.task_params, parent.task_ypath
        node.bind = dict(parent.bind) if parent is not None else {}
        for slot, ref in spec.bind.items():
            node.bind[slot] = ("", ref, ypath + ("bind", slot))
        if isinstance(spec, State):
            node.history = spec.history
            node.final = "succeeded" if spec.final is True else (spec.final or None)
            if spec.foreach is not None:
                node.foreach = (spec.foreach.in_, spec.foreach.as_, spec.foreach.on_failure)
            if spec.action is not None:
                node.action = (spec.action.name, dict(spec.action.params))
            if spec.final and (spec.states or spec.task or spec.transitions or spec.action):
                self.err(ypath + ("final",), "a final state ends its machine: it has no task, action, sub-states or transitions",
                         "remove them or drop `final`")
            if spec.history and not spec.states:
                self.err(ypath + ("history",), "history only applies to a state with sub-states")
            if spec.foreach is not None and not spec.states:
                self.err(ypath + ("foreach",), "foreach repeats a sub-machine: give the state `states` and `initial`")
        if spec.states:
            if spec.initial is None:
                self.err(ypath, "a state with sub-states needs `initial`", f"one of: {', '.join(spec.states)}")
            elif spec.initial not in spec.states:
                self.err(ypath + ("initial",), f"initial state {spec.initial!r} is not a sub-state",
                         describe_choices(spec.initial, list(spec.states)))
            node.initial = spec.initial
            for name, child_spec in spec.states.items():
                if "." in name or not name.replace("_", "a").replace("-", "a").isalnum():
                    self.err(ypath + ("states", name), f"state name {name!r} must be letters, digits, '_' or '-'")
                    continue
                child = StateNode(name, f"{node.path}.{name}" if node.path else name, node, ypath + ("states", name),
                                  depth=node.depth + 1)
                node.children[name] = child
                self.states[child.path] = child
                self._build(child, child_spec, ypath + ("states", name))
        elif isinstance(spec, State) and spec.initial is not None:
            self.err(ypath + ("initial",), "`initial` given but the state has no sub-states")
        elif isinstance(spec, Machine):
            self.err(ypath + ("states",), "the machine has no states", "declare at least one state and a final one")

    # -- what names exist ---------------------------------------------------------------------
    def _catalogue(self, root: StateNode) -> tuple[dict[str, str], set[str]]:
        units: dict[str, str] = dict(self.world_cls.metrics)
        events: set[str] = set(self.world_cls.events)
        for evs in self.world_cls.actions.values():
            events.update(evs)
        for n in root.walk():
            if n.task_cls is not None:
                units.update(n.task_cls.metrics)
                events.update(n.task_cls.events)
        return units, events

    def _metrics_under(self, node: StateNode) -> dict[str, str]:
        units = dict(self.world_cls.metrics)
        for n in node.walk():
            if n.task_cls is not None:
                units.update(n.task_cls.metrics)
        return units

    # -- profiles -----------------------------------------------------------------------------
    def _bind_profiles(self, root: StateNode) -> None:
        profiles = self.spec.profiles
        # every slot a task uses, with its model
        kinds: dict[str, type[BaseModel]] = {}
        for n in root.walk():
            if n.task_cls is not None:
                for slot, model in n.task_cls.slots.items():
                    kinds.setdefault(profile_kind(model, slot), model)
        for kind, named in profiles.items():
            if kind not in kinds:
                self.err(("profiles", kind), f"no task of this mission uses profiles of kind {kind!r}",
                         describe_choices(kind, list(kinds)))
                continue
            for pname, values in named.items():
                self._validate_model(kinds[kind], values, ("profiles", kind, pname))
        for n in root.walk():
            # a bind must name a slot some task at or below it uses
            used_slots = {s for d in n.walk() if d.task_cls is not None for s in d.task_cls.slots}
            spec_bind = self._spec_of(n).bind
            for slot in spec_bind:
                if slot not in used_slots:
                    self.err(n.ypath + ("bind", slot), f"no task at or below this state has a profile slot {slot!r}",
                             describe_choices(slot, sorted(used_slots)))
            if not n.is_leaf or n.task_cls is None:
                continue
            for slot, model in n.task_cls.slots.items():
                kind = profile_kind(model, slot)
                if slot not in n.bind:
                    try:
                        n.profiles[slot] = model()
                    except ValidationError:
                        self.err(n.ypath, f"task {n.task_cls.name!r} needs a {kind!r} profile in slot {slot!r}",
                                 f"add `bind: {{{slot}: NAME}}` here or on a parent; defined {kind} profiles: "
                                 f"{', '.join(profiles.get(kind, {})) or '(none)'}")
                    continue
                _, ref, where = n.bind[slot]
                if isinstance(ref, dict):
                    m = self._validate_model(model, ref, where)
                else:
                    if ref not in profiles.get(kind, {}):
                        self.err(where, f"unknown {kind} profile {ref!r}", describe_choices(ref, list(profiles.get(kind, {}))))
                        continue
                    try:
                        m = model.model_validate(profiles[kind][ref])
                    except ValidationError:
                        m = None  # reported at the profile itself
                if m is not None:
                    n.profiles[slot] = m

    def _spec_of(self, n: StateNode) -> State | Machine:
        spec: State | Machine = self.spec.machine
        for a in n.ancestors()[1:]:
            spec = spec.states[a.name]
        return spec

    # -- task parameters -------------------------------------------------------------------------
    def _check_task_params(self, root: StateNode) -> None:
        params = self.spec.parameters
        for n in root.walk():
            if n.action is not None:
                name, aparams = n.action
                if name not in self.world_cls.actions:
                    self.err(n.ypath + ("action", "name"), f"world {self.world_cls.name!r} has no action {name!r}",
                             describe_choices(name, list(self.world_cls.actions)))
                scope = {item: (params.get(lst) or [None])[0] if isinstance(params.get(lst), list) else None
                         for item, lst in n.scope_items()}
                try:
                    resolve_refs(aparams, params, scope)
                except UnknownRef as exc:
                    valid = ["$" + k for k in list(params) + list(scope)]
                    self.err(n.ypath + ("action", "params") + exc.path, f"unknown reference ${exc.name}",
                             describe_choices("$" + exc.name, valid))
                else:
                    model = self.world_cls.action_params.get(name)
                    if model is not None:
                        self._validate_every_item(n, model, aparams, n.ypath + ("action", "params"),
                                                  f"action {name!r}")
            spec = self._spec_of(n)
            if isinstance(spec, State) and spec.foreach is not None:
                fe = spec.foreach
                where = n.ypath + ("foreach", "in")
                if fe.in_ not in params:
                    self.err(where, f"unknown list parameter {fe.in_!r}", describe_choices(fe.in_, list(params)))
                elif not isinstance(params[fe.in_], list) or not params[fe.in_]:
                    self.err(where, f"parameter {fe.in_!r} must be a non-empty list to iterate over")
                else:
                    n_items = len(params[fe.in_])
                    n.require, n.require_text = fe.required(n_items), str(fe.require)
                    if n.require > n_items:
                        self.err(n.ypath + ("foreach", "require"), f"require {fe.require!r}: the list {fe.in_!r} has "
                                 f"only {n_items} items", f"require at most {n_items}, or 'all'")
                    if fe.on_failure == "stop" and fe.require != "all":
                        self.err(n.ypath + ("foreach", "require"), f"require {fe.require!r} with on_failure: stop — "
                                 "the first failed item ends the loop, so the rule could never let one fail",
                                 "add `on_failure: continue`, or drop `require`")
                if fe.as_ in params:
                    self.err(n.ypath + ("foreach", "as"), f"{fe.as_!r} would hide the mission parameter of that name",
                             "choose another item name")
            if not n.is_leaf or n.task_cls is None:
                continue
            scope = {item: params.get(lst, [None]) for item, lst in n.scope_items()}
            sample_scope = {k: (v[0] if isinstance(v, list) and v else None) for k, v in scope.items()}
            try:
                resolve_refs(n.task_params, params, sample_scope)
            except UnknownRef as exc:
                valid = ["$" + k for k in list(params) + list(scope)]
                self.err(n.task_ypath + ("params",) + exc.path, f"unknown reference ${exc.name}",
                         describe_choices("$" + exc.name, valid))
                continue
            self._validate_every_item(n, n.task_cls.Params, n.task_params, n.task_ypath + ("params",),
                                      f"task {n.task_cls.name!r}")

    def _validate_every_item(self, n: StateNode, model: type[BaseModel], raw: dict[str, Any], where: YPath,
                             what: str) -> None:
        """Validate ``raw`` (which may hold ``$references``) against ``model`` with the first item of every
        enclosing foreach, then with every other item of each list (the others at their first item)."""
        params = self.spec.parameters
        scope = {item: params.get(lst, [None]) for item, lst in n.scope_items()}
        sample_scope = {k: (v[0] if isinstance(v, list) and v else None) for k, v in scope.items()}
        if self._validate_model(model, resolve_refs(raw, params, sample_scope), where) is None:
            return
        for item, lst in n.scope_items():
            values = params.get(lst)
            for idx, value in enumerate(values if isinstance(values, list) else []):
                if idx == 0:
                    continue
                try:
                    model.model_validate(with_model_defaults(model, resolve_refs(raw, params, {**sample_scope, item: value})))
                except ValidationError as exc:
                    first = exc.errors()[0]
                    loc = ".".join(str(x) for x in _clean_loc(tuple(first["loc"])))
                    self.err(("parameters", lst, idx), f"item {idx} of {lst!r} does not fit {what} "
                             f"(state {n.path!r}): {loc}: {first['msg']}", "make every item the same shape as the first")
                    break

    # -- transitions ---------------------------------------------------------------------------
    def _resolve_target(self, source: StateNode, name: str) -> StateNode | None:
        if "." in name:
            return self.states.get(name)
        scope: StateNode | None = source.parent
        while scope is not None:
            if name in scope.children:
                return scope.children[name]
            scope = scope.parent
        return None

    def _guard_params(self) -> tuple[dict[str, tuple[float, str]], dict[str, str]]:
        """Parameters usable in guards (quantities), and why each other parameter is not."""
        out: dict[str, tuple[float, str]] = {}
        bad: dict[str, str] = {}
        for k, v in self.spec.parameters.items():
            try:
                if isinstance(v, bool) or not isinstance(v, (str, int, float)):
                    raise UnitError(f"it is {type(v).__name__} {v!r}")
                out[k] = parse_quantity(v)
            except UnitError as exc:
                bad[k] = f"${k} is not a quantity like '2 mm' ({exc})"
        return out, bad

    def _compile_transitions(self, root: StateNode, metric_units: dict[str, str], events: set[str]) -> None:
        gparams, not_quantities = self._guard_params()
        for n in root.walk():
            if n.parent is None:
                continue
            spec = self._spec_of(n)
            assert isinstance(spec, State)
            for i, tr in enumerate(spec.transitions):
                tpath = n.ypath + ("transitions", i)
                target = self._resolve_target(n, tr.to)
                if target is None:
                    valid = sorted({c for s in [n.parent, *n.parent.ancestors()] for c in s.children} | set(self.states))
                    self.err(tpath + ("to",), f"unknown target state {tr.to!r}", describe_choices(tr.to, valid))
                    continue
                ct = CompiledTransition(len(self.transitions), n, target, "", "", resume=tr.resume,
                                        blend=tr.blend or 0.0)
                if tr.when is not None:
                    ct.kind, ct.label, ct.dwell = "when", tr.when, tr.for_ or 0.0
                    if ct.dwell:
                        ct.label += f" for {ct.dwell:g} s"
                    ct.predicate = self._compile_guard(n, tr.when, tpath + ("when",), not_quantities, gparams)
                    if ct.predicate is None:
                        continue
                if tr.after is not None:
                    ct.kind, ct.after, ct.label = "after", float(tr.after), f"after {float(tr.after):g} s"
                    ct.since = n
                    if tr.since is not None and tr.since != SINCE_ENTRY:
                        ct.label += f" since {tr.since}"
                        if tr.since == SINCE_FIRST_ENTRY:
                            ct.since_first = True
                        else:
                            since = self._enclosing(n, tr.since)
                            if since is None:
                                valid = [SINCE_ENTRY, SINCE_FIRST_ENTRY] + [a.name for a in n.ancestors()[1:]]
                                self.err(tpath + ("since",), f"since {tr.since!r}: neither 'entry', 'first_entry' nor "
                                         f"a state enclosing {n.path!r}", describe_choices(tr.since, valid))
                                continue
                            ct.since = since
                elif tr.on is not None:
                    cond = ct.label
                    ct.kind, ct.event, ct.label = "on", tr.on, f"on {tr.on}" + (f" when {cond}" if cond else "")
                    if tr.on not in events:
                        self.err(tpath + ("on",), f"unknown event {tr.on!r}: no world, sensor, action or task of this mission emits it",
                                 describe_choices(tr.on, sorted(events)))
                        continue
                elif tr.done not in (None, False):
                    ct.kind, ct.done = "done", tr.done
                    ct.label = "done" if tr.done is True else f"done {tr.done}"
                    if n.is_leaf:
                        self.err(tpath + ("done",), "`done` waits for a sub-machine to finish, but this state has no sub-states",
                                 "use `when`, `after` or `on`")
                        continue
                n.transitions.append(ct)
                self.transitions.append(ct)

    def _compile_guard(self, n: StateNode, text: str, where: YPath, not_quantities: dict[str, str],
                       gparams: dict[str, tuple[float, str]]) -> Predicate | None:
        """Parse, check and compile the guard ``text`` of a transition of ``n`` (None: reported)."""
        try:
            guard = parse_guard(text)
        except GuardSyntaxError as exc:
            self.err(where, f"guard {text!r}: {exc} (at character {exc.offset + 1})", exc.hint)
            return None
        available = self._metrics_under(n)
        bad = False
        for m in sorted(guard.metrics):
            if m not in available:
                bad = True
                self.err(where, f"metric {m!r} is not published in state {n.path!r}", describe_choices(m, list(available)))
        if bad:
            return None
        for c in guard.comparisons():
            if c.param is not None and c.param in not_quantities:
                self.err(where, f"guard {text!r}: {not_quantities[c.param]}", "give the parameter a number with a unit")
        for msg in bind_units(guard, available, gparams, skip=set(not_quantities)):
            self.err(where, f"guard {text!r}: {msg}")
        if any(c.value is None for c in guard.comparisons()):
            return None
        return compile_guard(guard)

    @staticmethod
    def _finishing_outcomes(n: StateNode, finals: list[StateNode]) -> dict[str, str]:
        """The outcomes composite ``n`` can finish with, each with why (for the message)."""
        out: dict[str, str] = {}
        for f in finals:
            out.setdefault(f.final or "succeeded", f"its sub-state {f.name!r} is final: {f.final}")
        if n.foreach and n.foreach[2] == "continue":
            # failed items are recorded and the loop goes on; at its end the `require` rule decides
            failing = [f.name for f in finals if f.final != "succeeded"]
            out = {k: v for k, v in out.items() if k == "succeeded"}
            if failing:
                out["failed"] = (f"when fewer than {n.require_text or 'all'} items succeed: "
                                 f"an item can end in {failing[0]!r}")
        return out

    @staticmethod
    def _enclosing(n: StateNode, name: str) -> StateNode | None:
        """``n`` or the ancestor of ``n`` called ``name`` (a bare name or a dotted path)."""
        for a in n.ancestors()[1:]:
            if name in (a.name, a.path):
                return a
        return None

    # -- structure: reachability, ways out ------------------------------------------------------------
    def _check_structure(self, root: StateNode) -> None:
        # every composite that can finish needs a `done` transition for each outcome it can finish with
        # (the root's finals end the run)
        for n in root.walk():
            finals = [c for c in n.children.values() if c.final]
            dones = [t for t in n.transitions if t.kind == "done"]
            if n.parent is not None and n.children and (finals or n.foreach) and not dones:
                self.err(n.ypath, f"state {n.path!r} can finish (it has final sub-states) but has no `done` transition",
                         "add e.g. `- {to: NEXT, done: true}`")
            elif n.parent is not None and finals:
                handled = {t.done for t in dones}
                for outcome, why in self._finishing_outcomes(n, finals).items():
                    if True not in handled and outcome not in handled:
                        self.err(n.ypath, f"state {n.path!r} can finish {outcome} ({why}) but no `done` transition "
                                 "handles that outcome", f"add `- {{to: NEXT, done: {outcome}}}`, or make one `done: true`")
            if n.children and not finals and dones:
                self.err(n.ypath, f"state {n.path!r} waits for `done` but none of its sub-states is final",
                         "mark the last sub-state `final: succeeded`")
        if not any(c.final for c in root.children.values()):
            self.err(("machine",), "the machine has no final state, so a run can only end by timeout",
                     "add e.g. `done: {final: succeeded}`")
        # reachability
        reached: set[str] = set()
        frontier: list[StateNode] = []

        def enter(target: StateNode) -> None:
            chain = target.ancestors()[1:]
            n = target
            while n.children:
                n = n.children[n.initial]  # type: ignore[index]
                chain.append(n)
            for s in chain:
                if s.path not in reached:
                    reached.add(s.path)
                    frontier.append(s)

        enter(root.children[root.initial])  # type: ignore[index]
        while frontier:
            s = frontier.pop()
            for t in s.transitions:
                enter(t.target)
            if s.final and s.parent is not None and s.parent.foreach:
                enter(s.parent)
        for path, n in self.states.items():
            if path not in reached:
                self.err(n.ypath, f"state {path!r} is unreachable: no transition leads to it",
                         "add a transition to it, or remove it")
        # ways out: a non-final leaf with no transition on itself or any ancestor
        for n in self.states.values():
            if n.is_leaf and not n.final and not any(t.kind != "done" for a in n.ancestors() for t in a.transitions):
                self.err(n.ypath, f"state {n.path!r} has no way out: neither it nor a parent has a transition that can fire while it is active",
                         "add a transition, or mark it `final`")


class UnknownRef(KeyError):
    """A ``$name`` that is neither a foreach item in scope nor a mission parameter."""

    def __init__(self, name: str, path: YPath) -> None:
        super().__init__(name)
        self.name, self.path = name, path


def resolve_refs(value: Any, params: dict[str, Any], items: dict[str, Any], path: YPath = ()) -> Any:
    """Replace every ``"$name"`` string by the foreach item or mission parameter of that name."""
    if isinstance(value, str) and value.startswith("$") and value[1:].isidentifier():
        key = value[1:]
        if key in items:
            return items[key]
        if key in params:
            return params[key]
        raise UnknownRef(key, path)
    if isinstance(value, dict):
        return {k: resolve_refs(v, params, items, path + (k,)) for k, v in value.items()}
    if isinstance(value, list):
        return [resolve_refs(v, params, items, path + (i,)) for i, v in enumerate(value)]
    return value

