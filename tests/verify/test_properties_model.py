"""Declared properties decided on the model (``taskflow.verify.properties``): each pattern holding and failing on
a small machine, with the counterexample a path the engine follows; a property that compares metrics is left to
the runs' monitor."""

from __future__ import annotations

import pytest

from taskflow.mission.loader import load_mission_text
from taskflow.verify import verify_mission

pytestmark = pytest.mark.machine

HEAD = """mission: props
robot: racecar
world: viki_ground
rate_hz: 20
profiles:
  viki_gains:
    front: {lam: [0.85, 0.3, 1.0, 1.0, 1.0], k1: [2.0, 1.0]}
properties:
PROPS
machine:
  initial: approach
  states:
    approach:
      task: {name: viki_hyco, params: {camera: front, desired: [1.0, 0.0], mode: hybrid}}
      bind: {gains: front}
      transitions:
        - {to: searching, on: target_lost}
        - {to: done, when: "feature_error < 2 px", for: 0.3 s}
        - {to: failed, after: 20 s}
    searching:
      transitions:
        - {to: approach, on: target_found}
        - {to: failed, after: 5 s}
    done: {final: succeeded}
    failed: {final: failed}
"""


def check(props: str) -> dict[str, object]:
    v = verify_mission(load_mission_text(HEAD.replace("PROPS", props), "props.yaml"))
    return {c.name.removeprefix("property:"): c for c in v.checks if c.name.startswith("property:")}


@pytest.mark.parametrize(("prop", "verdict"), [
    ('never: "state(searching) and outcome(succeeded)"', "holds"),
    ('never: "state(done)"\n    while: "state(approach)"', "holds"),
    ('never: "outcome(failed)"', "fails"),  # the timeouts lead there
    ('always: "state(approach) or state(searching) or outcome(succeeded) or outcome(failed)"', "holds"),
    ('always: "state(approach)"', "fails"),
    ('only_after: "state(approach)"\n    occurs: "state(searching)"', "holds"),
    ('only_after: "state(searching)"\n    occurs: "outcome(succeeded)"', "fails"),  # done straight from approach
    ('after: "event(target_lost)"\n    within: 0.05 s\n    then: "state(searching) or outcome(failed)"', "holds"),
    ('after: "event(target_lost)"\n    within: 30 s\n    then: "outcome(succeeded)"', "fails"),
    ('after: "state(searching)"\n    within: 2 s\n    then: "state(approach)"', "fails"),  # it may wait 5 s
    ('after: "state(searching)"\n    within: 5 s\n    then: "state(approach) or outcome(failed)"', "holds"),
    ('never: "feature_error > 100 px"', "monitored"),
])
def test_each_pattern_on_the_model(prop: str, verdict: str) -> None:
    got = check(f"  p:\n    {prop}")["p"]
    assert got.verdict == verdict, got.detail  # type: ignore[attr-defined]
    if verdict == "fails":
        cex = got.counterexample  # type: ignore[attr-defined]
        assert cex is not None
        replay = cex.replay()
        assert replay.followed, replay.describe()


def test_a_response_to_an_event_is_taken_in_the_same_control_period() -> None:
    """`target_lost` in `approach` fires its transition before any time passes: within one control period the
    machine is in `searching` — not after a tick of the model (5 s here)."""
    got = check('  p:\n    after: "event(target_lost)"\n    within: 0.05 s\n    then: "state(searching)"')["p"]
    assert got.verdict == "holds", got.detail  # type: ignore[attr-defined]


def test_a_recorded_run_that_violates_a_property_is_still_a_path_of_the_model(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The monitor's violation record sits among the transitions in `transitions.jsonl`; the model follows the run
    through it, and the property the model refuted is the one the run's monitor reports violated."""
    import json

    from taskflow.testing import Script, drive
    from taskflow.verify.model import build_model

    mission = load_mission_text(HEAD.replace("PROPS", '  p:\n    always: "state(approach)"'), "props.yaml")
    result = drive(mission, Script(events=[(1.0, "target_lost"), (2.0, "target_found")]), max_time=4.0, out_dir=tmp_path)
    records = [json.loads(line) for line in (tmp_path / "transitions.jsonl").read_text().splitlines()]
    assert any(r["cause"] == "property" for r in records) and result.summary["properties"]["p"]["verdict"] == "violated"
    build_model(mission).path_of(records, outcome=result.outcome)
    assert verify_mission(mission).check("property:p").verdict == "fails"
