"""The compiled mission: the state tree, its transitions as typed records, and the references
(``$name``) its parameters hold.  The compiler (:mod:`taskflow.mission.compile`) builds it; the engine
(:mod:`taskflow.execution.executor`) runs it and never calls back into the compiler.

A transition is one of four record types — :class:`GuardTransition` (``when``),
:class:`TimeoutTransition` (``after``), :class:`EventTransition` (``on``, with an optional ``when``
condition) and :class:`DoneTransition` (``done``) — each carrying only the fields its trigger needs.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from pydantic import BaseModel

from taskflow.api import Robot, Task, World
from taskflow.mission.data import DataCatalogue, json_value
from taskflow.mission.distributions import sample, world_rng
from taskflow.mission.guards import DATA_PREFIX, Guard, Predicate
from taskflow.mission.properties import Property
from taskflow.mission.schema import Mission

YPath = tuple[Any, ...]
"""A path into the mission document (keys and list indices), as the source map records them."""


@dataclass(eq=False, kw_only=True)
class Transition:
    """What every transition has: where it is declared, where it leads, and how it enters the target."""

    index: int  # position among the mission's transitions (dwell timers are keyed by it)
    source: StateNode
    target: StateNode
    label: str  # the trigger as written, for records and diagrams
    resume: bool = True  # re-enter a history target where it was left
    blend: float = 0.0  # seconds of command blending after it fires

    @cached_property
    def domain(self) -> StateNode:
        """The state whose descendants this transition exits and enters (UML external semantics): the
        deepest common ancestor of source and target, or its parent when one of them contains the other
        (so that one is left and re-entered)."""
        pa, pb = self.source.ancestors(), self.target.ancestors()
        common = pa[0]
        for x, y in zip(pa, pb):
            if x is not y:
                break
            common = x
        if (common is self.source or common is self.target) and common.parent is not None:
            return common.parent
        return common

    @cached_property
    def domain_depth(self) -> int:
        """Depth of :attr:`domain` (0: the root): how many levels of the new leaf's path stay active."""
        return self.domain.depth


@dataclass(eq=False, kw_only=True)
class GuardTransition(Transition):
    """``when: EXPR`` (``for: T``): the guard holds, for ``dwell`` seconds without a break."""

    guard: Guard
    predicate: Predicate
    dwell: float = 0.0


@dataclass(eq=False, kw_only=True)
class TimeoutTransition(Transition):
    """``after: T`` (``since: …``): ``after`` seconds since ``since`` was (first, with ``since_first``) entered."""

    after: float
    since: StateNode
    since_first: bool = False


@dataclass(eq=False, kw_only=True)
class EventTransition(Transition):
    """``on: EVENT`` (``when: EXPR``): the event was emitted this tick, and the condition (if any) holds."""

    event: str
    guard: Guard | None = None
    predicate: Predicate | None = None


@dataclass(eq=False, kw_only=True)
class DoneTransition(Transition):
    """``done: true | OUTCOME``: the source's sub-machine finished (with ``outcome``; None: any)."""

    outcome: str | None = None

    def handles(self, outcome: str) -> bool:
        return self.outcome is None or self.outcome == outcome


@dataclass(frozen=True)
class Loop:
    """A ``foreach``: the list parameter it iterates, the item's name, what a failed item does, its
    success rule resolved against the list (``required`` items must succeed; ``rule`` as written), and how
    often an item that failed is run again (``retries``, for the final states ``retry_on``)."""

    items: str
    item: str
    on_failure: str  # "stop" | "continue"
    required: int = 0
    rule: str = "all"
    retries: int = 0  # further attempts of an item that ends in one of ``retry_on`` (``retry``)
    retry_on: tuple[str, ...] = ()  # the names of the sub-machine's final states worth retrying

    def retries_after(self, final: StateNode, attempt: int) -> bool:
        """Whether an item whose ``attempt``-th attempt (1: the first) ended in the final state ``final`` runs again."""
        return attempt <= self.retries and final.name in self.retry_on


