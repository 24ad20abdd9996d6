"""Same seed, same bytes: two runs of a shipped mission with one seed write identical ``trace.csv``,
``transitions.jsonl`` and ``summary.json`` — on every world and perception mode (short runs here;
``benchmarks/determinism.py`` checks every shipped mission to its end).  Wall-clock figures live in
``timing.json`` only, which is the one file allowed to differ."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
RECORDS = ("trace.csv", "transitions.jsonl", "summary.json", "mission.yaml")

CASES = [  # (mission, overrides, simulated seconds)
    ("car_waypoints.yaml", [], 6.0),
    ("husky_waypoints.yaml", ["world.params.odom_noise=0.003"], 6.0),
    ("husky_viki_approach.yaml", [], 6.0),
    ("viki_hyco.yaml", [], 6.0),
    ("viki_hyco.yaml", ["world.params.perception=rendered", "world.params.image_size=[320, 180]"], 2.0),
    ("visual_path_pose_regulation.yaml", [], 2.0),
    ("visual_path_pose_regulation.yaml", ["world.params.perception=geometric"], 4.0),
    ("screw_fastening_trolley.yaml", [], 6.0),
    ("screw_fastening.yaml", ["world.params.perception=rendered"], 1.0),
]


@pytest.mark.parametrize("file, overrides, seconds", CASES,
                         ids=[f"{f.removesuffix('.yaml')}{'-' + o[0].split('=')[1] if o else ''}" for f, o, _ in CASES])
def test_two_runs_with_one_seed_write_the_same_bytes(tmp_path: Path, file: str, overrides: list[str],
                                                     seconds: float) -> None:
    m = load_mission(MISSIONS / file, overrides)
    a = run_mission(m, seed=3, out_dir=tmp_path / "a", max_time=seconds)
    run_mission(m, seed=3, out_dir=tmp_path / "b", max_time=seconds)
    assert a.summary["ticks"] > 0
    for name in RECORDS:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    trace = (tmp_path / "a" / "trace.csv").read_text()
    header = trace.splitlines()[0]
    assert "time" not in header.replace("t,", "", 1) and "_ms" not in header  # no wall-clock column
    assert (tmp_path / "a" / "timing.json").exists()


def test_one_seed_from_two_working_directories_writes_the_same_bytes(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The mission named as a user types it, relative to two different working directories: the record
    (``summary.json``'s ``file`` included, as the resolved path) is the same."""
    from taskflow.cli import main

    root = MISSIONS.parent
    for cwd, typed, out in ((root, "missions/car_waypoints.yaml", tmp_path / "a"),
                            (MISSIONS, "car_waypoints.yaml", tmp_path / "b")):
        monkeypatch.chdir(cwd)
        assert main(["run", typed, "--seed", "3", "--max-time", "2", "--out", str(out), "--quiet"]) == 1  # timeout
    for name in RECORDS:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["file"] == str(MISSIONS / "car_waypoints.yaml")
