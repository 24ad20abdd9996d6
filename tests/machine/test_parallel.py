"""Parallel (orthogonal) regions: entry, command ownership, completion and outcome rules, and the load
errors that keep regions apart — through the real loader, engine and executor (toy world and tasks)."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, assert_outcome, drive

HEAD = """
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
parameters: {tol: 1 cm}
"""
PROFILES = """profiles:
  gains: {slow: {kp: 1.0}}
"""


def mission(machine: str):  # type: ignore[no-untyped-def]
    return load_mission_text(HEAD + (PROFILES if "bind:" in machine else "") + machine, "par.yaml")


def fired(result):  # type: ignore[no-untyped-def]
    return [(round(r.t, 6), r.source, r.target, r.cause) for r in result.executor.transitions_fired]


TIMED = """
machine:
  initial: both
  states:
    both:
      regions:
        a:
          initial: a1
          states:
            a1: {transitions: [{to: a_end, after: A_AFTER}]}
            a_end: {final: A_OUTCOME}
        b:
          initial: b1
          states:
            b1: {transitions: [{to: b_end, after: B_AFTER}]}
            b_end: {final: B_OUTCOME}
      OUTCOME_MAP
      transitions:
        - {to: ok, done: succeeded}
        - {to: bad, done: failed}
    ok: {final: succeeded}
    bad: {final: failed}
