"""The visual-path collision task past columns it loses from view or meets head-on (geometric camera,
PyBullet ground truth: collisions and clearance from the drone's collision shapes)."""

from __future__ import annotations

from pathlib import Path

import taskflow_robots.quadcopter  # noqa: F401 - registration
import taskflow_sim.quad.world  # noqa: F401
import taskflow_tasks.quad.visual_path  # noqa: F401

from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.testing import assert_outcome

POSE_REG = Path(__file__).resolve().parents[2] / "missions" / "visual_path_pose_regulation.yaml"
GEOMETRIC = "world.params.perception=geometric"
BOX = "width: 0.05, depth: 0.02"


def run(*overrides: str, seed: int = 0):
    return run_mission(load_mission(POSE_REG, overrides=[GEOMETRIC, *overrides]), seed=seed, record=False)


def test_a_column_exactly_on_the_taught_line_is_passed_and_the_keyframe_reached():
    """Symmetric block: the column dead ahead on the straight line to the keyframe."""
    r = run(f"world.params.obstacles=[{{x: 0.75, y: 0.0, {BOX}}}]")
    assert_outcome(r, "succeeded")
    m = r.summary["metrics"]
    assert m["collisions"] == 0 and m["min_obstacle_clearance_m"] > 0.1
    assert m["final_position_error_m"] <= 0.05
    assert m["path_deviation_max_m"] > 0.3  # it went round the column, not through it


def test_a_column_that_leaves_the_view_beside_the_drone_is_kept_clear_of():
    """The column leaves the image 0.4 m before the drone reaches it: remembered, it is passed with room
    to spare; the paper's task (h_a decays as soon as an edge leaves the image) flies into it."""
    column = f"world.params.obstacles=[{{x: 0.642, y: -0.038, {BOX}}}]"
    r = run(column)
    assert_outcome(r, "succeeded")
    m = r.summary["metrics"]
    assert m["collisions"] == 0 and m["min_obstacle_clearance_m"] > 0.1
    assert m["final_position_error_m"] <= 0.05
    paper = run(column, "profiles.hierarchy.paper.memory=false")
    assert_outcome(paper, "failed")
    assert paper.summary["final_state"] == "crashed" and paper.summary["metrics"]["min_obstacle_clearance_m"] < 0.0
