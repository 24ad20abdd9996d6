"""The Husky waypoint mission on PyBullet, judged from the simulator's ground truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

from taskflow.execution.records import read_trace
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.testing import assert_outcome

MISSION = Path(__file__).resolve().parents[2] / "missions" / "husky_waypoints.yaml"


def test_husky_reaches_every_waypoint_within_5_cm_of_ground_truth(tmp_path):
    m = load_mission(MISSION)
    r = run_mission(m, out_dir=tmp_path / "run")
    assert_outcome(r, "succeeded")
    its = r.summary["iterations"]
    assert [it["item"] for it in its] == m.spec.parameters["waypoints"]
    for it in its:
        gt = it["ground_truth"]  # the simulator's pose of base_footprint when the iteration ended
        err = math.dist((gt["x"], gt["y"]), it["item"])
        assert err < 0.05, f"waypoint {it['item']}: ground-truth error {100 * err:.1f} cm"
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "succeeded" and summary["sim_time_s"] < 60.0
    trace = read_trace(tmp_path / "run")
    assert abs(trace["gt.v"][-1]) < 1e-2  # at rest after the safe stop
    assert set(trace["state"]) >= {"drive.approach", "drive.settle"}
    assert {"cmd.v", "cmd.w"} <= set(trace)  # the unicycle command is recorded


def test_husky_approaches_the_object_in_the_viki_scene(tmp_path):
    """viki_ground hosts the Husky through its body and camera mounts (no edit to the world): it waits for
    the front camera's detection, then stops with the object ~1 m ahead (ground truth)."""
    m = load_mission(MISSION.with_name("husky_viki_approach.yaml"))
    r = run_mission(m, seed=1, out_dir=tmp_path / "run")
    assert_outcome(r, "succeeded")
    s = r.summary["metrics"]
    assert s["first_detection_s"] is not None and s["detections"] > 0
    assert s["final_error_m"] < 0.15, s["final_error_m"]  # object in the robot frame vs goal [1.0, 0.0]
    assert 0.85 < s["object_x_m"] < 1.15