"""


def timed(a_after: str, b_after: str, a_out: str = "succeeded", b_out: str = "succeeded", omap: str = ""):  # type: ignore[no-untyped-def]
    text = (TIMED.replace("A_AFTER", a_after).replace("B_AFTER", b_after).replace("A_OUTCOME", a_out)
            .replace("B_OUTCOME", b_out).replace("OUTCOME_MAP", omap))
    return mission(text)


def test_entering_a_parallel_state_enters_every_region():
    r = drive(timed("5 s", "5 s"), Script(), max_time=1.0)
    assert r.executor.state == "both.a.a1|both.b.b1"
    assert [leaf.path for leaf in r.executor.leaves] == ["both.a.a1", "both.b.b1"]
    assert fired(r)[0][2] == "both"  # the start transition names the parallel state


def test_the_parallel_state_is_done_when_every_region_is_final():
    r = drive(timed("1 s", "2 s"), Script())
    assert_outcome(r, "succeeded")
    assert fired(r)[1:] == [(1.0, "both.a.a1", "both.a.a_end", "timeout"),
                            (2.0, "both.b.b1", "both.b.b_end", "timeout"),
                            (2.0, "both.a.a_end|both.b.b_end", "ok", "done")]


def test_a_failed_region_preempts_the_others_at_once():
    r = drive(timed("3 s", "0.5 s", b_out="failed"), Script())
    assert_outcome(r, "failed")
    assert fired(r)[-2:] == [(0.5, "both.b.b1", "both.b.b_end", "timeout"),
                             (0.5, "both.a.a1|both.b.b_end", "bad", "done")]
    assert "both.a.a_end" not in r.summary["states_visited"]  # region a never finished: it was pre-empted


def test_outcome_map_finishes_on_the_regions_it_names():
    # b is a monitor that never ends: the map makes a's success the parallel state's
    r = drive(timed("1 s", "60 s", omap="outcome_map: {succeeded: {a: succeeded}}"), Script())
    assert_outcome(r, "succeeded")
    assert fired(r)[-1] == (1.0, "both.a.a_end|both.b.b1", "ok", "done")
    # the first matching rule wins, even over a region's own failure
    r = drive(timed("1 s", "2 s", b_out="failed", omap="outcome_map: {succeeded: {a: succeeded, b: failed}}"),
              Script())
    assert_outcome(r, "succeeded")
    assert fired(r)[-1] == (2.0, "both.a.a_end|both.b.b_end", "ok", "done")


def test_without_a_rule_a_monitor_that_never_ends_keeps_the_state_active():
    r = drive(timed("1 s", "60 s"), Script(), max_time=5.0)
    assert r.outcome == "timeout" and r.executor.state == "both.a.a_end|both.b.b1"


def test_a_transition_inside_one_region_leaves_the_other_alone():
    r = drive(timed("1 s", "3 s"), Script(), max_time=2.0)
    ex = r.executor
    b1 = ex.mission.states["both.b.b1"]
    assert ex.entered_at(b1) == 0.0  # not re-entered when region a moved on at 1 s
    assert r.summary["time_in_state_s"]["both.a.a1"] == pytest.approx(1.0)


def test_both_regions_can_fire_in_the_same_tick():
    r = drive(timed("1 s", "1 s"), Script())
    assert [(t, tgt) for t, _, tgt, _ in fired(r)[1:]] == [(1.0, "both.a.a_end"), (1.0, "both.b.b_end"), (1.0, "ok")]


REGIONS = (Path(__file__).parent / "missions" / "toy_regions.yaml").read_text()


def regions(limit: str = "5 m") -> str:
    """The toy_regions mission, its watch region tripping at ``x_abs > limit``."""
    return REGIONS.replace('"x_abs > 5 m"', f'"x_abs > {limit}"')


def test_each_region_drives_only_the_parts_it_owns_on_the_real_loop():
    m = load_mission_text(regions(), "par.yaml")
    r = run_mission(m, record=False, max_time=20.0)
    # the monitor commands full reverse (v = -9) but owns nothing: the robot follows the drive region
    assert r.outcome == "timeout"  # the monitor never finishes and no outcome_map lets the drive's success end it
    assert r.executor.world.ground_truth()["x"] == pytest.approx(1.0, abs=0.01)
    assert r.executor.state == "work.drive.there|work.watch.look"


def test_a_monitor_region_preempts_the_driving_region_and_the_robot_stops():
    m = load_mission_text(regions("0.5 m"), "par.yaml")
    r = run_mission(m, record=False, max_time=20.0)
    assert_outcome(r, "failed")
    trip = next(rec for rec in r.executor.transitions_fired if rec.target == "work.watch.too_far")
    assert trip.t == pytest.approx(0.72, abs=0.06)  # x(t) ≈ 1 - e^-t passes 0.5 m at ln 2 ≈ 0.69 s
    assert "work.drive.there" not in r.summary["states_visited"]
    # the stop state has no task: the robot's stop command holds it where the monitor caught it
    gt = r.executor.world.ground_truth()["x"]
    assert 0.5 <= gt < 0.6


# -- load errors -------------------------------------------------------------------------------------


def load_error(text: str) -> str:
    """The load error of a whole mission, or of a machine under the common head."""
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "par.yaml") if text.lstrip().startswith(("#", "mission:")) else mission(text)
    return str(exc.value)


def test_two_regions_driving_the_same_part_are_refused_at_load():
    msg = load_error(regions().replace("task: toy_watch", "task: toy_watch\n              ")
                     .replace("watch:\n          initial: look", "watch:\n          owns: [v]\n          initial: look"))
    assert "par.yaml:" in msg and "regions 'drive' and 'watch' both drive 'v'" in msg


def test_an_unknown_command_part_is_refused_with_the_robots_parts():
    msg = load_error(regions().replace("owns: [v]", "owns: [base_twist]"))
    assert "the robot's command has no part 'base_twist'" in msg and "v" in msg


def test_entering_a_region_state_from_outside_is_refused():
    text = regions().replace("transitions: [{to: halted, after: 1 s}]",
                                                  "transitions: [{to: work.watch.look, after: 1 s}]")
    msg = load_error(text)
    assert "'work.watch.look' is inside region 'work.watch'" in msg and "target 'work'" in msg


def test_same_metric_from_two_regions_is_refused():
    msg = load_error(regions().replace("task: toy_watch", "task: {name: toy_goto, params: {target: 2}}"
                                                           ).replace('"x_abs > 5 m"', '"pos_error > 5 m"')
                     .replace("          initial: look", "          initial: look\n          bind: {gains: slow}"))
    assert "both run tasks that publish the metric 'pos_error'" in msg


def test_outcome_map_names_real_regions_and_outcomes_must_be_handled():
    assert "'c' is not a region of this state" in load_error(
        TIMED.replace("A_AFTER", "1 s").replace("B_AFTER", "1 s").replace("A_OUTCOME", "succeeded")
        .replace("B_OUTCOME", "succeeded").replace("OUTCOME_MAP", "outcome_map: {failed: {c: failed}}"))
    text = (TIMED.replace("A_AFTER", "1 s").replace("B_AFTER", "1 s").replace("A_OUTCOME", "succeeded")
            .replace("B_OUTCOME", "aborted").replace("OUTCOME_MAP", ""))
    msg = load_error(text)
    assert "can finish aborted" in msg and "region 'b'" in msg


def test_regions_and_states_together_are_refused():
    msg = load_error(TIMED.replace("A_AFTER", "1 s").replace("B_AFTER", "1 s").replace("A_OUTCOME", "succeeded")
                     .replace("B_OUTCOME", "succeeded").replace("OUTCOME_MAP", "initial: x\n      states: {x: {final: true}}"))
    assert "cannot also have `states`" in msg


def test_history_above_a_parallel_state_resumes_it_afresh():
    m = mission("""
