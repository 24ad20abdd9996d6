"""`taskflow verify --export prism|jani`: the texts are the model the checks were answered on — Storm reads
each back (its PRISM and JANI parsers, its own builder) and gives the same values as the sparse model the
checks build directly, in every configuration, as it is and under sensor loss."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
import stormpy
import stormpy.developer as dev

from taskflow.mission.loader import load_mission
from taskflow.verify.export import jani_text, prism_text
from taskflow.verify.model import build_model
from taskflow.verify.storm import StormModel

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]
SMALL = [p for p in sorted((ROOT / "missions").glob("*.yaml")) if "screw" not in p.name]  # explicit PRISM builds are quadratic
FORMULAS = ['Pmax=? [F "final"]', 'Pmin=? [F "final"]', 'R{"time"}max=? [F "final"]']


def _same(a: float, b: float) -> bool:
    return (math.isinf(a) and math.isinf(b)) or abs(a - b) < 1e-6


def _prism_values(text: str, n: int, tmp_path: Path) -> list[list[float]]:
    f = tmp_path / "m.prism"
    f.write_text(text)
    program = stormpy.parse_prism_program(str(f))
    props = stormpy.parse_properties(";".join(FORMULAS), program)
    options = dev.BuilderOptions([p.get_raw_formula() for p in props])
    options.set_build_state_valuations()
    sparse = dev.build_sparse_model(program, options)
    var = program.get_module("machine").get_integer_variable("s").expression_variable
    config = [int(sparse.state_valuations.get_int64_value(i, var)) for i in range(sparse.nr_states)]
    out = []
    for p in props:
        result = stormpy.model_checking(sparse, p, only_initial_states=False)
        row = [math.nan] * n
        for i, s in enumerate(config):
            row[s] = float(result.get_value(i))
        out.append(row)
    return out


@pytest.mark.parametrize("timed_only", [False, True], ids=["full", "sensor_loss"])
@pytest.mark.parametrize("path", SMALL, ids=lambda p: p.stem)
def test_prism_text_is_the_checked_model(path: Path, timed_only: bool, tmp_path: Path) -> None:
    model = build_model(load_mission(path))
    direct = StormModel(model, timed_only=timed_only)
    from_text = _prism_values(prism_text(model, timed_only=timed_only), model.n_states, tmp_path)
    for formula, got in zip(FORMULAS, from_text):
        want = direct.values(formula)
        reached = [s for s in range(model.n_states) if not math.isnan(got[s])]
        # the full model's text starts in configuration 0, so Storm keeps what it reaches: all of them
        assert len(reached) == model.n_states
        bad = [s for s in reached if not _same(got[s], want[s])]
        assert not bad, f"{formula}: configurations {bad[:5]} differ: text {[got[s] for s in bad[:5]]}, direct {[want[s] for s in bad[:5]]}"


@pytest.mark.parametrize("path", SMALL, ids=lambda p: p.stem)
def test_jani_text_is_the_checked_model(path: Path) -> None:
    model = build_model(load_mission(path))
    doc = jani_text(model)
    jani, props = stormpy.parse_jani_model_from_string(doc)
    sparse = stormpy.build_model(jani, props)
    direct = StormModel(model)
    want = {"reach_final_max": direct.values(FORMULAS[0])[0], "reach_final_min": direct.values(FORMULAS[1])[0],
            "time_to_final_max": direct.values(FORMULAS[2])[0]}
    names = [p["name"] for p in json.loads(doc)["properties"]]
    for name, p in zip(names, props):
        got = float(stormpy.model_checking(sparse, p).get_value(sparse.initial_states[0]))
        if name in want:
            assert _same(got, want[name]), (name, got, want[name])
        else:  # reach_outcome_X: reachable, as the outcomes check found
            assert got == 1.0 or got == 0.0


def test_the_command_prints_what_storm_reads(tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, "-m", "taskflow.cli", "verify", str(ROOT / "missions" / "viki_hyco.yaml"),
                          "--export", "prism", "--sensor-loss"], capture_output=True, text=True, check=True).stdout
    assert "init true endinit" in out and 'label "final"' in out
    f = tmp_path / "m.prism"
    f.write_text(out)
    program = stormpy.parse_prism_program(str(f))
    sparse = stormpy.build_model(program)
    assert sparse.nr_states == build_model(load_mission(ROOT / "missions" / "viki_hyco.yaml")).n_states
