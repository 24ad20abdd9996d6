"""Every shipped mission verified, as CI runs it: each check holds on the model (the properties its paper implies are
checked in ``test_properties``), and the outcome witnesses the checks print replay on the real engine."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.mission.loader import load_mission
from taskflow.verify import verify_mission
from taskflow.verify.counterexample import Counterexample

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "missions").glob("*.yaml"))


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_check_holds(path: Path) -> None:
    v = verify_mission(load_mission(path))
    failing = [f"{c.name}: {c.detail}\n{c.counterexample.render() if c.counterexample else ''}"
               for c in v.checks if c.verdict == "fails"]
    assert not failing, "\n".join(failing)


@pytest.mark.parametrize("path", [p for p in SHIPPED if p.stem in ("viki_hyco", "screw_fastening", "visual_path_oval")],
                         ids=lambda p: p.stem)
def test_each_outcomes_witness_is_a_run_of_the_engine(path: Path) -> None:
    """The shortest path to each outcome, driven through the scripted backend, is followed record for record."""
    v = verify_mission(load_mission(path))
    model = v.model
    for outcome in model.outcomes():
        path_to = model.path_to([i for i, c in enumerate(model.configs) if c.outcome == outcome])
        assert path_to is not None
        replay = Counterexample(model, path_to).replay()
        assert replay.followed, f"{outcome}: {replay.describe()}"
        assert replay.result.outcome == outcome
