"""The abstraction test: the model of :mod:`taskflow.verify.model` over-approximates the engine.

Random machines (``machines.generate``: nested composites, history, foreach with ``require`` rules and
``retry``, parallel
regions with ``owns`` and ``outcome_map``, guards with dwells, timeouts ``since`` an enclosing state or
``first_entry``, declared events, ``done`` by outcome, finals of several outcomes) are driven by the real engine
(scripted backend, ``machines.random_script``: metric values either side of the guards' thresholds, events,
action ends after random delays), and every run's transition records must be a path of the model
(:meth:`Model.path_of`).  A :class:`NotAPath` is a real disagreement between the model and the engine: the
failure prints the seed, the run, the mission YAML and the records, so it can be replayed alone with
``machines.generate(seed)`` and ``random.Random(seed * 1000 + run)``.
"""

from __future__ import annotations

import json
import random
import re
from pathlib import Path

import pytest
from machines import generate, random_script

from taskflow.mission.loader import load_mission_text
from taskflow.testing import drive
from taskflow.verify.model import NotAPath, StateBudgetExceeded, build_model

pytestmark = pytest.mark.machine

MACHINES = 110  # machines driven (those whose model fits BUDGET)
RUNS = 10  # runs per machine
BUDGET = 5_000  # configurations; a generated machine past it is skipped (counted), see machines.generate
FEATURES = ("history: true", "foreach:", "require:", "on_failure: continue", "on_failure: stop", "regions:",
            "owns:", "outcome_map:", "for:", "since: first_entry", "'on': go_on", "'on': tool_done",
            "done: failed", "done: true", "final: aborted", "action:", "retry:", "times:")


def test_every_generated_machine_loads_and_the_features_occur() -> None:
    seen = dict.fromkeys(FEATURES, 0)
    sizes = []
    for seed in range(200):
        text = generate(seed)
        mission = load_mission_text(text, f"generated_{seed}.yaml")  # raises MissionError with FILE:LINE:COL
        sizes.append(len(mission.states))
        for f in FEATURES:
            seen[f] += f in text
    assert all(n >= 10 for n in seen.values()), seen
    assert sum("since: s" in generate(s) for s in range(200)) >= 10
    assert min(sizes) <= 5 and max(sizes) >= 45, (min(sizes), max(sizes))
    assert generate(7) == generate(7)  # seeded


def test_records_in_memory_are_the_records_written(tmp_path: Path) -> None:
    """The test reads the executor's records (no disk); they are what ``transitions.jsonl`` holds."""
    mission = load_mission_text(generate(3), "generated_3.yaml")
    result = drive(mission, random_script(mission, random.Random(3), 20.0), max_time=20.0, out_dir=tmp_path)
    assert result.executor is not None
    written = [json.loads(line) for line in (tmp_path / "transitions.jsonl").read_text().splitlines()]
    transitions = [r for r in written if r.get("kind", "transition") == "transition" and "to" in r]
    assert [r.as_dict() for r in result.executor.transitions_fired] == transitions
    assert len(transitions) > 3


def _failure(seed: int, run: int, text: str, records: list[dict[str, object]], error: Exception) -> str:
    found = re.match(r"records? (\d+)", str(error))
    upto = int(found.group(1)) if found else len(records)  # the records up to the one the model cannot take
    shown = "\n".join(json.dumps({k: v for k, v in r.items() if k != "metrics"}) for r in records[:upto])
    return (f"seed {seed}, run {run} (random.Random({seed * 1000 + run})): {error}\n--- mission ---\n{text}"
            f"--- records ---\n{shown}")


def test_random_engine_runs_are_paths_of_the_model() -> None:
    failures: list[str] = []
    runs = machines = skipped = 0
    seed = 0
    while machines < MACHINES:
        text = generate(seed)
        mission = load_mission_text(text, f"generated_{seed}.yaml")
        try:
            model = build_model(mission, budget=BUDGET)
        except StateBudgetExceeded:
            skipped += 1
            seed += 1
            continue
        machines += 1
        for run in range(RUNS):
            rng = random.Random(seed * 1000 + run)
            horizon = rng.choice((5.0, 10.0, 20.0))
            result = drive(mission, random_script(mission, rng, horizon), max_time=horizon)
            assert result.executor is not None
            records = [r.as_dict() for r in result.executor.transitions_fired]
            runs += 1
            try:
                model.path_of(records, outcome=result.outcome)
            except NotAPath as exc:
                failures.append(_failure(seed, run, text, records, exc))
        seed += 1
    assert runs >= 1000 and machines >= 100 and skipped < machines / 2, (runs, machines, skipped)
    if failures:
        firsts = sorted({f.split(":", 1)[0] for f in failures})
        pytest.fail(f"{len(failures)} of {runs} engine runs are not paths of the model ({', '.join(firsts)});"
                    f" the first:\n{failures[0]}", pytrace=False)
