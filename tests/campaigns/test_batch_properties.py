"""``taskflow batch`` reports each declared property's violation rate with its Wilson interval, in
``batch.json`` and in its table; a mission without properties writes no such key."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskflow.campaigns.batch import aggregate, format_table, run_batch
from taskflow.campaigns.stats import wilson_interval

pytestmark = pytest.mark.machine

TOY = Path(__file__).resolve().parents[1] / "machine" / "missions" / "toy_full.yaml"
PROPS = """properties:
  near_when_settling: {never: "state(operate.visit.settle)", while: "pos_error > 5 cm"}
  always_near: {always: "pos_error < 0.5 m"}
  tool_after_approach: {only_after: "state(operate.visit.approach)", occurs: "event(tool_done)"}
"""


def test_batch_json_and_table_give_each_property_its_violation_rate(tmp_path: Path) -> None:
    mission = tmp_path / "toy_props.yaml"
    mission.write_text(TOY.read_text().replace("machine:\n", PROPS + "machine:\n", 1))
    result = run_batch(str(mission), trials=3, workers=1, out=tmp_path / "batch")
    props = json.loads((tmp_path / "batch" / "batch.json").read_text())["aggregate"]["properties"]
    assert props["near_when_settling"] == {"pattern": "absence", "held": 3, "violated": 0, "not_decided": 0,
                                           "violation_rate": 0.0, "violation_ci95": list(wilson_interval(0, 3))}
    always = props["always_near"]  # the first goal is 1 m away: broken in the first tick of every trial
    assert (always["violated"], always["violation_rate"], always["first_violation_t"]) == (3, 1.0, 0.0)
    assert props["tool_after_approach"]["violated"] == 0
    table = format_table(result)
    low, high = wilson_interval(3, 3)
    assert f"property always_near (universality): violated in 3/3 = 100.0 % [{100 * low:.1f}, {100 * high:.1f}]" \
           " (95 % Wilson)" in table


def test_not_decided_trials_are_counted_apart_and_no_properties_no_key() -> None:
    summaries = [{"outcome": "timeout", "sim_time_s": 1.0, "properties": {"r": {"pattern": "response",
                                                                                 "verdict": v, "t": None}}}
                 for v in ("held", "violated", "not_decided", "not_decided")]
    agg = aggregate(summaries)
    assert agg["properties"]["r"]["violation_rate"] == 0.5 and agg["properties"]["r"]["not_decided"] == 2
    assert "2 not decided" in "\n".join(format_table({"mission": "m", "aggregate": agg}).splitlines())
    assert "properties" not in aggregate([{"outcome": "succeeded", "sim_time_s": 1.0}])
