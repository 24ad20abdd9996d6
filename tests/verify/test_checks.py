"""taskflow verify's checks on small machines with one planted defect each (toy world, real loader and Storm):
the check that must fail fails, with a counterexample the real engine follows (scripted backend), and the
others hold.  The shipped missions are checked in ``test_shipped.py``; the generated corpus in ``test_corpus.py``."""

from __future__ import annotations

import pytest

from taskflow.mission.loader import load_mission_text
from taskflow.verify import verify_mission

pytestmark = pytest.mark.machine

HEAD = """
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 60 s
parameters: {tol: 1 cm, items: [1, 2, 3]}
"""


def verdicts(machine: str) -> tuple[dict[str, str], object]:
    v = verify_mission(load_mission_text(HEAD + machine, "planted.yaml"))
    return {c.name: c.verdict for c in v.checks}, v


SEARCH_NO_TIMEOUT = """
machine:
  initial: approach
  states:
    approach:
      transitions:
        - {to: searching, on: target_lost}
        - {to: done, when: "visible > 0.5"}
        - {to: failed, after: 20 s}
    searching:
      transitions:
        - {to: approach, on: target_found}
    done: {final: succeeded}
    failed: {final: failed}
"""


def test_a_search_state_without_timeout_waits_forever_under_sensor_loss() -> None:
    got, v = verdicts(SEARCH_NO_TIMEOUT)
    assert got == {"no_trap": "holds", "timed_exit": "fails", "duration": "fails", "outcomes": "holds",
                   "region_conflicts": "holds"}
    check = v.check("timed_exit")  # type: ignore[attr-defined]
    assert check.data["waits_forever"] == ["searching"]
    cex = check.counterexample
    assert [c for c, _ in cex.path[0][1].records] == ["event"] and cex.path[0][1].event == "target_lost"
    assert "waits in searching forever" in cex.render()
    replay = cex.replay()
    assert replay.followed, replay.describe()
    assert replay.result.summary["states_visited"] == ["approach", "searching"]
    assert replay.result.outcome == "timeout"  # the engine did wait in `searching` until the run's max time


def test_with_the_timeout_it_holds_and_the_duration_is_the_sum_of_the_timers() -> None:
    fixed = SEARCH_NO_TIMEOUT.replace("        - {to: approach, on: target_found}\n",
                                      "        - {to: approach, on: target_found}\n        - {to: failed, after: 5 s}\n")
    got, v = verdicts(fixed)
    assert set(got.values()) == {"holds"}
    d = v.check("duration")  # type: ignore[attr-defined]
    assert d.data["from_start_s"] == 20.0  # with every guard false the approach times out at 20 s
    assert d.data["worst_s"] == 20.0


LOOP_NO_EXIT = """
machine:
  initial: a
  states:
    a:
      transitions:
        - {to: b, when: "visible > 0.5"}
        - {to: done, after: 5 s}
    b:
      transitions:
        - {to: c, after: 1 s}
    c:
      transitions:
        - {to: b, after: 1 s}
    done: {final: succeeded}
"""


def test_a_loop_with_no_exit_is_a_trap() -> None:
    got, v = verdicts(LOOP_NO_EXIT)
    assert got["no_trap"] == "fails" and got["timed_exit"] == "fails" and got["duration"] == "fails"
    cex = v.check("no_trap").counterexample  # type: ignore[attr-defined]
    assert "b, c" in cex.ending
    replay = cex.replay()
    assert replay.followed, replay.describe()
    t = v.check("timed_exit")  # type: ignore[attr-defined]
    assert "cycles through b, c" in t.counterexample.ending


REQUIRE_NEVER = """
machine:
  initial: each
  states:
    each:
      foreach: {in: items, as: it, on_failure: continue, require: 2}
      initial: work
      states:
        work:
          transitions:
            - {to: check, when: "visible > 0.5"}
            - {to: bad, on: target_lost}
        check:
          transitions:
            - {to: ok, after: 3 s}   # never first: the loop's own 2 s budget runs out before
        ok: {final: succeeded}
        bad: {final: failed}
      transitions:
        - {to: failed, after: 2 s}
        - {to: done, done: succeeded}
        - {to: failed, done: failed}
    done: {final: succeeded}
    failed: {final: failed}
"""


def test_a_require_rule_that_can_never_hold_leaves_succeeded_unreachable() -> None:
    got, v = verdicts(REQUIRE_NEVER)
    assert got == {"no_trap": "holds", "timed_exit": "holds", "duration": "holds", "outcomes": "fails",
                   "region_conflicts": "holds"}
    assert "never reached: succeeded" in v.check("outcomes").detail  # type: ignore[attr-defined]
