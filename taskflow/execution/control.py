"""Operator control of a running mission: the actions, the channel the run loop drains, operator scripts.

An operator (``taskflow ctl``, a web page through :mod:`taskflow.operate.control_http`, or a script replayed in a
test) can ask a running mission to

* ``pause`` — freeze the simulation (no world step, no task step, the sim clock stops; the loop waits on
  this channel in wall time);
* ``hold`` — bring the robot to a safe stop (the world's ``safe_stop()`` every tick) while the world goes
  on; no task steps and no transition fires while held, and the time held does not count toward the
  ``after`` and ``for`` of the active states (:meth:`Executor.hold_for`);
* ``resume`` — from pause or hold;
* ``preempt`` — leave every active state for ``args.to`` (a state path of the mission), or with no ``to``
  end the run ``aborted`` (then the robot is stopped as after a failure); refused while a state it would
  enter reads mission data not written yet, and never a way past a loop's or parallel state's own
  success rule (:meth:`Executor.preempt`);
* ``inject`` — emit the declared event ``args.event``: the tick's guards see it as a world or task event.

Actions take effect at tick boundaries only: the run loop calls :meth:`OperatorChannel.begin_tick` at the
top of every tick, which applies the due actions of the operator script (sim time ``t`` reached), then
those queued by the endpoint, in order, and writes each as an :class:`~taskflow.execution.records.OperatorRecord`
(``transitions.jsonl``, with the tick's sim time and index).  A list of those records is itself an
operator script (:func:`script_from_records`): replayed, it gives the same run record.

A ``preempt`` leaves pause and hold (the run goes on from the new state); the other actions change only
what they name.  Events the world emits while the run is held are recorded in the trace but not acted on, and so
is an ``inject`` applied while held (the endpoint's reply says so: :meth:`OperatorChannel.note`).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal, Protocol

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from taskflow.api import Observation
from taskflow.errors import MissionError, Problem
from taskflow.execution.executor import Executor
from taskflow.execution.records import OPERATOR, OperatorRecord
from taskflow.mission.model import CompiledMission
from taskflow.registry import describe_choices

ACTIONS = ("pause", "hold", "resume", "preempt", "inject")
_ARGS: dict[str, tuple[str, ...]] = {"pause": (), "hold": (), "resume": (), "preempt": ("to",), "inject": ("event",)}
RUNNING, PAUSED, HELD = "running", "paused", "held"
WAIT_S = 0.25  # while paused, how often the loop looks up from the channel (for Ctrl-C and a finished run)


class ControlError(ValueError):
    """An operator action that cannot be applied: the message says why and what would be valid."""


class OperatorAction(BaseModel):
    """One operator action: what (``action`` with its ``args``), who asked, and — in an operator script —
    the sim time ``t`` (s) from which it applies (the first tick at or after ``t``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    t: float = Field(default=0.0, ge=0.0, allow_inf_nan=False)
    action: Literal["pause", "hold", "resume", "preempt", "inject"]
    args: dict[str, str] = Field(default_factory=dict)
    who: str = Field(default="operator", min_length=1)

    @model_validator(mode="after")
    def _args_fit(self) -> OperatorAction:
        allowed = _ARGS[self.action]
        for key in self.args:
            if key not in allowed:
                valid = f"it takes {', '.join(allowed)}" if allowed else "it takes none"
                raise ValueError(f"unknown argument {key!r} ({valid})")
        if self.action == "inject" and "event" not in self.args:
            raise ValueError("missing argument 'event': the declared event to emit")
        return self


_SCRIPT = TypeAdapter(list[OperatorAction])


def check_action(action: OperatorAction, mission: CompiledMission) -> None:
    """Refuse a pre-emption to a state the mission does not have, or an event it does not declare."""
    to = action.args.get("to")
    if action.action == "preempt" and to is not None and to not in mission.outside_regions:
        inside = to in mission.states
        raise ControlError((f"preempt: {to!r} is inside a parallel region, which is entered only with its parallel "
                            "state" if inside else f"preempt: no state {to!r} in mission {mission.name!r}") + " — "
                           + describe_choices(to, sorted(mission.outside_regions)))
    event = action.args.get("event")
    if action.action == "inject" and event is not None and event not in mission.events:
        raise ControlError(f"inject: event {event!r} is not declared by mission {mission.name!r} (its world, actions "
                           "and tasks) — " + describe_choices(event, sorted(mission.events)))


def unended_pause(script: Sequence[OperatorAction]) -> int | None:
    """The index in ``script`` of a pause that no later action (in sim-time order, as the channel applies
    them) at the same sim time resumes, holds or pre-empts (the sim clock stops while paused); None if every
    pause is ended."""
    order = sorted(range(len(script)), key=lambda i: script[i].t)  # stable: equal times keep their order
    for n, i in enumerate(order):
        if script[i].action == "pause" and not any(script[j].action in ("resume", "hold", "preempt")
                                                   and script[j].t <= script[i].t + 1e-9 for j in order[n + 1:]):
            return i
    return None


def _never_resumed(a: OperatorAction) -> str:
    return (f"pause at t={a.t:g} s is never resumed, held or pre-empted at that sim time and no control endpoint "
            "is open — the sim clock stops while paused, so the run would wait for ever: end it with an action at "
            f"t={a.t:g}, or run with a control endpoint")


def check_script(script: Sequence[OperatorAction], live: bool) -> None:
    """Without a live endpoint (``live=False``) a scripted pause must be ended by the script itself, at the
    same sim time (the sim clock stops while paused, so a later time never comes)."""
    i = None if live else unended_pause(script)
    if i is not None:
        raise ControlError(f"operator script item {i}: {_never_resumed(script[i])}")


# what each field of a script item holds, for the messages about a bad one
_FIELD_HINTS = {
    "t": "t is the sim time in seconds from which the action applies: a finite number >= 0",
    "args": "args: {to: STATE_PATH} for preempt (none: abort the run), {event: EVENT} for inject, none otherwise",
    "who": "who: a non-empty name, recorded with the action",
}


def load_operator_script(path: str | Path, mission: CompiledMission, live: bool = True) -> list[OperatorAction]:
    """Read an operator script file (YAML, a list of ``{t, action, args, who}``) and check it against
    ``mission`` (and, with ``live=False``, that every pause is ended by the script); every problem is a
    :class:`~taskflow.errors.MissionError` with the script's ``FILE:LINE:COL``."""
    from dataclasses import replace

    from taskflow.mission.diagnostics import clean_loc, pydantic_problems
    from taskflow.mission.yamlsrc import load_yaml_file

    example = "write a list of actions, e.g. - {t: 2.0, action: pause, who: me}"
    try:
        data, smap, _ = load_yaml_file(path)
    except MissionError as exc:  # the reader's message for an empty file speaks of missions
        raise MissionError([replace(p, message="the operator script is empty", hint=example)
                            if p.message == "the file is empty" else p for p in exc.problems]) from None
    if not isinstance(data, list):
        raise MissionError([smap.problem((), f"an operator script is a list of actions, got {type(data).__name__}",
                                         example)])
    try:
        script = _SCRIPT.validate_python(data)
    except ValidationError as exc:
        found = pydantic_problems(exc, smap, (), OperatorAction)
        hints: dict[tuple[int, int], str] = {}
        for err in exc.errors():
            loc = clean_loc(tuple(err["loc"]))
            if len(loc) >= 2 and loc[1] in _FIELD_HINTS:
                hints.setdefault(smap.where(loc), _FIELD_HINTS[str(loc[1])])
            elif len(loc) == 1:  # the item as a whole: not a mapping, or its args do not fit its action
                hints.setdefault(smap.where(loc), "an item is {t, action, args, who}, args {to: STATE_PATH} for "
                                 "preempt, {event: EVENT} for inject (this mission's events: "
                                 f"{', '.join(sorted(mission.events)) or 'none'}), none for pause, hold, resume")
        raise MissionError([p if p.hint else replace(p, hint=hints.get((p.line, p.col), "")) for p in found]) from None
    problems: list[Problem] = []
    for i, a in enumerate(script):
        try:
            check_action(a, mission)
        except ControlError as exc:
            key = "to" if a.action == "preempt" else "event"
            problems.append(smap.problem((i, "args", key), str(exc)))
    if problems:
        raise MissionError(problems)
    unended = None if live else unended_pause(script)
    if unended is not None:
        raise MissionError([smap.problem((unended, "action"), _never_resumed(script[unended]))])
    return script


def as_script(items: Sequence[OperatorAction | dict[str, Any]]) -> list[OperatorAction]:
    """Operator actions from ``items`` (actions or their mappings); a bad one is a :class:`ControlError`."""
    try:
        return [a if isinstance(a, OperatorAction) else OperatorAction.model_validate(a) for a in items]
    except ValidationError as exc:
        raise ControlError(f"operator script: {exc}") from None


def script_from_records(records: Sequence[dict[str, Any]]) -> list[OperatorAction]:
    """The operator script that replays a run's operator actions: its ``transitions.jsonl`` objects with
    ``cause: operator`` and an ``action`` (pre-emption transition records are left out: the action makes them)."""
    return [OperatorAction(t=r["t"], action=r["action"], args=r.get("args", {}), who=r["who"])
            for r in records if r.get("cause") == OPERATOR and "action" in r]


class ControlEndpoint(Protocol):
    """What a run needs of its operator endpoint (:func:`taskflow.execution.runtime.run_mission`'s
    ``control``): served from the run's start to its end.  The HTTP one is
    :class:`taskflow.operate.control_http.ControlServer`; the run never imports it (the operating layer sits
    above the run)."""

    def start(self, channel: OperatorChannel | None, run_dir: Path | None) -> None:
        """Serve ``channel`` (the run's; the record lands in ``run_dir``) from now on."""

    def stop(self) -> None:
        """Stop serving (the run has ended)."""


class OperatorChannel:
    """The one place operator actions meet the run loop.

    The endpoint's thread calls :meth:`submit` and :meth:`snapshot`; the run loop calls
    :meth:`begin_tick` at the top of each tick (the only place an action takes effect) and :meth:`finish`.
    ``mode`` is ``running``, ``paused`` or ``held``; ``records`` the actions applied so far."""

    def __init__(self, mission: CompiledMission, script: Sequence[OperatorAction | dict[str, Any]] = (), *,
                 live: bool = False, on_record: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.mission = mission
        script = as_script(script)
        for a in script:
            check_action(a, mission)
        check_script(script, live)
        self._script = sorted(script, key=lambda a: a.t)  # stable: equal times keep their order
        self._next = 0
        self._queue: queue.SimpleQueue[OperatorAction] = queue.SimpleQueue()
        self.on_record = on_record  # where each OperatorRecord's object goes (transitions.jsonl)
        self.on_wait: Callable[[], None] | None = None  # called as a pause begins (the recorder flushes)
        self.mode = RUNNING
        self.executor: Executor | None = None  # the run's, once it has started: submissions are checked against it
        self.records: list[OperatorRecord] = []
        self._lock = threading.Lock()
        self._state: dict[str, Any] = {"mission": mission.name, "state": "", "t": 0.0, "tick": 0, "paused": False,
                                       "held": False, "outcome": None, "reason": "", "running": True}

    # -- the endpoint's side ------------------------------------------------------------------------
    def submit(self, action: OperatorAction) -> None:
        """Queue ``action`` for the next tick boundary; raises :class:`ControlError` if the mission cannot
        take it or the run has ended."""
        check_action(action, self.mission)
        if not self.snapshot()["running"]:
            raise ControlError(f"{action.action}: the run has ended ({self.snapshot()['outcome']})")
        problem = self._refusal(action, self.executor)
        if problem is not None:
            raise ControlError(problem)
        self._queue.put(action)

    def note(self, action: OperatorAction) -> str | None:
        """What the operator should know about ``action`` just queued (the endpoint's reply says it), or None: an
        ``inject`` while the run is held is recorded but fires nothing — no transition fires while held."""
        if action.action == "inject" and self.mode == HELD:
            return (f"the run is held: the injected {action.args.get('event')!r} is recorded but not acted on "
                    "(no transition fires while held); resume first to have an event fire")
        return None

    @staticmethod
    def _refusal(action: OperatorAction, executor: Executor | None) -> str | None:
        """Why the run cannot take ``action`` now (a pre-emption into a state whose entry reads mission data
        not written yet: :meth:`Executor.preempt_problem`), or None."""
        to = action.args.get("to")
        if action.action != "preempt" or to is None or executor is None:
            return None
        return executor.preempt_problem(to)

    def snapshot(self) -> dict[str, Any]:
        """``GET /state``: active state, sim time and tick, the paused/held flags, outcome once decided."""
        with self._lock:
            return dict(self._state)

    def describe(self) -> dict[str, Any]:
        """``GET /mission``: what may be asked of this run (the state paths to pre-empt to, events to inject)."""
        return {"mission": self.mission.name, "actions": list(ACTIONS), "states": sorted(self.mission.outside_regions),
                "events": sorted(self.mission.events)}

    # -- the run loop's side ------------------------------------------------------------------------
    @property
    def held(self) -> bool:
        return self.mode == HELD

    def begin_tick(self, k: int, obs: Observation, executor: Executor, stopping: Callable[[], bool]) -> Observation:
        """Apply the actions due at the start of tick ``k`` (sim time ``obs.t``); while paused, wait on the
        channel (in wall time) until resumed, pre-empted or ``stopping()``.  Returns ``obs`` with the events
        injected this tick added."""
        injected: list[str] = []
        waited = False
        while True:
            self._apply_due(k, obs.t, executor, injected)
            self._publish(k, obs.t, executor)
            if self.mode != PAUSED or executor.outcome is not None or stopping():
                break
            if self.on_wait is not None and not waited:
                self.on_wait()  # the record so far is on disk while the run waits (the web view reads it)
            waited = True
            try:
                action = self._queue.get(timeout=WAIT_S)
            except queue.Empty:
                continue
            self._apply(action, k, obs.t, executor, injected)
        if injected:
            obs = Observation(t=obs.t, state=obs.state, sensors=obs.sensors, events=(*obs.events, *injected),
                              metrics=obs.metrics, timings=obs.timings)
        return obs

    def finish(self, executor: Executor, t: float) -> None:
        """The run has ended: the snapshot shows its outcome; later submissions are refused."""
        with self._lock:
            self._state.update(state=executor.state, t=round(t, 9), paused=False, held=False,
                               outcome=executor.outcome, reason=executor.reason, running=False)

    def _apply_due(self, k: int, t: float, executor: Executor, injected: list[str]) -> None:
        script = self._script
        while self._next < len(script) and script[self._next].t <= t + 1e-9 and executor.outcome is None:
            self._apply(script[self._next], k, t, executor, injected)
            self._next += 1
        while executor.outcome is None:
            try:
                action = self._queue.get_nowait()
            except queue.Empty:
                break
            self._apply(action, k, t, executor, injected)

    def _apply(self, a: OperatorAction, k: int, t: float, executor: Executor, injected: list[str]) -> None:
        if executor.outcome is not None:
            return
        refused = self._refusal(a, executor)  # checked again at the tick boundary: a script's, or a race
        rec = OperatorRecord(t, k, a.action, a.who, executor.state, dict(a.args), refused)
        self.records.append(rec)
        if self.on_record is not None:
            self.on_record(rec.as_dict())
        if refused is not None:
            return
        if a.action == "pause":
            self.mode = PAUSED
        elif a.action == "hold":
            self.mode = HELD
        elif a.action == "resume":
            self.mode = RUNNING
        elif a.action == "inject":
            injected.append(a.args["event"])
        else:  # preempt
            self.mode = RUNNING
            executor.preempt(a.args.get("to"), a.who, t)

    def _publish(self, k: int, t: float, executor: Executor) -> None:
        with self._lock:
            self._state.update(state=executor.state, t=round(t, 9), tick=k, paused=self.mode == PAUSED,
                               held=self.mode == HELD)
