"""What each kind of transition checks in a tick: the compiled records armed for one run.

The compiled mission's transitions (:mod:`taskflow.mission.model`) are data, shared by every run of the
mission and read by the view, the record readers and the compiler's passes.  A run arms each of them once
(:func:`arm`) as a :class:`Trigger` of its kind, which holds what the check needs at hand (the predicate,
the mission data, the engine state whose clock a timeout reads) and the run-time state a kind has (a
dwell guard's start).  The tick then asks every trigger of the active leaf's table ``ready(...)`` — one
method call, no dispatch on the kind — and the one that fires names its record's cause and fields.

* ``when: EXPR`` — :class:`GuardTrigger`; with ``for: T``, :class:`DwellTrigger`: the guard has held
  without a break for ``T`` of operating time (sim time not under operator hold);
* ``on: EVENT`` — :class:`EventTrigger`; with a ``when`` condition, :class:`ConditionalEventTrigger`;
* ``after: T`` — :class:`TimeoutTrigger`: ``T`` of operating time since its ``since`` state was entered
  (first entered, with ``since: first_entry``);
* ``done`` transitions have no trigger: they fire when their sub-machine finishes (:mod:`.statechart`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Any, ClassVar

from taskflow.execution.engine import MissionState
from taskflow.execution.records import EVENT, GUARD, TIMEOUT
from taskflow.mission import model
from taskflow.mission.guards import Guard, Predicate
from taskflow.mission.model import StateNode, Transition

__all__ = ["ConditionalEventTrigger", "DwellTrigger", "EventTrigger", "GuardTrigger", "TimeoutTrigger", "Trigger",
           "arm"]

Metrics = dict[str, float]
EPS = 1e-9  # seconds: a timeout or dwell due within this of the tick's time is due at it


class Trigger:
    """One transition of a run that a tick checks (its own state's and its ancestors' tables hold it)."""

    __slots__ = ("index", "transition")
    cause: ClassVar[str]  # the record's ``cause`` when it fires (:data:`taskflow.execution.records.CAUSES`)

    def __init__(self, transition: Transition) -> None:
        self.transition = transition
        self.index = transition.index

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        """Whether it fires at sim time ``t`` (``held_s``: the run's time under operator hold so far), given
        this tick's metrics and events."""
        raise NotImplementedError

    def missed(self, metrics: Metrics) -> None:
        """An earlier transition of the same table fired this tick, so this one was not checked: what it
        must still see of this tick's ``metrics`` (only a dwell guard does)."""

    def reset(self) -> None:
        """The state that declares it was entered: its run-time state starts afresh."""

    def why(self, metrics: Metrics | None) -> dict[str, Any]:
        """The fields of its transition record beyond the leaves and the cause (``metrics``: the tick's,
        None when it fires without them)."""
        tr = self.transition
        return {"state": tr.source.path, "label": tr.label, "index": tr.index}


def _guard_values(guard: Guard, metrics: Metrics | None) -> dict[str, Any]:
    """The values a guard read this tick, for the record (a metric not published this tick: None)."""
    return {} if metrics is None else {"metrics": {m: metrics.get(m) for m in sorted(guard.metrics)}}


class GuardTrigger(Trigger):
    """``when: EXPR``: fires in the tick its guard holds."""

    __slots__ = ("guard", "memory", "predicate")
    cause = GUARD

    def __init__(self, transition: model.GuardTransition, memory: dict[str, Any]) -> None:
        super().__init__(transition)
        self.guard: Guard = transition.guard
        self.predicate: Predicate = transition.predicate
        self.memory = memory

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        return self.predicate(metrics, self.memory)

    def why(self, metrics: Metrics | None) -> dict[str, Any]:
        return {**super().why(metrics), **_guard_values(self.guard, metrics)}


class DwellTrigger(GuardTrigger):
    """``when: EXPR`` with ``for: T``: fires once its guard has held for ``T`` of operating time without a
    break (checked every tick its table is, and by :meth:`missed` when an earlier transition fires)."""

    __slots__ = ("dwell", "since")

    def __init__(self, transition: model.GuardTransition, memory: dict[str, Any]) -> None:
        super().__init__(transition, memory)
        self.dwell = transition.dwell
        self.since: float | None = None  # operating-clock time its guard began to hold (None: it does not)

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        if self.predicate(metrics, self.memory):
            op = t - held_s  # the operating clock: time under hold does not count
            since = self.since
            if since is None:
                since = self.since = op
            return not (op - since + EPS < self.dwell)
        self.since = None
        return False

    def missed(self, metrics: Metrics) -> None:
        if self.since is not None and not self.predicate(metrics, self.memory):
            self.since = None

    def reset(self) -> None:
        self.since = None


class EventTrigger(Trigger):
    """``on: EVENT``: fires in the tick the event is emitted."""

    __slots__ = ("event",)
    cause = EVENT

    def __init__(self, transition: model.EventTransition) -> None:
        super().__init__(transition)
        self.event = transition.event

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        return self.event in events

    def why(self, metrics: Metrics | None) -> dict[str, Any]:
        return {**super().why(metrics), "event": self.event}


class ConditionalEventTrigger(EventTrigger):
    """``on: EVENT`` with ``when: EXPR``: fires in the tick the event is emitted and the condition holds."""

    __slots__ = ("guard", "memory", "predicate")

    def __init__(self, transition: model.EventTransition, guard: Guard, predicate: Predicate,
                 memory: dict[str, Any]) -> None:
        super().__init__(transition)
        self.guard, self.predicate, self.memory = guard, predicate, memory

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        return self.event in events and self.predicate(metrics, self.memory)

    def why(self, metrics: Metrics | None) -> dict[str, Any]:
        tr = self.transition
        return {"state": tr.source.path, "label": tr.label, "index": tr.index, **_guard_values(self.guard, metrics),
                "event": self.event}


class TimeoutTrigger(Trigger):
    """``after: T``: fires once ``T`` of operating time has passed since its clock state was entered."""

    __slots__ = ("after", "clock", "first")
    cause = TIMEOUT

    def __init__(self, transition: model.TimeoutTransition, clock: MissionState) -> None:
        super().__init__(transition)
        self.after, self.clock, self.first = transition.after, clock, transition.since_first

    def ready(self, t: float, held_s: float, metrics: Metrics, events: Collection[str]) -> bool:
        return self.clock.operating_time(t, held_s, self.first) + EPS >= self.after


def arm(tr: Transition, memory: dict[str, Any], clock: Callable[[StateNode], MissionState]) -> Trigger:
    """``tr`` armed for a run whose mission data is ``memory``; ``clock`` gives the engine state of a node
    (whose entry times a timeout reads)."""
    match tr:
        case model.GuardTransition():
            return DwellTrigger(tr, memory) if tr.dwell > 0.0 else GuardTrigger(tr, memory)
        case model.EventTransition(guard=Guard() as guard, predicate=pred) if pred is not None:
            return ConditionalEventTrigger(tr, guard, pred, memory)
        case model.EventTransition():
            return EventTrigger(tr)
        case model.TimeoutTransition():
            return TimeoutTrigger(tr, clock(tr.since))
        case model.DoneTransition():
            raise TypeError(f"{tr.label!r}: a `done` transition has no trigger, its sub-machine's end fires it")
    raise TypeError(f"no trigger for a {type(tr).__name__}")
