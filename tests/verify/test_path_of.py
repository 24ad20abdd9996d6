"""``Model.path_of`` is a real check, not a sieve that lets everything through: records the engine could not have
written — a timeout a tick early, a guard to a state it does not lead to, an event from a state that cannot
receive it, a run that ends with another outcome — are refused, naming the record."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from taskflow.mission.loader import load_mission
from taskflow.testing import Script, drive
from taskflow.verify.model import NotAPath, build_model

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]


def _run() -> tuple[Any, list[dict[str, Any]], str]:
    """ViKi-HyCo on the scripted backend: forward converges after 2 s, then the rotation times out (40 s)."""
    mission = load_mission(ROOT / "missions" / "viki_hyco.yaml")

    def metrics(s: Any) -> dict[str, float]:
        if s.state == "forward" and s.time_in_state > 2.0:
            return {"feature_error": 0.0, "detection_age": 0.0}
        return {}

    result = drive(mission, Script(metrics=metrics), max_time=200)
    assert result.executor is not None
    return mission, [r.as_dict() for r in result.executor.transitions_fired], str(result.outcome)


def test_the_real_run_is_a_path_and_each_forgery_is_refused() -> None:
    mission, records, outcome = _run()
    model = build_model(mission)
    assert [r["cause"] for r in records] == ["start", "guard", "timeout"], records
    model.path_of(records, outcome=outcome)  # the run itself
    violated = {"t": records[1]["t"], "cause": "property", "property": "p", "pattern": "absence", "verdict": "violated",
                "state": "forward", "atoms": {}}
    model.path_of([records[0], records[1], violated, *records[2:]], outcome=outcome)  # a violation is no firing

    early = copy.deepcopy(records)
    early[2]["t"] -= model.quantum  # the rotation's timeout one tick early
    with pytest.raises(NotAPath, match="record 3"):
        model.path_of(early)

    elsewhere = copy.deepcopy(records)
    elsewhere[1]["to"] = "backward"  # forward's guard does not lead there
    with pytest.raises(NotAPath, match="record 2"):
        model.path_of(elsewhere)

    foreign = copy.deepcopy(records)
    foreign[1].update(cause="event", event="no_target", to="no_target", index=None)  # fine: forward receives it
    model.path_of(foreign[:2])
    foreign[2].update(cause="event", event="no_target", to="no_target", index=None)  # rotate has no such transition
    with pytest.raises(NotAPath, match="record 3"):
        model.path_of(foreign[:3])

    with pytest.raises(NotAPath, match="ended 'succeeded'"):
        model.path_of(records, outcome="succeeded")


RETRY = """
mission: m
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 60 s
parameters: {xs: [1, 2]}
machine:
  initial: loop
  states:
    loop:
      foreach: {in: xs, as: x, on_failure: continue, require: 1, retry: 1}
      initial: work
      transitions: [{to: done, done: succeeded}, {to: gave_up, done: failed}]
      states:
        work: {transitions: [{to: ok, on: go_on}, {to: missed, after: 1 s}]}
        ok: {final: succeeded}
        missed: {final: failed}
    done: {final: succeeded}
    gave_up: {final: failed}
events: [go_on]
"""


def test_a_retry_is_a_step_of_the_model_and_a_retry_past_the_budget_is_refused() -> None:
    """The model keeps the item's attempt: the first item misses twice (a retry, then it counts failed), the
    second succeeds; a forged third attempt of an item that has had its one retry is refused."""
    from taskflow.mission.loader import load_mission_text

    mission = load_mission_text(RETRY, "retry.yaml")
    model = build_model(mission)
    assert {c.loops[0][2] for c in model.configs} == {1, 2}  # the attempt is part of the configuration
    result = drive(mission, Script(events=[(2.5, "go_on")]), max_time=60)
    records = [r.as_dict() for r in result.executor.transitions_fired]
    assert [r["cause"] for r in records] == ["start", "timeout", "retry", "timeout", "next_item", "event", "done"]
    model.path_of(records, outcome=str(result.outcome))
    forged = copy.deepcopy(records[:4])
    forged += [{**records[2], "t": records[3]["t"], "attempt": 3}]  # a second retry of item 0 (retry: 1)
    with pytest.raises(NotAPath, match="record 4 "):  # the timeout's step: it ends the item, not a retry
        model.path_of(forged)
