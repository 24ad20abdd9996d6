"""The visual-path collision task past columns it loses from view or meets head-on (geometric camera,
PyBullet ground truth: collisions and clearance from the drone's collision shapes)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
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


BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.mark.parametrize("seed", [0, 1])
def test_two_columns_of_drawn_widths_beside_a_figure_eights_leg_are_passed(seed, tmp_path):
    """The campaign condition of ``benchmarks/visual_path_obstacles.py --only figure_eight``: a figure-eight
    (turns both ways) flown by the oval's mission with the collision task on, one cylinder of 6-16 cm
    each side of its first straight leg within 0.15 m of it, places and widths drawn from the seed.  Ground
    truth: no contact, positive clearance, and the mission's own success rule."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from visual_path_obstacles import beside
        from visual_path_shapes import figure_eight, shape_mission, with_columns
    finally:
        sys.path.remove(str(BENCHMARKS))
    mission = with_columns(shape_mission("figure_eight", figure_eight(), tmp_path))
    r = run_mission(load_mission(mission, overrides=[GEOMETRIC, beside("figure_eight")]), seed=seed, record=False)
    assert_outcome(r, "succeeded")
    m = r.summary["metrics"]
    assert m["collisions"] == 0 and m["min_obstacle_clearance_m"] > 0.0
    assert len(r.summary["iterations"]) == 38  # every keyframe of the path, the last one reached
