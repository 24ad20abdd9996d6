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
