"""Loops that retry (``foreach: {retry: …}``, issue 25): a failed item runs again from the sub-machine's
initial state before it counts, each attempt a ``retry`` record; the item counts on its last attempt —
driven through the real machine with the scripted backend."""

from __future__ import annotations

from collections import Counter

import pytest

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, assert_outcome, drive

HEAD = """
mission: m
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 200 s
"""

LOOP = HEAD + """
parameters: {screws: [a, b, c]}
machine:
  initial: screws
  states:
    screws:
      foreach: {in: screws, as: screw, on_failure: continue, retry: %s}
      initial: work
      transitions:
        - {to: done, done: succeeded}
        - {to: error, done: failed}
      states:
        work:
          action: {name: tool, params: {ok: $screw}}
          transitions:
            - {to: settle, on: tool_done}
            - {to: missed, on: tool_failed}
            - {to: stopped, after: 5 s, since: first_entry}
        settle: {transitions: [{to: fastened, after: 0.5 s}]}
        fastened: {final: succeeded}
        missed: {final: failed}
        stopped: {final: aborted}
    done: {final: succeeded}
    error: {final: failed}
"""


def _failing(times: dict[str, int]):  # type: ignore[no-untyped-def]
    """A tool that fails screw ``s`` on its first ``times[s]`` activations, then fastens it."""
    calls: Counter[str] = Counter()

    def tool(params):  # type: ignore[no-untyped-def]
        calls[params["ok"]] += 1
        return 0.2, "tool_failed" if calls[params["ok"]] <= times.get(params["ok"], 0) else "tool_done"
    return tool


def _records(r):  # type: ignore[no-untyped-def]
    return [rec.as_dict() for rec in r.executor.transitions_fired]


def test_a_failed_item_runs_again_and_counts_on_its_last_attempt() -> None:
    r = drive(load_mission_text(LOOP % "2", "retry.yaml"), Script(actions={"tool": _failing({"b": 2})}))
    assert_outcome(r, "succeeded")
    retries = [rec for rec in _records(r) if rec["cause"] == "retry"]
    assert [(x["from"], x["to"], x["state"], x["item"], x["attempt"], x["outcome"]) for x in retries] == [
        ("screws.missed", "screws.work", "screws", 1, 2, "failed"),
        ("screws.missed", "screws.work", "screws", 1, 3, "failed")]
    its = r.summary["iterations"]
    assert [(it["index"], it["outcome"], it["attempts"], it["retried"]) for it in its] == [
        (0, "succeeded", 1, []), (1, "succeeded", 3, ["missed", "missed"]), (2, "succeeded", 1, [])]
    items = r.summary["items"]["screws"]
    assert (items["attempted"], items["succeeded"], items["failed"], items["attempts"], items["retried"],
            items["recovered"]) == (3, 3, 0, 5, 1, 1)
    # the loop's next item comes after the retried one's last attempt, not after its first failure
    assert [x["item"] for x in _records(r) if x["cause"] == "next_item"] == [1, 2]


def test_an_item_out_of_attempts_counts_failed_and_the_loop_rule_sees_only_that() -> None:
    r = drive(load_mission_text(LOOP % "1", "retry.yaml"), Script(actions={"tool": _failing({"b": 5})}))
    assert_outcome(r, "failed")
    assert [x["attempt"] for x in _records(r) if x["cause"] == "retry"] == [2]
    assert [(it["outcome"], it["attempts"]) for it in r.summary["iterations"]] == [
        ("succeeded", 1), ("failed", 2), ("succeeded", 1)]
    assert "2 of 3 items succeeded" in r.summary["reason"]
    assert r.summary["items"]["screws"]["failed"] == 1


def test_a_retry_enters_the_sub_machine_afresh_its_first_entry_clocks_included() -> None:
    """``after 5 s since first_entry`` is measured from each attempt's start, as from each item's."""
    r = drive(load_mission_text(LOOP % "1", "retry.yaml"), Script(actions={"tool": _failing({"a": 1})}))
    assert_outcome(r, "succeeded")
    assert not [x for x in _records(r) if x["to"] == "screws.stopped"]
    retry = next(x for x in _records(r) if x["cause"] == "retry")
    work = [rec for rec in r.executor.transitions_fired if rec.target == "screws.work"]
    assert retry["t"] == pytest.approx(work[1].t) and r.executor.iteration == {"screws": 2}


def test_retry_on_restricts_the_final_states_retried_and_aborted_is_not_retried_by_default() -> None:
    stuck = Script(actions={"tool": lambda params: (60.0, "tool_done")})  # never ends within 5 s: aborted
    r = drive(load_mission_text(LOOP % "2", "retry.yaml"), stuck)
    assert not [x for x in _records(r) if x["cause"] == "retry"]
    r = drive(load_mission_text(LOOP % "{times: 1, on: [stopped]}", "retry.yaml"), stuck)
    assert [(x["from"], x["item"], x["outcome"]) for x in _records(r) if x["cause"] == "retry"] == [
        ("screws.stopped", i, "aborted") for i in range(3)]  # each item once (`on_failure: continue`)
    r = drive(load_mission_text(LOOP % "{times: 2, on: [stopped]}", "retry.yaml"),
              Script(actions={"tool": _failing({"a": 1})}))
    assert not [x for x in _records(r) if x["cause"] == "retry"]  # `missed` is not in `on`


def test_a_loop_without_retry_writes_no_attempts() -> None:
    r = drive(load_mission_text(LOOP.replace(", retry: %s", ""), "plain.yaml"), Script(actions={"tool": _failing({})}))
    assert "attempts" not in r.summary["iterations"][0] and "attempts" not in r.summary["items"]["screws"]


@pytest.mark.parametrize("retry, message, hint", [
    ("-1", "retry -1: an item may be attempted again 0 to 10 times", ""),
    ("{times: 11}", "retry 11: an item may be attempted again 0 to 10 times (every expansion has a budget)", ""),
    ("1.5", "retry 1.5 is not a number of further attempts", ""),
    ("{times: 1, on: [mised]}", "retry on 'mised' names no final state of the sub-machine", "missed"),
    ("{times: 1, on: [fastened]}", "that final state succeeds", "missed, stopped"),
    ("{times: 1, on: [work]}", "'work' is not a final state", ""),
    ("{times: 1, every: 2}", "unknown key 'every'", "times"),
])
def test_retry_is_checked_at_load(retry: str, message: str, hint: str) -> None:
    with pytest.raises(MissionError) as exc:
        load_mission_text(LOOP % retry, "retry.yaml")
    p = exc.value.first
    assert message in p.message and hint in p.hint
    assert p.line == 13  # the foreach line (flow style: every key of it is on that line)
