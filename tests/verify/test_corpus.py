"""The broken-mission corpus (``tests/verify/broken/*.yaml``): one mission per defect class of issue 22, each
caught by the check meant for it, with the other checks' verdicts as expected, and a counterexample the real
engine follows (its :meth:`~taskflow.verify.counterexample.Counterexample.script` driven through the scripted
backend visits the counterexample's states, in order).  A defect without a path to show (an outcome that is
never reached) is checked against the engine the other way: random runs never end with it.

Every shipped mission passing every check is ``test_shipped.py``'s."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from machines import random_script

from taskflow.mission.loader import load_mission
from taskflow.testing import drive
from taskflow.verify import verify_mission

pytestmark = pytest.mark.machine

BROKEN = Path(__file__).parent / "broken"
H, F = "holds", "fails"
CHECKS = ("no_trap", "timed_exit", "duration", "outcomes", "region_conflicts")

# file → (the check the defect is planted for, every check's verdict in CHECKS order)
CORPUS = {
    "search_no_timeout": ("timed_exit", (H, F, F, H, H)),
    "loop_no_exit": ("no_trap", (F, F, F, H, H)),
    "region_never_finishes": ("outcomes", (H, H, H, F, H)),
    "require_never": ("outcomes", (H, H, H, F, H)),
    "region_conflict": ("region_conflicts", (H, H, H, H, F)),
    "duration_unbounded": ("duration", (H, F, F, H, H)),
    "property_violated": ("property:screw_after_align", (H, H, H, H, H)),
}


def test_the_corpus_is_every_file_of_broken() -> None:
    assert sorted(p.stem for p in BROKEN.glob("*.yaml")) == sorted(CORPUS)


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_the_planted_defect_is_caught_and_the_counterexample_replays(name: str) -> None:
    check, expected = CORPUS[name]
    mission = load_mission(BROKEN / f"{name}.yaml")
    v = verify_mission(mission)
    got = {c.name: c.verdict for c in v.checks}
    assert {k: got.get(k) for k in CHECKS} == dict(zip(CHECKS, expected)), v.render()
    assert v.check(check).verdict == F
    for c in v.checks:
        if c.verdict != F or c.counterexample is None:
            continue
        cex = c.counterexample
        _, _, t_end = cex.schedule()
        result = drive(mission, cex.script(), max_time=t_end + v.model.quantum + 1.0)
        want = cex.states_visited()
        visited = list(result.summary["states_visited"])
        assert visited[:len(want)] == want, f"{c.name}: the engine visited {visited}, the counterexample {want}\n" \
                                            f"{cex.render()}"
        replay = cex.replay()
        assert replay.followed, f"{c.name}: {replay.describe()}"


def test_the_search_state_is_named() -> None:
    v = verify_mission(load_mission(BROKEN / "search_no_timeout.yaml"))
    timed = v.check("timed_exit")
    assert timed.data["waits_forever"] == ["searching"]
    assert timed.counterexample is not None and "waits in searching forever" in timed.counterexample.ending


def test_the_loop_and_the_retry_cycle_are_named() -> None:
    trap = verify_mission(load_mission(BROKEN / "loop_no_exit.yaml")).check("no_trap")
    assert trap.counterexample is not None and "cycle.load, cycle.unload" in trap.counterexample.ending
    duration = verify_mission(load_mission(BROKEN / "duration_unbounded.yaml")).check("duration")
    assert duration.detail.startswith("unbounded") and duration.counterexample is not None
    assert "attempt, backoff" in duration.counterexample.ending


def test_the_region_conflict_names_the_dropped_task() -> None:
    rc = verify_mission(load_mission(BROKEN / "region_conflict.yaml")).check("region_conflicts")
    assert "cell.safety.retract_arm" in rc.detail and "owns no command part" in rc.detail


@pytest.mark.parametrize("name", ["region_never_finishes", "require_never"])
def test_an_unreachable_success_is_never_reached_by_the_engine(name: str) -> None:
    mission = load_mission(BROKEN / f"{name}.yaml")
    v = verify_mission(mission)
    assert "never reached: succeeded" in v.check("outcomes").detail
    outcomes = set()
    for seed in range(40):
        rng = random.Random(seed)
        result = drive(mission, random_script(mission, rng, 40.0), max_time=40.0)
        outcomes.add(result.outcome)
        assert result.outcome != "succeeded", seed
    assert "failed" in outcomes  # the runs did end