@dataclass(eq=False)
class StateNode:
    """One state of the compiled machine."""

    name: str
    path: str  # dotted from the root; "" for the root
    parent: StateNode | None
    ypath: YPath
    children: dict[str, StateNode] = field(default_factory=dict)
    initial: str | None = None
    task_cls: type[Task[Any, Any]] | None = None  # effective (inherited)
    task_params: dict[str, Any] = field(default_factory=dict)  # raw, may hold $refs
    task_ypath: YPath = ()
    bind: dict[str, tuple[str, Any, YPath]] = field(default_factory=dict)  # slot → (kind, name|inline, where)
    profiles: dict[str, BaseModel] = field(default_factory=dict)  # resolved for a leaf
    transitions: list[Transition] = field(default_factory=list)
    history: bool = False
    loop: Loop | None = None  # foreach
    action: tuple[str, dict[str, Any]] | None = None
    final: str | None = None  # outcome
    depth: int = 0
    parallel: bool = False  # its children are regions, all active together
    outcome_map: tuple[tuple[str, dict[str, str]], ...] = ()  # parallel: (outcome, {region: outcome}) in order
    owns: tuple[str, ...] | None = None  # a region: the command parts it drives (None: not a region)
    use: str | None = None  # the sub-mission file its sub-machine came from, as written (`use:`)

    @property
    def is_leaf(self) -> bool:
        return not self.children

    def ancestors(self) -> list[StateNode]:
        """Root first, self last."""
        out: list[StateNode] = []
        n: StateNode | None = self
        while n is not None:
            out.append(n)
            n = n.parent
        return out[::-1]

    def walk(self) -> Iterator[StateNode]:
        yield self
        for c in self.children.values():
            yield from c.walk()

    def initial_leaf(self) -> StateNode:
        """The leaf entering this state leads to (for a parallel state: the first region's)."""
        n = self
        while n.children:
            n = n.children[n.initial] if n.initial is not None else next(iter(n.children.values()))
        return n

    def initial_child(self) -> StateNode:
        """The child a composite (not parallel) state enters first."""
        assert self.initial is not None, f"{self.path}: a composite state has an initial child"
        return self.children[self.initial]

    def entry_point(self) -> StateNode:
        """What entering this state makes active: its initial leaf, or the first parallel state on the
        way there (entering that enters every region's initial chain)."""
        n = self
        while n.children and not n.parallel:
            n = n.initial_child()
        return n

    def entry_leaves(self) -> list[StateNode]:
        """Every leaf that entering this state makes active (one per region below a parallel state)."""
        if not self.children:
            return [self]
        if self.parallel:
            return [leaf for r in self.children.values() for leaf in r.entry_leaves()]
        return self.initial_child().entry_leaves()

    @property
    def region(self) -> StateNode | None:
        """The innermost parallel region this state is in (None: outside any)."""
        n: StateNode | None = self
        while n is not None and n.owns is None:
            n = n.parent
        return n

    def scope_items(self) -> list[tuple[str, str]]:
        """(item name, list parameter) of every enclosing foreach, outermost first."""
        return [(a.loop.item, a.loop.items) for a in self.ancestors() if a.loop]


