"""``taskflow compare`` compares every numeric aggregate both batches have — ``sim_time_s`` included."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.stats import mann_whitney
from taskflow.cli import main

TOY = Path(__file__).resolve().parents[1] / "machine" / "missions" / "toy_full.yaml"


def test_compare_carries_sim_time_and_accepts_it_as_a_metric(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    run_batch(str(TOY), trials=2, workers=1, out=a)
    run_batch(str(TOY), trials=2, workers=1, out=b, overrides=["world.params.start=-1.0"])  # farther: longer runs
    times = {k: [t["sim_time_s"] for t in json.loads((d / "batch.json").read_text())["trials"]] for k, d in (("a", a), ("b", b))}
    assert np.mean(times["b"]) > np.mean(times["a"])  # the two batches do differ in sim time
    assert main(["compare", str(a), str(b), "--json"]) == 0
    (r,) = json.loads(capsys.readouterr().out)
    s = r["metrics"]["sim_time_s"]
    assert s["mean_a"] == pytest.approx(np.mean(times["a"])) and s["mean_b"] == pytest.approx(np.mean(times["b"]))
    assert (s["n_a"], s["n_b"]) == (2, 2) and s["p"] == pytest.approx(mann_whitney(times["a"], times["b"])[1])
    assert main(["compare", str(a), str(b), "--metric", "sim_time_s"]) == 0
    text = capsys.readouterr().out
    assert "sim_time_s" in text and "of 1 metrics differ" in text
