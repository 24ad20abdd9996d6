"""Operator semantics in the engine (issue 20, "mops"): what a pre-emption does to the outcome, what hold
does to the timers, and pre-emptions the run's mission data cannot take.

* A pre-emption that leaves a ``foreach`` (or parallel) state before its own success rule decided it
  cannot make the run ``succeeded`` unless that rule, evaluated when it was left, holds; the summary's
  ``preempted`` list and the reason name who pre-empted and to where (the car on PyBullet through
  ``taskflow run --operator-script``, and the rule's cases on the scripted backend).
* Time under ``hold`` does not count toward ``after`` and ``for`` (the car held for 100 s, longer than
  every timeout it has, completes after ``resume``).
* A pre-emption into a state whose entry reads mission data the run has not written is refused, naming the
  key and its writers, and the run goes on (toy world: the live endpoint and an operator script).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from toys import MARKED

from taskflow.cli import main
from taskflow.execution.control import ControlError, OperatorChannel
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission_text
from taskflow.readers.run_files import read_trace
from taskflow.testing import Script, assert_outcome, drive

HERE = Path(__file__).resolve().parents[1]
CAR = HERE.parent / "missions" / "car_waypoints.yaml"


def _jsonl(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "transitions.jsonl").read_text().splitlines()]


def _car_run(tmp_path: Path, ops: list[dict[str, Any]], *extra: str) -> tuple[int, dict[str, Any], Path]:
    script = tmp_path / "ops.yaml"
    script.write_text(yaml.safe_dump(ops))
    out = tmp_path / "run"
    code = main(["run", str(CAR), "--no-control", "--quiet", "--operator-script", str(script), "--out", str(out),
                 *extra])
    return code, json.loads((out / "summary.json").read_text()), out


WAYPOINTS = [(2.0, 0.5), (3.0, 2.0), (1.5, 3.0)]  # missions/car_waypoints.yaml


D = 0.325  # the control point's distance ahead of the rear axle (the mission's gains profiles)


def _closest(trace: dict[str, np.ndarray], goal: tuple[float, float], since: float = 0.0) -> float:
    """The control point's closest approach (m) to ``goal`` from sim time ``since`` on, from the ground truth
    (``gt.x``, ``gt.y``: the rear axle; ``gt.yaw``)."""
    sel = trace["t"] >= since
    x = trace["gt.x"][sel] + D * np.cos(trace["gt.yaw"][sel])
    y = trace["gt.y"][sel] + D * np.sin(trace["gt.yaw"][sel])
    return float(np.nanmin(np.hypot(x - goal[0], y - goal[1])))


# -- 1. a pre-emption never ends `succeeded` unless the mission's own rule holds --------------------------

@pytest.mark.mission
def test_car_preempted_to_done_after_one_of_three_waypoints_fails_naming_the_operator(tmp_path):
    # unhindered, waypoint 1 is reached at 7.2 s and waypoint 2 at 14.55 s: at 10 s one item has succeeded
    code, summary, out = _car_run(tmp_path, [{"t": 10.0, "action": "preempt", "args": {"to": "done"}, "who": "alice"}])
    assert code == 1
    assert summary["outcome"] == "failed" and summary["final_state"] == "done"
    assert summary["preempted"] == [{"t": 10.0, "who": "alice", "to": "done", "from": "drive.approach"}]
    reason = summary["reason"]
    assert "alice" in reason and "'done'" in reason and "1 of 3 items succeeded" in reason, reason
    assert summary["items"]["drive"]["succeeded"] == 1
    trace = read_trace(out)
    assert _closest(trace, WAYPOINTS[0]) < 0.05  # ground truth: the first waypoint was reached ...
    assert _closest(trace, WAYPOINTS[1]) > 0.3 and _closest(trace, WAYPOINTS[2]) > 0.3  # ... the others never
    assert [r["to"] for r in _jsonl(out) if r.get("cause") == "operator" and "to" in r] == ["done"]


# the rule's cases on the scripted backend: a loop of three items (each: `work` until `tool_done`)
LOOP = """
mission: loop
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 30 s
parameters: {goals: [1.0, 2.0, 3.0]}
machine:
  initial: visit
  states:
    visit:
      foreach: {in: goals, as: goal%s}
      initial: work
      transitions:
        - {to: done, done: succeeded}
        - {to: error, done: failed}
        - {to: aside, on: target_lost}     # never emitted: `aside` is for the operator
      states:
        work:
          action: {name: tool}
          transitions: [{to: ok, on: tool_done}]
        ok: {final: succeeded}
    aside:
      transitions: [{to: visit, after: 0.5 s}]
    done: {final: succeeded}
    error: {final: failed}
