"""The model with the operator (``build_model(operator=True)``, ``taskflow verify --operator``): runs of the real
engine with scripted pre-emptions and aborts are paths of it, and a pre-emption past a loop's or parallel state's
rule cannot make the run succeed in the model either (the engine's ``end_verdict``)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from taskflow.mission.loader import load_mission
from taskflow.testing import Script, drive
from taskflow.verify.model import build_model

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", ["screw_fastening", "viki_hyco"])
def test_runs_with_preemptions_are_paths_of_the_operator_model(name: str) -> None:
    mission = load_mission(ROOT / "missions" / f"{name}.yaml")
    model = build_model(mission, operator=True)
    metrics = sorted({c.metric for t in mission.transitions if (g := getattr(t, "guard", None)) for c in g.comparisons()})
    preempted = 0
    for seed in range(12):
        rng = random.Random(seed)

        def values(s: object, rng: random.Random = rng) -> dict[str, float]:
            return {k: rng.choice([0.0, 1e-3, 1e3, -1e3]) for k in metrics if rng.random() < 0.05}

        events = sorted((round(rng.uniform(0, 30), 2), rng.choice(sorted(mission.world_cls.events))) for _ in range(6))
        actions = {a: (rng.uniform(0.1, 3.0), rng.choice(ends)) for a, ends in mission.world_cls.actions.items()}
        ops = [{"t": round(rng.uniform(0, 25), 2), "action": "preempt", "who": "test",
                "args": {"to": rng.choice(mission.outside_regions)}} for _ in range(2)]
        if seed % 3 == 0:
            ops.append({"t": round(rng.uniform(0, 25), 2), "action": "preempt", "who": "test"})  # abort
        ops.sort(key=lambda o: float(str(o["t"])))
        result = drive(mission, Script(metrics=values, events=events, actions=actions), max_time=40, operator=ops)
        assert result.executor is not None
        records = [r.as_dict() for r in result.executor.transitions_fired]
        preempted += sum(r["cause"] == "operator" for r in records)
        model.path_of(records, outcome=result.outcome)
    assert preempted > 5  # the runs did take pre-emptions


def test_a_preemption_past_the_loops_rule_cannot_succeed() -> None:
    mission = load_mission(ROOT / "missions" / "car_waypoints.yaml")
    model = build_model(mission, operator=True)
    to_success = [i for i, c in enumerate(model.configs) if c.outcome == "succeeded"]
    # every way the model reaches `succeeded` passes the loop's own rule, or pre-empts straight into a final state
    # that is not left by the rule: a pre-emption that leaves `drive` mid-way records its verdict (failed)
    for i in to_success:
        c = model.configs[i]
        assert all(v == "succeeded" for _, v in c.skipped), c
    left_mid_way = [c for c in model.configs if any(v == "failed" for _, v in c.skipped)]
    assert left_mid_way and all(c.outcome in (None, "failed", "aborted") for c in left_mid_way)
