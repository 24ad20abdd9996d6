"""A `done` transition that re-enters a final state finishing its own source at the same instant is refused at
load, with its line (found by the abstraction test's generator: the engine ended such a run `aborted` with a
RecursionError and `taskflow verify` raised one)."""

from __future__ import annotations

import pytest

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission_text
from taskflow.verify import verify_mission

pytestmark = pytest.mark.machine

CASCADE = """mission: done_cascade
robot: toy_point
world: toy_line
rate_hz: 20
machine:
  initial: outer
  states:
    outer:
      initial: inner
      states:
        inner:
          initial: work
          states:
            work:
              transitions:
                - {to: outer.inner.ok, on: target_lost}
            ok: {final: succeeded}
          transitions:
            - {to: TARGET, done: succeeded}
      transitions:
        - {to: end, after: 5 s}
    end: {final: succeeded}
"""


def test_a_done_transition_into_its_own_final_state_is_refused_at_its_line() -> None:
    with pytest.raises(MissionError) as exc:
        load_mission_text(CASCADE.replace("TARGET", "outer.inner.ok"), "cascade.yaml")
    text = str(exc.value)
    assert text.startswith("cascade.yaml:19:15: this `done` transition enters 'outer.inner.ok'"), text
    assert "finishes 'outer.inner' again at once" in text


def test_the_same_machine_with_a_way_on_loads_and_verifies() -> None:
    mission = load_mission_text(CASCADE.replace("TARGET", "outer.inner.work"), "cascade.yaml")
    v = verify_mission(mission)  # each item starts over; the outer timeout ends the run
    assert v.ok and v.model.outcomes() == ["succeeded"], v.render()