"""
TOOL = Script(actions={"tool": (1.0, "tool_done")})  # an item takes 1 s: items end at 1.0, 2.0, 3.0 s


def _drive_loop(ops: list[dict[str, Any]], foreach: str = "") -> Any:
    return drive(load_mission_text(LOOP % foreach, "loop.yaml"), TOOL, operator=ops)


def test_preempt_out_of_a_loop_whose_rule_does_not_hold_fails():
    r = _drive_loop([{"t": 1.5, "action": "preempt", "args": {"to": "done"}, "who": "bob"}])
    assert_outcome(r, "failed")
    assert "1 of 3 items succeeded, its rule requires 3 (all)" in r.summary["reason"]
    assert "bob (operator) pre-empted the run to 'done' at t = 1.5 s" in r.summary["reason"]
    assert r.summary["preempted"] == [{"t": 1.5, "who": "bob", "to": "done", "from": "visit.work"}]


def test_preempt_out_of_a_loop_whose_rule_already_holds_may_succeed():
    r = _drive_loop([{"t": 1.5, "action": "preempt", "args": {"to": "done"}, "who": "bob"}],
                    ", on_failure: continue, require: 1")
    assert_outcome(r, "succeeded")
    assert r.summary["reason"].endswith("; pre-empted by bob (operator) to 'done' at t = 1.5 s")


def test_a_loop_entered_afresh_after_a_preemption_is_judged_by_its_own_rule_again():
    # pre-empted aside at 1.5 s (1 of 3 done); `aside` re-enters the loop, whose three items then succeed
    r = _drive_loop([{"t": 1.5, "action": "preempt", "args": {"to": "aside"}, "who": "bob"}])
    assert_outcome(r, "succeeded")
    assert r.summary["items"]["visit"]["attempted"] == 4 and r.summary["final_state"] == "done"
    assert "pre-empted by bob (operator) to 'aside' at t = 1.5 s" in r.summary["reason"]


def test_a_preemption_into_the_loop_itself_leaves_its_rule_to_decide():
    r = _drive_loop([{"t": 1.5, "action": "preempt", "args": {"to": "visit"}, "who": "bob"}])
    assert_outcome(r, "succeeded")  # the loop restarted (item 0) and ran all three items
    assert [it["index"] for it in r.summary["iterations"]] == [0, 0, 1, 2]


def test_preempt_without_a_target_aborts_and_is_listed():
    r = _drive_loop([{"t": 0.5, "action": "preempt", "who": "bob"}])
    assert_outcome(r, "aborted")
    assert r.summary["preempted"] == [{"t": 0.5, "who": "bob", "to": None, "from": "visit.work"}]


REGIONS = HERE / "machine" / "missions" / "toy_regions.yaml"


def test_preempt_out_of_a_parallel_state_before_its_regions_finish_is_aborted():
    m = load_mission_text(REGIONS.read_text(), str(REGIONS))
    metrics = Script(metrics=lambda s: {"pos_error": 1.0, "x_abs": 0.0})  # neither region ever finishes
    r = drive(m, metrics, operator=[{"t": 1.0, "action": "preempt", "args": {"to": "done"}, "who": "carol"}])
    assert_outcome(r, "aborted")
    assert "'work' had not finished" in r.summary["reason"] and "'drive', 'watch'" in r.summary["reason"]


def test_an_undisturbed_run_has_no_operator_fields():
    r = _drive_loop([])
    assert_outcome(r, "succeeded")
    assert "preempted" not in r.summary and "held_s" not in r.summary


# -- 2. time under hold does not count toward `after` and `for` ----------------------------------------

@pytest.mark.mission
def test_car_held_longer_than_every_timeout_completes_after_resume(tmp_path):
    # held in `drive.approach` from 3 s to 103 s: longer than approach's 30 s, settle's 15 s and the whole
    # loop's 90 s; before the change, resume fired `drive`'s `after: 90 s` at once (outcome failed)
    code, summary, out = _car_run(tmp_path, [{"t": 3.0, "action": "hold", "who": "alice"},
                                             {"t": 103.0, "action": "resume", "who": "alice"}], "--max-time", "200 s")
    assert code == 0 and summary["outcome"] == "succeeded", summary["reason"]
    assert summary["held_s"] == pytest.approx(100.0)
    assert summary["items"]["drive"]["succeeded"] == 3
    assert not [r for r in _jsonl(out) if r.get("cause") == "timeout"]
    trace = read_trace(out)
    held = np.array(["hold" in str(e).split("|") for e in trace["events"]])
    assert held.sum() == 2000 and trace["t"][held][0] == 3.0  # 100 s of held ticks at 20 Hz
    v_held = np.abs(trace["gt.v"][held & (trace["t"] > 5.0)])
    assert v_held.max() < 0.01  # the car stood still while held
    for goal in WAYPOINTS:  # ground truth: every waypoint reached within the settle guard's 3 cm (+ odometry)
        assert _closest(trace, goal, since=103.0 if goal != WAYPOINTS[0] else 0.0) < 0.04
    # the entry clocks the records give are sim times: settle of item 0 entered after the hold
    settle = [r for r in _jsonl(out) if r.get("to") == "drive.settle"]
    assert settle[0]["t"] > 103.0
    assert summary["time_in_state_s"]["drive.approach"] > 100.0


HOLD = """
mission: hold
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 60 s
machine:
  initial: outer
  states:
    outer:
      initial: a
      transitions:
        - {to: late, after: 4 s, since: first_entry}
      states:
        a:
          transitions:
            - {to: b, when: "visible == 1", for: 1 s}
            - {to: late, after: 2 s}
        b:
          transitions: [{to: a, on: target_lost}, {to: done, after: 1 s}]
    late: {final: failed}
    done: {final: succeeded}