machine:
  initial: outer
  states:
    outer:
      history: true
      initial: both
      transitions: [{to: pause, on: target_lost}]
      states:
        both:
          regions:
            a: {initial: a1, states: {a1: {transitions: [{to: a2, after: 1 s}]}, a2: {transitions: [{to: a_end, after: 10 s}]}, a_end: {final: true}}}
            b: {initial: b1, states: {b1: {transitions: [{to: b_end, after: 10 s}]}, b_end: {final: true}}}
          transitions: [{to: fin, done: succeeded}]
        fin: {final: true}
      transitions_placeholder: 0
    pause:
      transitions: [{to: outer, after: 1 s}]
""".replace("      transitions_placeholder: 0\n", "").replace("""      transitions: [{to: pause, on: target_lost}]
      states:""", """      transitions:
        - {to: pause, on: target_lost}
        - {to: end, done: succeeded}
      states:""") + "    end: {final: true}\n")
    r = drive(m, Script(events=[(2.0, "target_lost")]), max_time=4.0)
    targets = [(round(rec.t, 3), rec.target, rec.resumed) for rec in r.executor.transitions_fired]
    assert (3.0, "outer.both", True) in targets  # resumed to the parallel state; its regions start again
    assert r.executor.state == "outer.both.a.a1|outer.both.b.b1"


def test_graphs_draw_regions_as_concurrent_blocks():
    from taskflow.catalogue.graph import to_dot, to_mermaid

    m = timed("1 s", "1 s")
    mer = to_mermaid(m)
    assert 'state "both [parallel]" as both {' in mer and "\n        --\n" in mer
    assert 'state "a [region: commands nothing]" as both__a {' in mer
    dot = to_dot(m)
    assert 'label="a (region: commands nothing)";' in dot and "style=dashed;" in dot
    assert '"both__a__a1" -> "__start__both__b" [style=invis, weight=0];' in dot  # region b stacked below a


def test_an_operator_preempts_into_a_parallel_state_but_not_into_one_region():
    from taskflow.operate.control import ControlError, OperatorAction

    text = TIMED.replace("A_AFTER", "5 s").replace("B_AFTER", "5 s").replace("A_OUTCOME", "succeeded") \
        .replace("B_OUTCOME", "succeeded").replace("OUTCOME_MAP", "") + "    again:\n      transitions: [{to: both, after: 1 s}]\n"
    mission_ = mission(text.replace("- {to: bad, done: failed}", "- {to: bad, done: failed}\n        - {to: again, after: 9 s}"))
    r = drive(mission_, Script(), max_time=2.0, operator=[OperatorAction(t=1.0, action="preempt", args={"to": "again"}),
                                                            OperatorAction(t=1.5, action="preempt", args={"to": "both"})])
    assert [(round(rec.t, 3), rec.target) for rec in r.executor.transitions_fired][-2:] == [(1.0, "again"), (1.5, "both")]
    assert r.executor.state == "both.a.a1|both.b.b1"  # every region entered again
    with pytest.raises(ControlError, match="inside a parallel region"):
        drive(mission_, Script(), max_time=2.0, operator=[OperatorAction(t=1.0, action="preempt", args={"to": "both.a.a1"})])


def test_data_written_in_one_region_is_not_on_the_path_into_another():
    text = """
machine:
  initial: both
  states:
    both:
      regions:
        a:
          owns: [v]
          initial: mark
          states:
            mark: {task: toy_mark, transitions: [{to: a_end, after: 1 s}]}
            a_end: {final: true}
        b:
          initial: back
          states:
            back:
              task: toy_return
              bind: {gains: slow}
              transitions: [{to: b_end, after: 1 s}]
            b_end: {final: true}
      transitions: [{to: ok, done: succeeded}]
    ok: {final: true}
"""
    msg = load_error(text)
    assert "reads mission data 'toy.mark', which is not written on every path into state 'both.b.back'" in msg
    assert "not on (start) → both.b.back" in msg  # the regions are entered together: region a has not run yet
