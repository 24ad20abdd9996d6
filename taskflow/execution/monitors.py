"""The runtime monitor of a mission's declared properties (:mod:`taskflow.mission.properties`).

Every control tick the run hands the monitor what the tick saw — its sim time, the configuration the tick ran
in (the active leaves before the tick's transition, as ``trace.csv``'s ``state`` column: the configuration
whose tasks produced the tick's metrics), the tick's metrics and events, the run's mission data — and each
property still undecided is evaluated on it (ticks under an operator's hold run no task and are not evaluated):

* absence (``never: A``, ``while: B``) and universality (``always: A``) are violated at the first tick where A
  (and B) holds, or A does not;
* response (``after: A``, ``within: T``, ``then: B``) keeps the earliest time A held without B since B last
  held; it is violated at the first tick later than that time + T (B in the tick A holds, or in a later one at
  most T after, discharges it).  When the run ends with an obligation open, the response is violated if the
  machine reached a final state, ``not_decided`` when the run was cut short (``timeout``, ``aborted``);
* precedence (``only_after: A``, ``occurs: B``) is violated at the first tick B holds before A has held at any
  (A and B in one tick is fine); once A has held it cannot be violated.

When the run ends, every property still open is evaluated once more on the final configuration (the final
state the last tick entered), the last tick's metrics, no event, and the outcome: ``outcome(NAME)`` holds only
then, and ``never: state(failed_state)`` sees the final state.

The first violation of each property is a :class:`~taskflow.execution.records.PropertyRecord` in
``transitions.jsonl`` (with the values its atoms had); :meth:`PropertyMonitor.verdicts` is ``summary.json``'s
``properties``.  A mission without properties has no monitor (the run loop checks one ``None``).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from typing import Any

from taskflow.execution.records import PropertyRecord
from taskflow.mission.guards import DATA_PREFIX, Atom, Predicate, compile_guard
from taskflow.mission.model import StateNode
from taskflow.mission.properties import Property

EPS = 1e-9  # seconds: a deadline met within this of the tick's time is met
HELD, VIOLATED, NOT_DECIDED = "held", "violated", "not_decided"
VERDICTS = (HELD, VIOLATED, NOT_DECIDED)
CUT_SHORT = ("timeout", "aborted")
"""Outcomes of a run that ended before its machine did: an open response is then not decided."""


class _Facts:
    """What the atoms read this tick: the active states (leaves and their ancestors), the events, the outcome."""

    __slots__ = ("active", "events", "outcome")

    def __init__(self) -> None:
        self.active: frozenset[str] = frozenset()
        self.events: Collection[str] = ()
        self.outcome: str | None = None


class _Check:
    """One property being monitored: its compiled expressions and what it has seen so far."""

    def __init__(self, prop: Property, facts: _Facts) -> None:
        self.prop = prop
        self.verdict = HELD
        self.t: float | None = None
        self.reason = ""
        self.pending: float | None = None  # response: the earliest time A held without B since B last held
        self.preceded = False  # precedence: A has held

        def atom(a: Atom) -> Predicate:
            if a.kind == "state":
                path = prop.states.get(a.name, a.name)
                return lambda m, d: path in facts.active
            if a.kind == "event":
                name = a.name
                return lambda m, d: name in facts.events
            outcome = a.name
            return lambda m, d: facts.outcome == outcome

        self.pred = {role: compile_guard(g, atom) for role, g in prop.exprs.items()}

    def step(self, t: float, m: Mapping[str, float], d: Mapping[str, Any]) -> bool:
        """Evaluate on one tick; True when this tick violated the property (first time)."""
        p, pred = self.prop.pattern, self.pred
        if p == "absence":
            cond = pred.get("while")
            return pred["never"](m, d) and (cond is None or cond(m, d)) and self._violate(t)
        if p == "universality":
            return not pred["always"](m, d) and self._violate(t)
        if p == "response":
            within = self.prop.within or 0.0
            if self.pending is not None and t > self.pending + within + EPS:
                return self._violate(t, f"'then' did not hold within {within:g} s of 'after' at t = {self.pending:g} s")
            if pred["then"](m, d):
                self.pending = None
            elif self.pending is None and pred["after"](m, d):
                self.pending = t
            return False
        # precedence
        if pred["only_after"](m, d):
            self.preceded = True
            return False
        return pred["occurs"](m, d) and self._violate(t, "'occurs' held before 'only_after' ever had")

    def _violate(self, t: float, reason: str = "") -> bool:
        self.verdict, self.t, self.reason = VIOLATED, t, reason
        return True

    @property
    def open(self) -> bool:
        """Whether a later tick could still change its verdict."""
        return self.verdict == HELD and not self.preceded

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"pattern": self.prop.pattern, "verdict": self.verdict,
                               "t": None if self.t is None else round(self.t, 9)}
        if self.reason:
            out["reason"] = self.reason
        return out


class PropertyMonitor:
    """Evaluates a mission's properties every tick (:meth:`tick`) and once at the end (:meth:`finish`);
    ``on_record`` receives each first violation's record object (``transitions.jsonl``)."""

    def __init__(self, properties: list[Property], states: Mapping[str, StateNode],
                 on_record: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.facts = _Facts()
        self.checks = [_Check(p, self.facts) for p in properties]
        self._open = list(self.checks)
        self._ancestors = {path: tuple(a.path for a in n.ancestors()[1:]) for path, n in states.items()}
        self._configs: dict[str, frozenset[str]] = {}
        self._state: str | None = None
        self.on_record = on_record
        self.records: list[PropertyRecord] = []
        self._last: tuple[float, str, Mapping[str, float], Mapping[str, Any]] | None = None

    def _configure(self, state: str) -> None:
        active = self._configs.get(state)
        if active is None:
            active = self._configs[state] = frozenset(
                p for leaf in state.split("|") for p in self._ancestors.get(leaf, ()))
        self.facts.active = active
        self._state = state

    def tick(self, t: float, state: str, metrics: Mapping[str, float], events: Collection[str],
             data: Mapping[str, Any]) -> None:
        """One control tick: ``state`` is the configuration it ran in (leaves joined by ``|``)."""
        if state != self._state:
            self._configure(state)
        self.facts.events = events
        self._last = (t, state, metrics, data)
        closed = False
        for chk in self._open:
            if chk.step(t, metrics, data):
                self._record(chk, t, state, metrics, data)
            if not chk.open:
                closed = True
        if closed:
            self._open = [c for c in self._open if c.open]

    def finish(self, t: float, state: str, outcome: str) -> None:
        """The run ended at ``t`` in ``state`` with ``outcome``: every open property sees the final configuration
        and the outcome once, and an open response is settled (violated after a final state, not decided when cut
        short)."""
        metrics, data = (self._last[2], self._last[3]) if self._last is not None else ({}, {})
        self._configure(state)
        self.facts.events, self.facts.outcome = (), outcome
        for chk in self._open:
            if chk.step(t, metrics, data):
                self._record(chk, t, state, metrics, data)
            elif chk.verdict == HELD and chk.pending is not None:
                if outcome in CUT_SHORT:
                    chk.verdict, chk.reason = NOT_DECIDED, (f"the run ended ({outcome}) before 'then' held for 'after' "
                                                            f"at t = {chk.pending:g} s, within its deadline")
                elif chk._violate(t, f"the run ended ({outcome}) before 'then' held for 'after' at "
                                     f"t = {chk.pending:g} s"):
                    self._record(chk, t, state, metrics, data)
        self._open = []

    def _record(self, chk: _Check, t: float, state: str, metrics: Mapping[str, float],
                data: Mapping[str, Any]) -> None:
        rec = PropertyRecord(t=t, property=chk.prop.name, pattern=chk.prop.pattern, state=state,
                             atoms=self._values(chk.prop, metrics, data), reason=chk.reason)
        self.records.append(rec)
        if self.on_record is not None:
            self.on_record(rec.as_dict())

    def _values(self, prop: Property, metrics: Mapping[str, float], data: Mapping[str, Any]) -> dict[str, Any]:
        """Each atom's value when it was violated: states, events and outcomes true/false, metrics their number
        (None when not published that tick)."""
        out: dict[str, Any] = {}
        f = self.facts
        for a in prop.atoms():
            if a.kind == "state":
                out[f"state({a.name})"] = a.name in f.active
            elif a.kind == "event":
                out[a.text] = a.name in f.events
            elif a.kind == "outcome":
                out[a.text] = f.outcome == a.name
            elif a.name.startswith(DATA_PREFIX):
                key = a.name[len(DATA_PREFIX):].split("[")[0]
                v = data.get(key)
                out[a.name] = v if isinstance(v, (int, float, bool, str)) or v is None else str(v)
            else:
                v = metrics.get(a.name)
                out[a.name] = None if v is None else float(v)
        return out

    def verdicts(self) -> dict[str, dict[str, Any]]:
        """``summary.json``'s ``properties``: name → ``pattern``, ``verdict`` (held, violated, not_decided), ``t`` of
        the first violation (None), and ``reason`` when there is one."""
        return {c.prop.name: c.as_dict() for c in self.checks}


def monitor_for(properties: list[Property], states: Mapping[str, StateNode],
                on_record: Callable[[dict[str, Any]], None] | None = None) -> PropertyMonitor | None:
    """A monitor for ``properties``, or None when the mission declares none (nothing runs per tick)."""
    return PropertyMonitor(properties, states, on_record) if properties else None
