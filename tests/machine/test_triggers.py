"""Each transition kind armed for a run (`taskflow/execution/triggers.py`): the trigger of its kind, what its
``ready`` reads, and its run-time state kept per run, not in the compiled mission every run shares."""

from __future__ import annotations

import pytest

from taskflow.execution.engine import MissionState
from taskflow.execution.records import EVENT, GUARD, TIMEOUT
from taskflow.execution.triggers import (
    ConditionalEventTrigger,
    DwellTrigger,
    EventTrigger,
    GuardTrigger,
    TimeoutTrigger,
    arm,
)
from taskflow.mission.loader import load_mission_text
from taskflow.mission.model import CompiledMission, DoneTransition
from taskflow.testing import Script, drive

MISSION = """
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 10 s
profiles:
  gains: {slow: {kp: 1.0}}
machine:
  initial: job
  states:
    job:
      initial: go
      transitions:
        - {to: lost, on: target_lost}
        - {to: lost, on: target_found, when: "pos_error < 1 m"}
        - {to: done, done: true}
      states:
        go:
          task: {name: toy_goto, params: {target: 1.0}}
          bind: {gains: slow}
          transitions:
            - {to: ok, when: "pos_error < 1 cm", for: 0.3 s}
            - {to: ok, when: "pos_error < 1 mm"}
            - {to: ok, after: 2 s}
        ok: {final: succeeded}
    lost: {final: failed}
    done: {final: succeeded}
"""


def mission() -> CompiledMission:
    return load_mission_text(MISSION, "t.yaml")


def test_every_kind_is_armed_as_its_own_trigger_and_done_has_none() -> None:
    m = mission()
    clocks = {p: MissionState(p.rsplit(".", 1)[-1]) for p in m.states}
    armed = {tr.label: arm(tr, {}, lambda n: clocks[n.path]) for n in m.states.values() for tr in n.transitions
             if not isinstance(tr, DoneTransition)}
    assert {label: type(t) for label, t in armed.items()} == {
        "on target_lost": EventTrigger, "on target_found when pos_error < 1 m": ConditionalEventTrigger,
        "pos_error < 1 cm for 0.3 s": DwellTrigger, "pos_error < 1 mm": GuardTrigger, "after 2 s": TimeoutTrigger}
    assert [armed[k].cause for k in ("on target_lost", "pos_error < 1 mm", "after 2 s")] == [EVENT, GUARD, TIMEOUT]
    done = next(tr for tr in m.states["job"].transitions if isinstance(tr, DoneTransition))
    with pytest.raises(TypeError, match="no trigger"):
        arm(done, {}, lambda n: clocks[n.path])


def test_ready_reads_the_guard_the_event_and_the_operating_clock() -> None:
    m = mission()
    go = m.states["job.go"]
    clock = MissionState("go")
    clock.entered_at = 1.0
    by = {tr.label: arm(tr, {}, lambda n: clock) for n in m.states.values() for tr in n.transitions
          if not isinstance(tr, DoneTransition)}
    near, far = {"pos_error": 0.0005}, {"pos_error": 0.5}
    assert by["pos_error < 1 mm"].ready(0.0, 0.0, near, ()) and not by["pos_error < 1 mm"].ready(0.0, 0.0, far, ())
    assert by["on target_lost"].ready(0.0, 0.0, {}, ("target_lost",))
    cond = by["on target_found when pos_error < 1 m"]
    assert cond.ready(0.0, 0.0, far, ("target_found",)) and not cond.ready(0.0, 0.0, {"pos_error": 2.0}, ("target_found",))
    timeout = by["after 2 s"]
    assert not timeout.ready(2.9, 0.0, {}, ()) and timeout.ready(3.0, 0.0, {}, ())
    assert not timeout.ready(3.0, 0.5, {}, ())  # half a second under hold does not count
    assert timeout.transition.source is go
    assert by["pos_error < 1 mm"].why(near) == {"state": "job.go", "label": "pos_error < 1 mm", "index": 4,
                                                "metrics": {"pos_error": 0.0005}}
    assert by["on target_lost"].why(None) == {"state": "job", "label": "on target_lost", "index": 0,
                                              "event": "target_lost"}


def test_a_dwell_holds_without_a_break_for_its_time_on_the_operating_clock() -> None:
    m = mission()
    tr = next(t for t in m.states["job.go"].transitions if t.label == "pos_error < 1 cm for 0.3 s")
    dwell = arm(tr, {}, lambda n: MissionState("go"))
    near, far = {"pos_error": 0.0}, {"pos_error": 1.0}
    assert [dwell.ready(t, 0.0, near, ()) for t in (0.0, 0.1, 0.2)] == [False, False, False]
    assert dwell.ready(0.3, 0.0, near, ())
    dwell.reset()  # its state entered again
    assert not dwell.ready(1.0, 0.0, near, ()) and not dwell.ready(1.3, 0.2, near, ())  # 0.2 s of it held
    assert dwell.ready(1.5, 0.2, near, ())
    dwell.missed(far)  # an earlier transition fired in a tick its guard broke: the dwell starts again
    assert not dwell.ready(1.6, 0.2, near, ())


def test_two_runs_of_one_compiled_mission_do_not_share_a_dwell() -> None:
    """The dwell's start lives in the run's trigger, not in the compiled record both runs read."""
    m = mission()
    script = Script(metrics=lambda s: {"pos_error": 0.005 if s.t >= 0.5 else 1.0})
    first = [(round(r.t, 6), r.target, r.cause) for r in drive(m, script).executor.transitions_fired]
    second = [(round(r.t, 6), r.target, r.cause) for r in drive(m, script).executor.transitions_fired]
    assert first == second
    assert first[1] == (0.8, "job.ok", "guard")  # 0.5 s + the 0.3 s dwell
