"""MCAP export: a short ViKi-HyCo run on PyBullet, read back with the ``mcap`` library's own reader,
holds the run's poses, metrics, commands and state changes as its record has them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from taskflow.cli import main
from taskflow.readers.run_files import read_trace

ROOT = Path(__file__).resolve().parents[2]
VIKI = ROOT / "missions" / "viki_hyco.yaml"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("viki") / "run"
    # geometric perception (the fastest sensor mode, the mission's own); 10 s covers state 1 → state 2
    code = main(["run", str(VIKI), "--out", str(out), "--quiet", "--max-time", "10 s", "--record", "mcap"])
    assert code == 1  # a timeout: the run was cut short on purpose
    assert (out / "telemetry.mcap").is_file()
    return out


def _messages(path: Path) -> dict[str, list[tuple[int, str, dict]]]:
    out: dict[str, list[tuple[int, str, dict]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            out.setdefault(channel.topic, []).append((message.log_time, schema.name, json.loads(message.data)))
    return out


def test_the_export_holds_every_tick_s_robot_pose(run_dir: Path) -> None:
    msgs = _messages(run_dir / "telemetry.mcap")
    tr = read_trace(run_dir)
    poses = msgs["/pose/robot"]
    assert len(poses) == tr["t"].size and {s for _, s, _ in poses} == {"foxglove.PoseInFrame"}
    assert [t for t, _, _ in poses] == [round(t * 1e9) for t in tr["t"]]
    xs = np.array([m["pose"]["position"]["x"] for _, _, m in poses])
    ys = np.array([m["pose"]["position"]["y"] for _, _, m in poses])
    yaws = np.array([2 * math.atan2(m["pose"]["orientation"]["z"], m["pose"]["orientation"]["w"]) for _, _, m in poses])
    np.testing.assert_allclose(xs, tr["gt.x"])
    np.testing.assert_allclose(ys, tr["gt.y"])
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaws - tr["gt.yaw"]))), 0.0, atol=1e-9)
    tf = msgs["/tf"]
    assert {s for _, s, _ in tf} == {"foxglove.FrameTransform"}
    assert {(m["parent_frame_id"], m["child_frame_id"]) for _, _, m in tf} == {("world", "robot")}
    # the control point of state 1 is where the object should end up: 1 m ahead of the rear axle
    cp = msgs["/control_point"]
    forward = np.flatnonzero(tr["state"] == "forward")
    i = int(forward[-1])
    assert cp[i][2]["pose"]["position"]["x"] == pytest.approx(tr["gt.x"][i] + math.cos(tr["gt.yaw"][i]))


def test_the_export_holds_the_metrics_with_units_and_the_commands(run_dir: Path) -> None:
    msgs = _messages(run_dir / "telemetry.mcap")
    tr = read_trace(run_dir)
    metrics = msgs["/metrics"]
    assert len(metrics) == tr["t"].size
    for name in ("feature_error", "detection_age", "pos_error"):
        got = np.array([np.nan if m[name] is None else m[name] for _, _, m in metrics], dtype=float)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(tr[f"m.{name}"]))
        np.testing.assert_allclose(got[~np.isnan(got)], tr[f"m.{name}"][~np.isnan(got)])
    assert [m["state"] for _, _, m in metrics] == tr["state"].tolist()
    commands = msgs["/commands"]
    np.testing.assert_allclose([m["v"] for _, _, m in commands], tr["cmd.v"])
    with open(run_dir / "telemetry.mcap", "rb") as f:
        schemas = {s.name: json.loads(s.data) for s in make_reader(f).get_summary().schemas.values()}  # type: ignore[union-attr]
    assert schemas["taskflow.Metrics"]["properties"]["feature_error"]["description"] == "px"
    assert schemas["taskflow.Commands"]["properties"]["steer"]["description"] == "rad"


def test_the_export_holds_every_state_change_with_its_cause(run_dir: Path) -> None:
    msgs = _messages(run_dir / "telemetry.mcap")
    records = [json.loads(line) for line in (run_dir / "transitions.jsonl").read_text().splitlines()]
    got = [(t, m) for t, _, m in msgs["/transitions"]]
    assert [m for _, m in got] == records
    assert [t for t, _ in got] == [round(r["t"] * 1e9) for r in records]
    guard = next(m for _, m in got if m["cause"] == "guard")
    assert guard["from"] == "forward" and guard["to"] == "rotate"
    # either of the mission's two ways out of positioning: the paper's ±2 px, or the settle rule
    m = guard["metrics"]
    assert m["feature_error"] < 2.0 if "feature_error" in m else (m["goal_error"] < 0.01 and m["speed"] < 0.01)
    scene = msgs["/scene"][0][2]["entities"]
    assert [e["id"].split("-")[0] for e in scene] == ["start", "object"]


def test_export_converts_an_existing_run_directory(run_dir: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "copy.mcap"
    assert main(["export", str(run_dir), "--format", "mcap", "-o", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    a, b = _messages(out), _messages(run_dir / "telemetry.mcap")
    assert a == b  # simulation-time stamps: the same record exports the same messages


def test_export_of_a_folder_that_is_no_run_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(tmp_path)]) == 1
    assert "not a run folder (it has no trace.csv)" in capsys.readouterr().err