@dataclass
class CompiledMission:
    """A validated mission: the raw document, its shape, and the compiled machine."""

    file: str
    raw: dict[str, Any]
    spec: Mission
    root: StateNode
    states: dict[str, StateNode]  # path → node (root excluded)
    transitions: list[Transition]
    robot_cls: type[Robot]
    robot_params: BaseModel
    world_cls: type[World]
    world_params_raw: dict[str, Any]
    metric_units: dict[str, str]  # every metric any task or the world publishes
    events: set[str]
    data: DataCatalogue = field(default_factory=DataCatalogue)  # the mission data its tasks declare
    properties: list[Property] = field(default_factory=list)  # its declared properties (taskflow.mission.properties)

    @property
    def name(self) -> str:
        return self.spec.mission

    def world_params(self, seed: int) -> BaseModel:
        """World parameters with every distribution drawn from ``seed``."""
        drawn = sample(self.world_params_raw, world_rng(seed))
        return self.world_cls.Params.model_validate(with_model_defaults(self.world_cls.Params, drawn))

    def build_robot(self) -> Robot:
        return self.robot_cls(self.robot_params)

    @property
    def outside_regions(self) -> list[str]:
        """The paths of the states a transition from anywhere may enter: every state but those inside a
        parallel region (a region is entered only with its parallel state) — the operator's pre-emption
        targets."""
        return [p for p, n in self.states.items() if n.region is None]

    def description_of(self, node: StateNode) -> str:
        """The ``description`` written on a state (empty when none)."""
        spec: Any = self.spec.machine
        for a in node.ancestors()[1:]:
            spec = spec.states[a.name] if a.owns is None else spec.regions[a.name]  # a region: its parallel state's
        return getattr(spec, "description", "") or ""

    def leaves(self) -> list[StateNode]:
        return [n for n in self.states.values() if n.is_leaf]


def with_model_defaults(model: type[BaseModel], values: Any) -> Any:
    """``values`` with every partial mapping given for a field whose default is a model completed
    from that default, recursively: ``front_camera: {width: 640}`` (or ``--set
    robot.params.front_camera.width=640``) changes one field of the default camera instead of
    replacing the camera by one with only a width."""
    if not isinstance(values, dict):
        return values
    out = dict(values)
    for name, fld in model.model_fields.items():
        key = fld.alias if fld.alias is not None and fld.alias in out else name
        default = fld.default
        if key in out and isinstance(out[key], dict) and isinstance(default, BaseModel):
            sub = type(default)
            out[key] = {**default.model_dump(by_alias=True), **with_model_defaults(sub, out[key])}
    return out


class UnknownRef(KeyError):
    """A ``$name`` that is neither a foreach item in scope nor a mission parameter."""

    def __init__(self, name: str, path: YPath) -> None:
        super().__init__(name)
        self.name, self.path = name, path


def resolve_refs(value: Any, params: dict[str, Any], items: dict[str, Any], path: YPath = (),
                 data: dict[str, Any] | None = None) -> Any:
    """Replace every ``"$name"`` string by the foreach item or mission parameter of that name, and every
    ``"$data.<key>"`` by the mission data's value of ``key`` in JSON form (``data``: the run's values; None
    where mission data is not available, e.g. action parameters — the reference is then unknown)."""
    if isinstance(value, str) and value.startswith("$"):
        key = value[1:]
        if key.startswith(DATA_PREFIX):
            name = key[len(DATA_PREFIX):]
            if data is None or name not in data:
                raise UnknownRef(key, path)
            return json_value(data[name])
        if not key.isidentifier():
            return value
        if key in items:
            return items[key]
        if key in params:
            return params[key]
        raise UnknownRef(key, path)
    if isinstance(value, dict):
        return {k: resolve_refs(v, params, items, path + (k,), data) for k, v in value.items()}
    if isinstance(value, list):
        return [resolve_refs(v, params, items, path + (i,), data) for i, v in enumerate(value)]
    return value


def data_refs(value: Any, path: YPath = ()) -> Iterator[tuple[str, YPath]]:
    """Every ``$data.<key>`` in ``value``: (key, where below ``value``)."""
    if isinstance(value, str) and value.startswith("$" + DATA_PREFIX):
        yield value[1 + len(DATA_PREFIX):], path
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from data_refs(v, path + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from data_refs(v, path + (i,))


def has_refs(value: Any) -> bool:
    """Whether ``value`` holds a ``$reference`` anywhere (so it must be resolved on every entry)."""
    if isinstance(value, str):
        return value.startswith("$")
    if isinstance(value, dict):
        return any(has_refs(v) for v in value.values())
    if isinstance(value, list):
        return any(has_refs(v) for v in value)
    return False
