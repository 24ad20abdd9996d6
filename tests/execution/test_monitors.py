"""The runtime monitor of mission properties (:mod:`taskflow.execution.monitors`) on the scripted backend: each
pattern held and violated, the first violation a ``cause: property`` record of ``transitions.jsonl`` with the
atoms' values, ``summary.json``'s ``properties``, and a mission without properties writing neither."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskflow.execution.monitors import PropertyMonitor
from taskflow.execution.records import PropertyRecord
from taskflow.mission.loader import load_mission_text
from taskflow.readers.recorded import load_run
from taskflow.readers.report import format_report
from taskflow.readers.run_files import read_transitions
from taskflow.testing import Script, drive

pytestmark = pytest.mark.machine

TOY = """
mission: toy
robot: racecar
world: flat_ground
rate_hz: 20
events: [lost]
properties: {PROPS}
machine:
  initial: move
  states:
    move:
      task: {name: car_goto, params: {target: [1.0, 0.0]}}
      transitions: [{to: done, when: "pos_error < 1 cm"}, {to: search, on: lost}]
    search:
      task: {name: car_goto, params: {target: [1.0, 0.0]}}
      transitions: [{to: move, after: 0.5 s}, {to: fail, on: lost}]
    done: {final: succeeded}
    fail: {final: failed}
"""


def run(props: str, *, error: float = 1.0, events: tuple[tuple[float, str], ...] = ((0.5, "lost"),),
        out: Path | None = None, max_time: float = 3.0) -> dict[str, dict[str, object]]:
    """Drive the toy: ``pos_error`` is ``error`` until t = 2 s, then 0 (the guard to ``done`` fires)."""
    mission = load_mission_text(TOY.replace("{PROPS}", props), "toy.yaml")
    r = drive(mission, Script(metrics=lambda s: {"pos_error": 0.0 if s.t >= 2.0 else error}, events=list(events)),
              max_time=max_time, out_dir=out)
    verdicts: dict[str, dict[str, object]] = r.summary["properties"]
    return verdicts


def test_absence_held_and_violated_with_and_without_its_condition() -> None:
    v = run('{a: {never: "state(fail)"}, b: {never: "state(search)", while: "pos_error > 2 m"},'
            ' c: {never: "state(search)", while: "pos_error > 0.5 m"}}')
    assert v["a"] == {"pattern": "absence", "verdict": "held", "t": None}
    assert v["b"]["verdict"] == "held"
    assert v["c"] == {"pattern": "absence", "verdict": "violated", "t": 0.55}  # the first tick run in search
    v = run('{a: {never: "state(fail)"}}', events=((0.5, "lost"), (0.7, "lost")))
    assert v["a"] == {"pattern": "absence", "verdict": "violated", "t": 0.7}  # the final state the run ended in


def test_universality_breaks_at_its_first_tick() -> None:
    assert run('{u: {always: "pos_error >= 0.5 m"}}')["u"] == {"pattern": "universality", "verdict": "violated",
                                                                "t": 2.0}
    assert run('{u: {always: "not state(fail)"}}')["u"]["verdict"] == "held"


def test_response_within_one_control_period_and_a_missed_deadline() -> None:
    v = run('{r1: {after: "event(lost)", within: 0.05 s, then: "state(search)"},'
            ' r2: {after: "event(lost)", within: 40 ms, then: "state(search)"},'
            ' r3: {after: "state(search)", within: 1 s, then: "state(move)"}}')
    assert v["r1"]["verdict"] == "held"  # lost at 0.5 s, the tick at 0.55 s runs in search
    assert v["r2"]["verdict"] == "violated" and v["r2"]["t"] == 0.55
    assert v["r3"]["verdict"] == "held"  # back to move after 0.5 s


def test_response_open_at_the_end_is_violated_after_a_final_state_and_undecided_when_cut_short() -> None:
    props = '{r: {after: "state(move) and pos_error < 1 cm", within: 10 s, then: "state(fail)"}}'
    v = run(props)
    assert v["r"]["verdict"] == "violated" and "the run ended (succeeded)" in str(v["r"]["reason"])
    v = run('{r: {after: "state(search)", within: 10 s, then: "state(fail)"}}', max_time=1.0)
    assert v["r"]["verdict"] == "not_decided" and "timeout" in str(v["r"]["reason"])


def test_precedence_and_outcome_atoms() -> None:
    v = run('{p1: {only_after: "event(lost)", occurs: "state(search)"},'
            ' p2: {only_after: "state(search)", occurs: "state(done)"},'
            ' p3: {only_after: "state(fail)", occurs: "outcome(succeeded)"}}', events=())
    assert v["p1"]["verdict"] == "held"
    assert v["p2"]["verdict"] == "violated" and v["p2"]["t"] == 2.0  # the run ended in done, search never ran
    assert v["p3"]["verdict"] == "violated" and v["p3"]["t"] == 2.0  # the run ended succeeded at t = 2 s


def test_the_first_violation_is_a_record_the_readers_and_report_read(tmp_path: Path) -> None:
    props = '{far: {never: "state(search)", while: "pos_error > 0.5 m", description: stop far away}}'
    run(props, out=tmp_path, events=((0.5, "lost"), (0.7, "lost")))  # search, then fail
    lines = [json.loads(x) for x in (tmp_path / "transitions.jsonl").read_text().splitlines()]
    props_lines = [x for x in lines if x["cause"] == "property"]
    assert props_lines == [{"t": 0.55, "cause": "property", "property": "far", "pattern": "absence",
                            "verdict": "violated", "state": "search",
                            "atoms": {"state(search)": True, "pos_error": 1.0}}]  # once, though search ran 4 ticks
    recs = [r for r, _, _ in read_transitions(tmp_path)]
    assert sum(isinstance(r, PropertyRecord) for r in recs) == 1
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["properties"]["far"]["verdict"] == "violated"
    run_ = load_run(tmp_path)
    assert [r.property for r in run_.properties] == ["far"]
    assert all(r.cause != "property" for r in run_.transitions)  # the "how it got there" chain: state changes only
    report = format_report(run_)
    assert "far (absence): violated at t = 0.55 s in search: state(search) = true, pos_error = 1" in report
    assert "how it got there" in report and "search → fail" in report


def test_no_properties_no_key_no_monitor(tmp_path: Path) -> None:
    mission = load_mission_text(TOY.replace("properties: {PROPS}\n", ""), "toy.yaml")
    r = drive(mission, Script(metrics=lambda s: {"pos_error": 1.0}), max_time=1.0, out_dir=tmp_path)
    assert "properties" not in r.summary
    assert "property" not in (tmp_path / "transitions.jsonl").read_text()


def test_the_monitor_reads_regions_as_every_active_leaf_and_its_ancestors() -> None:
    mission = load_mission_text(TOY.replace("{PROPS}", '{a: {always: "pos_error >= 0 m"}}'), "toy.yaml")
    mon = PropertyMonitor(mission.properties, mission.states)
    mon.tick(0.0, "move|search", {"pos_error": 1.0}, (), {})
    assert mon.facts.active == {"move", "search"}
    mon.tick(0.05, "move", {"pos_error": -1.0}, (), {})
    assert mon.verdicts()["a"]["verdict"] == "violated" and mon.records[0].atoms == {"pos_error": -1.0}