"""


def test_hold_stops_after_and_for_clocks_and_first_entry_clocks():
    m = load_mission_text(HOLD, "hold.yaml")
    near = Script(metrics=lambda s: {"visible": 1.0 if s.t >= 0.5 else 0.0})
    # unheld: the dwell starts at 0.5 s and fires at 1.5 s; `b` then ends the run at 2.5 s
    base = drive(m, near)
    assert_outcome(base, "succeeded")
    assert [(r.t, r.target) for r in base.executor.transitions_fired][1:] == [(1.5, "outer.b"), (2.5, "done")]
    # held 0.9 s → 10.9 s: the dwell (begun at 0.5 s) needs 0.1 s more of operating time after resume, and
    # neither `after: 2 s` nor `after: 4 s since first_entry` counts the 10 s held
    r = drive(m, near, operator=[{"t": 0.9, "action": "hold"}, {"t": 10.9, "action": "resume"}])
    assert_outcome(r, "succeeded")
    assert [(r_.t, r_.target) for r_ in r.executor.transitions_fired][1:] == [(11.5, "outer.b"), (12.5, "done")]
    assert r.summary["held_s"] == pytest.approx(10.0)
    ex = r.executor
    assert ex.entered_at(m.states["outer"]) == 0.0  # entry clocks stay sim times
    assert ex.operating_since(m.states["outer"], 12.5) == pytest.approx(2.5)
    # pause freezes the sim clock itself: nothing to discount
    p = drive(m, near, operator=[{"t": 0.9, "action": "pause"}, {"t": 0.9, "action": "resume"}])
    assert [(r_.t, r_.target) for r_ in p.executor.transitions_fired] == [
        (r_.t, r_.target) for r_ in base.executor.transitions_fired]


def test_a_scripted_pause_must_end_at_its_own_sim_time():
    m = load_mission_text(HOLD, "hold.yaml")
    with pytest.raises(ControlError, match="never resumed, held or pre-empted at that sim time"):
        OperatorChannel(m, [{"t": 1.0, "action": "pause"}, {"t": 2.0, "action": "resume"}])


# -- 3. a pre-emption into a state that reads mission data not written yet is refused ---------------------

# MARKED (tests/toys.py): start at 0.3 → away to x = 1.0 → mark writes toy.mark → back (toy_return reads it) → done

def test_a_scripted_preempt_into_an_unwritten_read_is_refused_and_the_run_goes_on(tmp_path):
    m = load_mission_text(MARKED, "marked.yaml")
    base = run_mission(m, record=False)
    assert_outcome(base, "succeeded")
    out = tmp_path / "run"
    r = run_mission(m, out_dir=out, operator=[{"t": 0.5, "action": "preempt", "args": {"to": "back"}, "who": "dan"}])
    assert_outcome(r, "succeeded")  # not aborted with KeyError: the pre-emption changed nothing
    assert r.summary["states_visited"] == base.summary["states_visited"] == ["away", "mark", "back", "done"]
    assert "preempted" not in r.summary
    (op,) = [x for x in _jsonl(out) if x.get("cause") == "operator"]
    assert op["t"] == 0.5 and op["state"] == "away"
    assert "'back' reads mission data 'toy.mark'" in op["refused"] and "written by 'mark'" in op["refused"]
    assert r.summary["sim_time_s"] == base.summary["sim_time_s"]
    # every reader takes the refused action: the recorded run and its printed summary name the refusal
    from taskflow.readers.recorded import load_run
    from taskflow.readers.report import format_report

    (rec,) = load_run(out).operator
    assert rec.action == "preempt" and rec.refused == op["refused"]
    assert "refused: preempt: 'back' reads mission data 'toy.mark'" in format_report(load_run(out))
