"""Loops whose items may fail, nested loops, deadlines across re-entries, and event + condition
transitions — each driven through the real machine with the scripted backend."""

from __future__ import annotations

import pytest

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, assert_outcome, assert_path, drive

HEAD = """
mission: m
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 200 s
"""


def test_nested_foreach_restarts_the_inner_loop_for_every_outer_item() -> None:
    """An outer × inner 2 × 3 loop visits every pair in order; each iteration record has its own index."""
    m = load_mission_text(HEAD + """
parameters: {rows: [1, 2], cols: [10, 20, 30]}
machine:
  initial: outer
  states:
    outer:
      foreach: {in: rows, as: row}
      initial: inner
      transitions: [{to: done, done: succeeded}]
      states:
        inner:
          foreach: {in: cols, as: col}
          initial: work
          transitions: [{to: row_done, done: succeeded}]
          states:
            work: {transitions: [{to: cell_done, after: 0.1 s}]}
            cell_done: {final: succeeded}
        row_done: {final: succeeded}
    done: {final: succeeded}
""", "nested.yaml")
    seen: list[tuple[float, float]] = []

    def metrics(s):  # type: ignore[no-untyped-def]
        if s.state == "outer.inner.work" and (not seen or seen[-1] != (s.items["row"], s.items["col"])):
            seen.append((s.items["row"], s.items["col"]))
        return {}

    r = drive(m, Script(metrics=metrics))
    assert_outcome(r, "succeeded")
    assert seen == [(1, 10), (1, 20), (1, 30), (2, 10), (2, 20), (2, 30)]
    inner = [(it["index"], it["item"]) for it in r.summary["iterations"] if it["state"] == "outer.inner"]
    assert inner == [(0, 10), (1, 20), (2, 30)] * 2
    assert [it["index"] for it in r.summary["iterations"] if it["state"] == "outer"] == [0, 1]
    assert r.summary["items"]["outer.inner"]["attempted"] == 6


LOOP = HEAD + """
parameters: {screws: [a, b, c, d]}
machine:
  initial: screws
  states:
    screws:
      foreach: {in: screws, as: screw, on_failure: continue%s}
      initial: work
      transitions:
        - {to: done, done: succeeded}
        - {to: error, done: failed}
      states:
        work:
          action: {name: tool, params: {ok: $screw}}
          transitions:
            - {to: fastened, on: tool_done}
            - {to: missed, on: tool_failed}
        fastened: {final: succeeded}
        missed: {final: failed}
    done: {final: succeeded}
    error: {final: failed}
"""


def _tool(params):  # type: ignore[no-untyped-def]
    return (0.2, "tool_done" if params["ok"] in ("a", "c") else "tool_failed")  # b and d fail


@pytest.mark.parametrize("rule, outcome", [("", "failed"), (", require: all", "failed"), (", require: 2", "succeeded"),
                                           (", require: 3", "failed"), (", require: '50 %'", "succeeded"),
                                           (", require: '51 %'", "failed")])
def test_a_loop_succeeds_only_when_its_rule_holds(rule: str, outcome: str) -> None:
    r = drive(load_mission_text(LOOP % rule, "loop.yaml"), Script(actions={"tool": _tool}))
    assert_outcome(r, outcome)
    assert [it["outcome"] for it in r.summary["iterations"]] == ["succeeded", "failed", "succeeded", "failed"]
    items = r.summary["items"]["screws"]
    assert (items["attempted"], items["succeeded"], items["failed"], items["success_rate"]) == (4, 2, 2, 0.5)
    if outcome == "failed":
        assert "2 of 4 items succeeded" in r.summary["reason"]


def test_a_loop_rule_is_checked_at_load() -> None:
    with pytest.raises(MissionError, match="has only 4 items") as exc:
        load_mission_text(LOOP % ", require: 5", "loop.yaml")
    assert exc.value.first.line == 13  # the foreach line
    with pytest.raises(MissionError, match="on_failure: stop"):
        load_mission_text((LOOP % ", require: 2").replace("on_failure: continue", "on_failure: stop"), "loop.yaml")
    with pytest.raises(MissionError, match="is not 'all', a number of items"):
        load_mission_text(LOOP % ", require: most", "loop.yaml")


def test_validate_reports_a_loop_outcome_no_done_transition_handles() -> None:
    """Items may fail and the loop go on; at the end it can finish failed: without a `done` for that
    outcome the file is refused (it used to load and stop the run with 'no done transition handles it')."""
    text = (LOOP % "").replace("        - {to: error, done: failed}\n", "")
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "loop.yaml")
    p = exc.value.first
    assert "can finish failed" in p.message and "done: failed" in p.hint and p.line == 12


PAUSES = HEAD + """
machine:
  initial: job
  states:
    job:
      initial: work
      states:
        work:
          transitions:
            - {to: pause, after: 12 s}
            - {to: stuck, after: 30 s%s}
        pause:
          transitions: [{to: work, after: 1 s}]
      transitions: [{to: stuck, after: 500 s}]
    stuck: {final: failed}
"""


def test_after_restarts_on_every_entry_so_a_repeating_pause_defeats_it() -> None:
    r = drive(load_mission_text(PAUSES % "", "p.yaml"), Script(), max_time=100)
    assert_outcome(r, "timeout")  # the statechart rule: `after` counts from the last entry


