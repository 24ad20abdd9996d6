"""The waypoint mission on PyBullet, judged from the simulator's ground truth."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from taskflow.cli import main
from taskflow.execution.records import read_trace
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.testing import assert_outcome

ROOT = Path(__file__).resolve().parents[2]
MISSION = ROOT / "missions" / "car_waypoints.yaml"
UNREACHABLE = ROOT / "missions" / "car_waypoints_unreachable.yaml"


def test_reaches_every_waypoint_within_5_cm_of_ground_truth(tmp_path):
    m = load_mission(MISSION)
    d = m.spec.profiles["gains"]["fine"]["d"]
    r = run_mission(m, out_dir=tmp_path / "run")
    assert_outcome(r, "succeeded")
    waypoints = m.spec.parameters["waypoints"]
    its = r.summary["iterations"]
    assert [it["item"] for it in its] == waypoints
    for it in its:
        gt = it["ground_truth"]  # the simulator's pose of the rear axle when the iteration ended
        point = (gt["x"] + d * math.cos(gt["yaw"]), gt["y"] + d * math.sin(gt["yaw"]))
        err = math.dist(point, it["item"])
        assert err < 0.05, f"waypoint {it['item']}: ground-truth error {100 * err:.1f} cm"
    # the record on disk agrees with the result, and the trace carries ground truth every tick
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "succeeded" and summary["final_state"] == "done"
    trace = read_trace(tmp_path / "run")
    stop = trace["events"] == "safe_stop"  # the 1 s safe stop that follows every outcome
    assert int((~stop).sum()) == summary["ticks"] and int(stop.sum()) == 20
    assert abs(trace["gt.v"][-1]) < 1e-3  # at rest when the record ends
    assert set(trace["state"]) >= {"drive.approach", "drive.settle"}
    assert not any(math.isnan(x) for x in trace["gt.x"])


def test_unreachable_goal_ends_in_error_through_its_timeout_and_exits_nonzero(tmp_path, capsys):
    code = main(["run", str(UNREACHABLE), "--out", str(tmp_path / "run"), "--quiet"])
    assert code == 1
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "failed"
    assert summary["final_state"] == "error"
    assert summary["sim_time_s"] == pytest.approx(20.0, abs=0.06)
    transitions = [json.loads(line) for line in (tmp_path / "run" / "transitions.jsonl").read_text().splitlines()]
    assert transitions[-1]["to"] == "error" and transitions[-1]["label"] == "after 20 s"
    assert transitions[-1]["cause"] == "timeout" and transitions[-1]["state"] == "drive"
    # the car was commanded to a safe stop: ground-truth speed is (almost) zero at the end
    assert summary["metrics"]["gt_speed_mps"] < 0.05


def test_same_seed_reproduces_the_pybullet_run_bit_for_bit(tmp_path):
    m = load_mission(MISSION, overrides=["parameters.waypoints=[[1.5, 0.5]]", "world.params.odom_noise=0.003"])
    a = run_mission(m, seed=11, out_dir=tmp_path / "a")
    b = run_mission(m, seed=11, out_dir=tmp_path / "b")
    c = run_mission(m, seed=12, out_dir=tmp_path / "c")
    trace_a = (tmp_path / "a" / "trace.csv").read_bytes()
    assert trace_a == (tmp_path / "b" / "trace.csv").read_bytes()
    assert trace_a != (tmp_path / "c" / "trace.csv").read_bytes()  # the seed drives the odometry noise
    assert a.summary["metrics"] == b.summary["metrics"]
    del c


def _strings(node: object) -> list[str]:
    """Every string in a YAML tree, keys included."""
    if isinstance(node, dict):
        return [s for k, v in node.items() for s in (*_strings(k), *_strings(v))]
    if isinstance(node, list):
        return [s for v in node for s in _strings(v)]
    return [node] if isinstance(node, str) else []


@pytest.mark.parametrize("file", sorted(p.name for p in (ROOT / "missions").glob("*.yaml")))
def test_every_parameter_a_shipped_mission_declares_is_used(file: str) -> None:
    raw = load_mission(ROOT / "missions" / file).raw
    used = " ".join(_strings({k: v for k, v in raw.items() if k != "parameters"}))
    foreach = set(re.findall(r"'in': '(\w+)'", str(raw.get("machine"))))
    unused = [p for p in raw.get("parameters", {}) if p not in foreach and not re.search(rf"\${p}\b", used)]
    assert unused == [], f"{file}: parameters nothing refers to: {unused}"


@pytest.mark.parametrize("file", ["car_waypoints.yaml", "husky_waypoints.yaml"])
def test_the_waypoint_missions_describe_the_settle_guard_they_have(file: str) -> None:
    raw = load_mission(ROOT / "missions" / file).raw
    (tolerance, dwell) = re.findall(r"within (\d+ cm) for ([\d.]+ s)", raw["description"])[0]
    settle = raw["machine"]["states"]["drive"]["states"]["settle"]["transitions"]
    assert {"to": "reached", "when": f"pos_error < {tolerance}", "for": dwell} in settle
