"""The ``taskflow`` command line, run in-process with :func:`taskflow.cli.main`.

The toy robot/world/task are registered in this process by ``tests/conftest.py``; a batch with
``--workers`` > 1 would start processes that do not have them, so batches here use ``--workers 1``.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from taskflow.cli import main
from taskflow.readers.run_files import read_trace

HERE = Path(__file__).parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
BROKEN = HERE / "broken"
TOY_STATES = ["search", "operate", "visit", "approach", "settle", "next", "broken", "home", "home_done",
              "searching", "done", "error"]


def _no_traceback(*texts: str) -> None:
    for t in texts:
        assert "Traceback" not in t


# -- validate -------------------------------------------------------------------------------------------


def test_validate_ok(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(TOY)]) == 0
    out, err = capsys.readouterr()
    assert f"{TOY}: ok" in out and "toy_full" in out
    assert err == ""


def test_validate_broken_prints_file_line_col(capsys: pytest.CaptureFixture[str]) -> None:
    broken = BROKEN / "unknown_task.yaml"
    assert main(["validate", str(broken)]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert out == ""
    first = err.splitlines()[0]
    assert first.startswith(f"{broken}:21:9: unknown task 'toy_gotoo' — did you mean 'toy_goto'?")


def test_validate_several_files(capsys: pytest.CaptureFixture[str]) -> None:
    bad1, bad2 = BROKEN / "unknown_robot.yaml", BROKEN / "guard_wrong_dimension.yaml"
    assert main(["validate", str(TOY), str(bad1), str(TOY), str(bad2)]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert out.count(f"{TOY}: ok") == 2
    lines = err.splitlines()
    assert any(line.startswith(f"{bad1}:4:1: unknown robot") for line in lines)
    assert any(line.startswith(f"{bad2}:24:11: guard 'pos_error < 3 deg'") for line in lines)
    # every problem line names its file
    assert all(line.startswith((str(bad1), str(bad2))) for line in lines)


def test_validate_all_good_files(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(TOY), str(TOY)]) == 0


@pytest.mark.parametrize("make, fragment", [
    (lambda p: p / "missing.yaml", "no such file"),
    (lambda p: p, "is a directory"),
    (lambda p: (p / "x.yaml").write_bytes(b"mission: caf\xe9\n") and p / "x.yaml", "not UTF-8"),
    (lambda p: (p / "e.yaml").write_text("") or p / "e.yaml", "the file is empty"),
], ids=["missing", "directory", "not-utf8", "empty"])
def test_validate_non_files(tmp_path: Path, capsys: pytest.CaptureFixture[str], make, fragment: str) -> None:
    path = make(tmp_path)
    assert main(["validate", str(path)]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert err.startswith(str(path)) and fragment in err


def test_validate_with_set(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(TOY), "--set", "rate_hz=50", "--set", "world.params.start=1.5"]) == 0
    assert main(["validate", str(TOY), "--set", "rate_hz=0"]) == 1
    err = capsys.readouterr().err
    assert "rate_hz must be > 0 Hz" in err


def test_set_unknown_key(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(TOY), "--set", "max_tries=3"]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "unknown key 'max_tries'" in err and "did you mean 'max_time'" in err


def test_set_unknown_key_names_the_override(capsys: pytest.CaptureFixture[str]) -> None:
    main(["validate", str(TOY), "--set", "machine.states.search.max_tries=3"])
    err = capsys.readouterr().err
    assert "--set" in err and "machine.states.search.max_tries" in err


@pytest.mark.parametrize("item, fragment", [
    ("max_time", "is not KEY=VALUE"),
    ("=3", "is not KEY=VALUE"),
    ("rate_hz=[1", "not valid YAML"),
    ("machine.states.search.transitions.7.after=1", "is not an index"),
    ("mission.name=x", "is not a mapping"),
])
def test_set_malformed(capsys: pytest.CaptureFixture[str], item: str, fragment: str) -> None:
    assert main(["validate", str(TOY), "--set", item]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert fragment in err


# -- graph, schema ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt, head", [("mermaid", "stateDiagram-v2"), ("dot", 'digraph "toy_full"')])
def test_graph(capsys: pytest.CaptureFixture[str], fmt: str, head: str) -> None:
    assert main(["graph", str(TOY), "--format", fmt]) == 0
    out = capsys.readouterr().out
    assert out.startswith(head)
    for name in TOY_STATES:
        assert name in out, f"{name} missing from the {fmt} graph"
    assert "on target_lost" in out and "after 3 s" in out


def test_graph_of_broken_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["graph", str(BROKEN / "unknown_target.yaml")]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "unknown target state 'eror'" in err and out == ""


def test_graph_bad_format() -> None:
    with pytest.raises(SystemExit) as exc:
        main(["graph", str(TOY), "--format", "svg"])
    assert exc.value.code == 2


def test_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert "machine" in schema["properties"]
    assert set(schema["required"]) >= {"mission", "robot", "world", "rate_hz", "machine"}
    assert "$defs" in schema and "Transition" in schema["$defs"]


# -- run ------------------------------------------------------------------------------------------------------

SUMMARY_KEYS = {"mission", "seed", "outcome", "final_state", "states_visited", "sim_time_s", "ticks", "items",
                "metrics", "versions", "stopped_at_s"}


def test_run_toy_mission(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "run"
    assert main(["run", str(TOY), "--out", str(out_dir), "--quiet"]) == 0
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "outcome: succeeded" in out

    summary = json.loads((out_dir / "summary.json").read_text())
    assert set(summary) >= SUMMARY_KEYS
    assert summary["mission"] == "toy_full" and summary["seed"] == 0 and summary["outcome"] == "succeeded"
    assert summary["final_state"] == "done" and summary["states_visited"][-1] == "done"
    assert summary["states_visited"][0] == "search"
    assert summary["ticks"] > 0 and summary["sim_time_s"] > 0
    assert "wall_time_s" not in summary and "real_time_factor" not in summary  # wall clock: timing.json only
    assert summary["versions"]["pybullet"] and summary["versions"]["numpy"] and summary["versions"]["transitions"]
    assert summary["metrics"]["final_x"] == pytest.approx(0.0, abs=0.03)  # home again
    timing = json.loads((out_dir / "timing.json").read_text())
    assert timing["wall_time_s"] > 0 and timing["real_time_factor"] > 0 and timing["ticks"] == summary["ticks"]

    trace = read_trace(out_dir)
    # the mission's ticks, then the safe stop that follows every outcome (1 s, event `safe_stop`)
    stop = trace["events"] == "safe_stop"
    assert int((~stop).sum()) == summary["ticks"] and int(stop.sum()) == round(1.0 * 20)
    assert summary["stopped_at_s"] == pytest.approx(summary["sim_time_s"] + 1.0)
    assert np.all(np.diff(trace["t"]) > 0)
    assert set(trace["state"]) <= set(summary["states_visited"])
    assert {"m.pos_error", "cmd.v", "gt.x"} <= set(trace)
    arr = np.genfromtxt(out_dir / "trace.csv", names=True, delimiter=",", dtype=None, encoding=None)
    assert arr.shape == (summary["ticks"] + 20,)
    assert np.allclose(arr["t"], trace["t"])

    recs = [json.loads(line) for line in (out_dir / "transitions.jsonl").read_text().splitlines()]
    assert recs[0]["cause"] == "start" and recs[0]["to"] == "search"
    assert all({"t", "from", "to", "cause", "state", "label"} <= set(r) for r in recs)
    guard = [r for r in recs if r["cause"] == "guard"]
    assert guard and all(set(r["metrics"]) == {"pos_error"} and r["metrics"]["pos_error"] < 0.02 for r in guard)
    assert [r["item"] for r in recs if r["cause"] == "next_item"] == [1, 2]
    assert [r["to"] for r in recs] == summary["states_visited"]
    assert all(a["to"] == b["from"] for a, b in itertools.pairwise(recs))


def test_run_seed_flag(tmp_path: Path) -> None:
    assert main(["run", str(TOY), "--out", str(tmp_path / "r"), "--seed", "7", "--quiet"]) == 0
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["seed"] == 7
    assert (tmp_path / "r" / "seed").read_text().strip() == "7"


@pytest.mark.parametrize("override, final", [
    ("world.params.lose_at=[1.0]", "error"),  # target lost for good: searching -> error after 3 s
    ("world.params.tool_ok=false", "error"),  # the tool fails: broken -> visit done failed -> error
])
def test_run_that_cannot_finish_exits_1(tmp_path: Path, capsys: pytest.CaptureFixture[str], override: str,
                                        final: str) -> None:
    out_dir = tmp_path / "run"
    assert main(["run", str(TOY), "--out", str(out_dir), "--set", override, "--quiet"]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["outcome"] == "failed" and summary["final_state"] == final


def test_run_timeout_exits_1(tmp_path: Path) -> None:
    out_dir = tmp_path / "run"
    assert main(["run", str(TOY), "--out", str(out_dir), "--max-time", "1.0", "--quiet"]) == 1
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["outcome"] == "timeout" and summary["sim_time_s"] == pytest.approx(1.0)


def test_run_broken_mission(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "run"
    assert main(["run", str(BROKEN / "guard_unknown_metric.yaml"), "--out", str(out_dir)]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "metric 'position_error' is not published" in err
    assert not out_dir.exists()  # nothing is recorded for a mission that does not validate


def test_run_set_unknown_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(TOY), "--out", str(tmp_path / "r"), "--set", "world.params.speed=2"]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "unknown key 'speed'" in err and "valid:" in err


# -- batch ------------------------------------------------------------------------------------------------------


def test_batch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "b"
    assert main(["batch", str(TOY), "--trials", "3", "--workers", "1", "--seed", "5", "--out", str(out_dir)]) == 0
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    batch = json.loads((out_dir / "batch.json").read_text())
    assert batch["aggregate"]["success_rate"] == 1.0
    assert batch["aggregate"]["trials"] == 3 and len(batch["trials"]) == 3
    assert [t["seed"] for t in batch["trials"]] == [5, 6, 7]
    assert all(t["outcome"] == "succeeded" for t in batch["trials"])
    assert "3 trials" in out


def test_batch_with_failures_exits_1(tmp_path: Path) -> None:
    out_dir = tmp_path / "b"
    assert main(["batch", str(TOY), "--trials", "2", "--workers", "1", "--out", str(out_dir),
                 "--set", "world.params.tool_ok=false"]) == 1
    batch = json.loads((out_dir / "batch.json").read_text())
    assert batch["aggregate"]["success_rate"] == 0.0 and batch["aggregate"]["outcomes"] == {"failed": 2}


def test_batch_broken_mission_fails_fast(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "b"
    assert main(["batch", str(BROKEN / "unknown_world.yaml"), "--trials", "2", "--workers", "1",
                 "--out", str(out_dir)]) == 1
    out, err = capsys.readouterr()
    _no_traceback(out, err)
    assert "unknown world 'toy_lines'" in err and not out_dir.exists()


def test_validate_in_a_fresh_process_prints_only_its_answer() -> None:
    """pybullet's import banner ("pybullet build time: …", on stderr) is muted by ``sim``; the answer
    is one line on stdout and nothing on stderr."""
    import subprocess
    import sys

    root = HERE.parent
    r = subprocess.run([sys.executable, "-m", "taskflow.cli", "validate", "missions/viki_hyco.yaml"], cwd=root,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines() == [r.stdout.strip()] and r.stdout.startswith("missions/viki_hyco.yaml: ok")
    assert r.stderr == ""


def test_a_world_that_cannot_be_built_ends_the_run_aborted_with_its_record(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A world check that needs the robot (here: the marker timeout shorter than the camera period) can only
    run when the world is built; the run then ends `aborted` with the reason, and its record is on disk."""
    mission = str(HERE.parent / "missions" / "screw_fastening.yaml")
    out = tmp_path / "run"
    assert main(["run", mission, "--set", "world.params.lost_after=0.01", "--out", str(out), "--quiet"]) == 1
    stdout, err = capsys.readouterr()
    _no_traceback(stdout, err)
    assert "outcome: aborted (the world could not be built: ValueError" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "aborted" and "lost_after" in summary["reason"] and summary["ticks"] == 0
    assert (out / "error.txt").read_text().startswith("Traceback") and (out / "mission.yaml").exists()


def test_teach_refuses_a_world_that_has_nothing_to_teach(capsys: pytest.CaptureFixture[str]) -> None:
    car = Path(__file__).resolve().parents[2] / "missions" / "car_waypoints.yaml"
    assert main(["teach", str(car)]) == 1
    err = capsys.readouterr().err
    assert "world 'flat_ground' has nothing to teach" in err and "quad_room" in err
    _no_traceback(err)
