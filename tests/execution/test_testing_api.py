"""The testing API as documented: every field of :class:`RunResult` and every key of the summary a run
returns is described in its docstring and in docs/missions.md ("Testing a mission")."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from taskflow.execution.summary import RunResult
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, assert_outcome, drive

ROOT = Path(__file__).resolve().parents[2]
TOY = """
mission: toy
robot: racecar
world: flat_ground
rate_hz: 20
parameters:
  goals: [[1.0, 0.0], [2.0, 0.0]]
machine:
  initial: go
  states:
    go:
      foreach: {in: goals, as: goal}
      initial: move
      transitions: [{to: done, done: succeeded}]
      states:
        move:
          task: {name: car_goto, params: {target: $goal}}
          transitions: [{to: ok, when: "pos_error < 1 cm"}]
        ok: {final: succeeded}
    done: {final: succeeded}
"""


def _testing_section() -> str:
    text = (ROOT / "docs" / "missions.md").read_text()
    return text[text.index("## Testing a mission"):]


def test_every_field_and_summary_key_of_a_run_result_is_documented() -> None:
    r = drive(load_mission_text(TOY), Script(metrics=lambda s: {"pos_error": 0.0}), max_time=5)
    assert_outcome(r, "succeeded")
    fields = [f.name for f in dataclasses.fields(RunResult)] + ["succeeded"]
    source_doc = RunResult.__doc__ or ""
    docs = _testing_section()
    table = set(re.findall(r"^\| `(\w+)` \|", docs, re.M))
    assert set(fields) <= table, set(fields) - table
    for key in r.summary:
        assert f"``{key}``" in source_doc, f"summary key {key!r} not in RunResult's docstring"
        assert f"`{key}`" in docs, f"summary key {key!r} not in docs/missions.md's Testing section"
    assert r.summary["states_visited"] == ["go.move", "go.ok", "go.move", "go.ok", "done"]
    assert r.run_dir is None and r.executor is not None and r.succeeded
