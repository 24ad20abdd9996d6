"""A mission's declared properties (``properties:``), compiled once when it loads.

Each property is one specification pattern (Dwyer et al., "Patterns in property specifications for
finite-state verification", ICSE 1999) over the run's ticks:

* **absence** — ``never: A`` (``while: B``): A never holds (in a tick where B holds);
* **universality** — ``always: A``: A holds at every tick;
* **response** — ``after: A``, ``within: T``, ``then: B``: whenever A holds at ``t``, B holds at some tick
  ``t'`` with ``t <= t' <= t + T`` (B in the same tick counts);
* **precedence** — ``only_after: A``, ``occurs: B``: B holds at no tick before A has held at one.

A and B are expressions of the guard grammar (:mod:`taskflow.mission.guards`, parsed with ``atoms=True``):
metric comparisons with units, as in guards, and the atoms ``state(PATH)``, ``event(NAME)``,
``outcome(NAME)``.  They are checked here as guards are (unknown states with "did you mean", events the
mission's world, sensors, tasks and actions declare or its ``events:`` list, published metrics, units,
``within`` a time with its unit), every problem at the property's ``FILE:LINE:COL``.  The runtime monitor
(:mod:`taskflow.execution.monitors`) evaluates them every tick; the model checker reads their atoms.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from taskflow.mission.guards import DATA_PREFIX, Atom, Guard, GuardSyntaxError, bind_units, parse_guard
from taskflow.mission.schema import OUTCOMES, PROPERTY_PATTERNS
from taskflow.mission.schema import Property as PropertySpec
from taskflow.registry import describe_choices
from taskflow.units import UnitError, parse_quantity


class _Named(Protocol):
    """What resolving ``state(NAME)`` needs of a state (:class:`taskflow.mission.model.StateNode`)."""

    name: str


Report = Callable[[tuple[Any, ...], str, str], None]
"""``report(where, message, hint)``: a problem at a path of the mission document (the compiler's ``err``)."""

RUN_OUTCOMES = (*OUTCOMES, "timeout")
"""What ``outcome(NAME)`` may name: a final state's outcome, or ``timeout`` (``max_time`` reached)."""

ROLES: dict[str, tuple[str, ...]] = {"absence": ("never", "while"), "universality": ("always",),
                                     "response": ("after", "then"), "precedence": ("only_after", "occurs")}
"""Each pattern's expressions, by the key that holds them (``while`` is optional)."""
assert set(ROLES) == set(PROPERTY_PATTERNS)


@dataclass(frozen=True)
class PropertyAtom:
    """One atom of a property: ``kind`` is ``state``, ``event``, ``outcome`` or ``metric``; ``name`` the
    state path (resolved), event, outcome or metric name (``data.KEY`` for mission data); ``text`` as written."""

    kind: str
    name: str
    text: str


@dataclass(eq=False)
class Property:
    """A compiled property: its name, pattern, expressions (by role: ``never``/``while``, ``always``,
    ``after``/``then``, ``only_after``/``occurs``; their units bound and state paths resolved), the response's
    deadline ``within`` in seconds, its description and where it is declared."""

    name: str
    pattern: str  # one of ROLES
    exprs: dict[str, Guard]
    within: float | None = None
    description: str = ""
    ypath: tuple[Any, ...] = ()
    states: dict[str, str] = field(default_factory=dict)  # state(NAME) as written → resolved path

    def atoms(self) -> list[PropertyAtom]:
        """Every atom of its expressions, once each, in the order written."""
        out: list[PropertyAtom] = []
        for g in self.exprs.values():
            for a in g.atoms():
                name = self.states.get(a.name, a.name) if a.kind == "state" else a.name
                out.append(PropertyAtom(a.kind, name, a.text))
            for c in g.comparisons():
                text = f"abs({c.metric})" if c.absolute else c.metric
                out.append(PropertyAtom("metric", c.metric, text))
        return list(dict.fromkeys(out))  # once each (PropertyAtom is frozen: hashable)

    @property
    def structural(self) -> bool:
        """Whether it reads only states, events and outcomes (no metric): a model of the machine decides it."""
        return all(a.kind != "metric" for a in self.atoms())

    def expression(self, role: str) -> Guard | None:
        return self.exprs.get(role)


def resolve_state(states: Mapping[str, _Named], name: str) -> tuple[str | None, str]:
    """``state(NAME)``'s path: ``NAME`` itself when it is a dotted path of the machine, else the one state
    called ``NAME``; (None, why) when there is none or more than one."""
    if name in states:
        return name, ""
    named = sorted(p for p, n in states.items() if n.name == name)
    if len(named) == 1:
        return named[0], ""
    if named:
        return None, f"state({name}) is ambiguous: {', '.join(named)} — write the dotted path"
    return None, f"unknown state {name!r} — {describe_choices(name, sorted(states))}"


@dataclass
class Scope:
    """What a property may name: the machine's states, the events the mission can see, the metrics its tasks and
    world publish (name → unit), the mission data a guard can read (``data.KEY`` → unit), the parameters usable as
    quantities (name → (base value, dimension)) and why each other parameter is not."""

    states: Mapping[str, _Named]
    events: set[str]
    metric_units: Mapping[str, str]
    readable: Mapping[str, str]
    quantities: Mapping[str, tuple[float, str]]
    not_quantities: Mapping[str, str]


def compile_properties(specs: Mapping[str, PropertySpec], scope: Scope, report: Report) -> list[Property]:
    """Every property of the mission, checked (each problem given to ``report``) and compiled; a property with a
    problem is left out (the compiler then refuses the mission)."""
    out: list[Property] = []
    for name, spec in specs.items():
        prop = _compile_one(name, spec, scope, report)
        if prop is not None:
            out.append(prop)
    return out


def _compile_one(name: str, spec: PropertySpec, scope: Scope, report: Report) -> Property | None:
    units: dict[str, str] = {**scope.metric_units, **scope.readable}
    not_quantities = dict(scope.not_quantities)
    where = ("properties", name)
    pattern = spec.pattern
    exprs: dict[str, Guard] = {}
    resolved: dict[str, str] = {}
    ok = True
    for role in ROLES[pattern]:
        text = getattr(spec, "while_" if role == "while" else role)
        if text is None:
            continue
        at = where + (role,)
        try:
            g = parse_guard(text, atoms=True)
        except GuardSyntaxError as exc:
            report(at, f"property {name!r}: {role} {text!r}: {exc} (at character {exc.offset + 1})", exc.hint)
            ok = False
            continue
        ok = _check_atoms(scope, report, name, role, text, g.atoms(), at, resolved) and ok
        for m in sorted({cmp.metric for cmp in g.comparisons()}):
            if m in units:
                continue
            ok = False
            if m.startswith(DATA_PREFIX):
                report(at, f"property {name!r}: {m!r} is not mission data a property can read",
                       describe_choices(m, sorted(scope.readable)))
            else:
                report(at, f"property {name!r}: metric {m!r} is published by no task or world of this mission",
                       describe_choices(m, sorted(scope.metric_units)) + "; `taskflow describe TASK` lists a "
                       "task's metrics")
        if not ok:
            continue
        for cmp in g.comparisons():
            if cmp.param is not None and cmp.param in not_quantities:
                report(at, f"property {name!r}: {not_quantities[cmp.param]}", "give the parameter a number with a unit")
                ok = False
        for msg in bind_units(g, units, scope.quantities, skip=set(not_quantities)):
            report(at, f"property {name!r}: {role} {text!r}: {msg}", "")
            ok = False
        exprs[role] = g
    within = None
    if pattern == "response":
        within = _within(report, name, spec.within, where + ("within",))
        ok = ok and within is not None
    return Property(name, pattern, exprs, within, spec.description, where, resolved) if ok else None


def _check_atoms(scope: Scope, report: Report, name: str, role: str, text: str, atoms: list[Atom], at: tuple[Any, ...],
                 resolved: dict[str, str]) -> bool:
    ok = True
    for a in atoms:
        head = f"property {name!r}: {role} {text!r}"
        if a.kind == "state":
            path, why = resolve_state(scope.states, a.name)
            if path is None:
                msg, _, hint = why.partition(" — ")
                report(at, f"{head}: {msg}", hint)
                ok = False
            else:
                resolved[a.name] = path
        elif a.kind == "event" and a.name not in scope.events:
            report(at, f"{head}: unknown event {a.name!r}: no world, sensor, action or task of this mission emits it, "
                  "nor does its `events:` list declare it",
                   f"{describe_choices(a.name, sorted(scope.events))}; `taskflow describe NAME` lists a world's or task's events")
            ok = False
        elif a.kind == "outcome" and a.name not in RUN_OUTCOMES:
            report(at, f"{head}: unknown outcome {a.name!r}", describe_choices(a.name, list(RUN_OUTCOMES)))
            ok = False
    return ok


def _within(report: Report, name: str, value: str | float | int | None, at: tuple[Any, ...]) -> float | None:
    """The response's deadline in seconds: a time with its unit (a bare number is refused: 0.05 of what?)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        report(at, f"property {name!r}: within {value!r} needs a time unit", f"write e.g. '{value:g} s' or '{value:g} ms'")
        return None
    try:
        seconds, dim = parse_quantity(str(value), "time")
    except UnitError as exc:
        report(at, f"property {name!r}: within: {exc}", "write a time such as '0.05 s' or '50 ms'")
        return None
    if seconds < 0 or seconds != seconds or seconds == float("inf"):
        report(at, f"property {name!r}: within {value!r}: a deadline is a finite time ≥ 0", "write e.g. '0.05 s'")
        return None
    return seconds