@pytest.mark.parametrize("since, fires_at", [("first_entry", 30.0), ("job", 30.0)])
def test_since_bounds_time_across_re_entries(since: str, fires_at: float) -> None:
    r = drive(load_mission_text(PAUSES % f", since: {since}", "p.yaml"), Script(), max_time=100)
    assert_outcome(r, "failed")
    stuck = [rec for rec in r.executor.transitions_fired if rec.target == "stuck"]
    # 0-12 work, 12-13 pause, 13-25 work, 25-26 pause, 26-30 work → stuck at 30 s from the first entry
    assert stuck[0].t == pytest.approx(fires_at) and stuck[0].cause == "timeout"
    assert stuck[0].state == "job.work" and stuck[0].label == f"after 30 s since {since}"


def test_since_first_entry_is_kept_across_a_history_resume_and_reset_by_a_fresh_entry() -> None:
    m = load_mission_text(HEAD + """
machine:
  initial: operate
  states:
    operate:
      history: true
      initial: work
      transitions:
        - {to: searching, on: target_lost}
        - {to: restart, on: target_found}
        - {to: gave_up, done: failed}
      states:
        work: {transitions: [{to: late, after: 10 s, since: first_entry}]}
        late: {final: failed}
    searching: {transitions: [{to: operate, after: 2 s}]}
    restart: {transitions: [{to: operate, after: 1 s, resume: false}]}
    gave_up: {final: failed}
""", "h.yaml")
    # lost at 4 s, resumed by history at 6 s: still 10 s from the first entry → late at 10 s
    r = drive(m, Script(events=[(4.0, "target_lost")]), max_time=30)
    assert [rec.t for rec in r.executor.transitions_fired if rec.target == "operate.late"] == [pytest.approx(10.0)]
    # a fresh entry (resume: false) at 5 s starts the clock again → late at 15 s
    r = drive(m, Script(events=[(4.0, "target_found")]), max_time=30)
    assert [rec.t for rec in r.executor.transitions_fired if rec.target == "operate.late"] == [pytest.approx(15.0)]


def test_since_must_name_an_enclosing_state() -> None:
    with pytest.raises(MissionError, match="since 'stuck'") as exc:
        load_mission_text(PAUSES % ", since: stuck", "p.yaml")
    assert "first_entry" in exc.value.first.hint
    with pytest.raises(MissionError, match="'since' only goes with 'after'"):
        load_mission_text(PAUSES.replace("{to: pause, after: 12 s}", "{to: pause, on: target_lost, since: job}") % "",
                          "p.yaml")


EVENT_COND = HEAD + """
parameters: {goal: 1.0}
profiles: {gains: {g: {kp: 1.0}}}
machine:
  initial: wait
  states:
    wait:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: g}
      transitions:
        - {to: done, on: target_found, when: "pos_error < 5 cm"}
    done: {final: succeeded}
"""


def test_an_event_with_a_condition_fires_only_when_both_hold() -> None:
    m = load_mission_text(EVENT_COND, "ec.yaml")
    far = {"pos_error": 0.5}
    near = {"pos_error": 0.01}
    script = Script(metrics=lambda s: near if s.t >= 3.0 else far,
                    events=[(1.0, "target_found"), (2.5, "target_found"), (4.0, "target_found")])
    r = drive(m, script, max_time=10)
    assert_outcome(r, "succeeded")
    fired = [rec for rec in r.executor.transitions_fired if rec.target == "done"]
    assert fired[0].t == pytest.approx(4.0)  # the events at 1 and 2.5 s found the condition false
    assert (fired[0].cause, fired[0].event, fired[0].label) == ("event", "target_found",
                                                                "on target_found when pos_error < 5 cm")
    assert fired[0].metrics == {"pos_error": pytest.approx(0.01)}  # the value that satisfied the condition
    # the condition alone does not fire it either
    r = drive(m, Script(metrics=lambda s: near), max_time=5)
    assert_outcome(r, "timeout")


def test_an_event_condition_is_checked_like_any_guard_and_takes_no_dwell() -> None:
    with pytest.raises(MissionError, match="metric 'pos_eror'"):
        load_mission_text(EVENT_COND.replace("pos_error < 5 cm", "pos_eror < 5 cm"), "ec.yaml")
    with pytest.raises(MissionError, match="an event has no duration"):
        load_mission_text(EVENT_COND.replace('when: "pos_error < 5 cm"', 'when: "pos_error < 5 cm", for: 1 s'), "ec.yaml")


def test_history_takes_only_true_or_false() -> None:
    """`history: yes` was read as true by the loader while the published JSON Schema refused it."""
    text = PAUSES.replace("    job:\n", "    job:\n      history: yes\n") % ""
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "p.yaml")
    assert "boolean" in exc.value.first.message and exc.value.first.line == 12
    assert "write true or false" in exc.value.first.hint


def test_a_finished_mission_ends_with_the_safe_stop_whatever_its_outcome() -> None:
    for outcome in ("succeeded", "failed"):
        text = HEAD + f"""
machine:
  initial: a
  states:
    a: {{transitions: [{{to: z, after: 1 s}}]}}
    z: {{final: {outcome}}}
"""
        worlds = []
        r = drive(load_mission_text(text, "s.yaml"), Script(), on_world=worlds.append)
        assert_outcome(r, outcome)
        assert r.summary["stopped_at_s"] == pytest.approx(2.0)
        assert len(worlds[0].applied) == r.summary["ticks"] + 20  # one stop command per tick of the 1 s stop


def test_assert_path_still_reads_the_nested_run() -> None:
    m = load_mission_text(LOOP % ", require: 2", "loop.yaml")
    r = drive(m, Script(actions={"tool": _tool}))
    assert_path(r, ["screws.work", "screws.fastened", "screws.work", "screws.missed"], exact=False)
