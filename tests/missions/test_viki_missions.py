"""The ViKi-HyCo missions on PyBullet, judged from the simulator's ground truth (summary metrics)."""

from __future__ import annotations

from pathlib import Path

import pytest
import taskflow_sim.viki.world  # noqa: F401  registers the world viki_ground
import taskflow_tasks.viki.hyco
import taskflow_tasks.viki.rotation  # noqa: F401  registers the task viki_rotate

from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.testing import assert_outcome, assert_path, run_on_world

ROOT = Path(__file__).resolve().parents[2] / "missions"
COMPLETE = ROOT / "viki_hyco.yaml"
FORWARD = ROOT / "viki_forward.yaml"
BACKWARD = ROOT / "viki_backward.yaml"
VS_ONLY = ROOT / "viki_vs_only.yaml"
MGBM = ROOT / "viki_mgbm.yaml"


def run(path, seed=0, overrides=()):
    return run_mission(load_mission(path, list(overrides)), seed=seed, record=False)


def test_complete_placement_geometric_reaches_the_manipulation_zone():
    r = run(COMPLETE, seed=0)
    assert_outcome(r, "succeeded")
    assert_path(r, ["forward", "rotate", "backward", "placed"])
    m = r.summary["metrics"]
    assert abs(m["final_error_x_m"]) <= 0.03 and abs(m["final_error_y_m"]) <= 0.03
    assert m["detections_missed"] > 0  # the detector did drop frames (15 %)
    assert m["first_detection_s"] == 0.0


def test_complete_placement_rendered_reaches_the_manipulation_zone():
    r = run(COMPLETE, seed=1, overrides=["world.params.perception=rendered", "world.params.image_size=[320, 180]",
                                         "world.params.object_distance=1.8", "world.params.object_kind=can"])
    assert_outcome(r, "succeeded")
    assert_path(r, ["forward", "rotate", "backward", "placed"])
    m = r.summary["metrics"]
    assert abs(m["final_error_x_m"]) <= 0.03 and abs(m["final_error_y_m"]) <= 0.03
    assert r.timing["parts_ms"]["world.perception"]["mean"] > 1.0  # it really rendered (wall clock: timing only)
    assert not any("ms" in k or "time" in k for k in m if k != "first_detection_s")  # no wall clock in the summary


def test_backward_positioning_reaches_the_manipulation_zone():
    r = run(BACKWARD, seed=0)
    assert_outcome(r, "succeeded")
    m = r.summary["metrics"]
    assert abs(m["final_error_x_m"]) <= 0.03 and abs(m["final_error_y_m"]) <= 0.03


def test_at_30pct_dropout_hybrid_succeeds_where_vs_only_stalls_short():
    drop = ["world.params.dropout=0.3"]
    vs_errors = []
    for seed in range(4):
        hybrid = run(FORWARD, seed, drop)
        vs_only = run(VS_ONLY, seed, drop)
        assert_outcome(hybrid, "succeeded")
        assert vs_only.outcome == "failed" and vs_only.summary["final_state"] == "stalled"
        h, v = hybrid.summary["metrics"], vs_only.summary["metrics"]
        assert h["object_kind"] == v["object_kind"] and h["object_world_x_m"] == v["object_world_x_m"]  # same scene
        assert h["final_error_m"] <= 0.03
        assert v["final_error_m"] > h["final_error_m"]  # stopped farther from the goal (ground truth)
        assert v["final_error_x_m"] > 0.0  # short of it: the object is still beyond the goal
        vs_errors.append(v["final_error_m"])
    assert sum(vs_errors) / len(vs_errors) > 0.05


def test_mgbm_never_settles_where_viki_hyco_does():
    mgbm = run(MGBM, 0)
    assert mgbm.outcome == "failed" and mgbm.summary["final_state"] == "no_settle"  # 40 s without +-2 px
    assert mgbm.summary["metrics"]["feature_error"] > 2.0  # the static box cannot be matched
    viki = run(MGBM, 0, ["machine.states.forward.task.params.mode=hybrid"])  # same scene, eq. 19 box
    assert_outcome(viki, "succeeded")  # settled within the same 40 s
    assert abs(viki.summary["metrics"]["final_error_x_m"]) < abs(mgbm.summary["metrics"]["final_error_x_m"])


def test_object_outside_every_view_fails_with_no_target():
    r = run(COMPLETE, 0, ["world.params.object_bearing=1.57"])
    assert r.outcome == "failed" and r.summary["final_state"] == "no_target"
    assert "no_target" in r.summary["reason"]
    assert r.summary["sim_time_s"] == pytest.approx(2.0, abs=0.06)  # search_timeout, not max_time
    assert r.summary["metrics"]["first_detection_s"] is None and r.summary["metrics"]["detections"] == 0


@pytest.mark.parametrize("override, message", [
    ("machine.states.backward.task.params.camera=top", "'front' or 'rear'"),
    ("profiles.viki_gains.rear.lam=[0.85, 1.05, 1.0]", "5 gains"),
    ("profiles.viki_gains.front.lam=[0.85, 0.0, 1.0, 1.0, 1.0]", "> 0"),
])
def test_bad_camera_or_gains_are_load_time_errors(override, message):
    with pytest.raises(MissionError, match=message):
        load_mission(COMPLETE, [override])


def test_same_seed_same_run():
    a, b = run(FORWARD, 3), run(FORWARD, 3)
    for k in ("final_error_x_m", "final_error_y_m", "detections_missed", "object_world_x_m"):
        assert a.summary["metrics"][k] == b.summary["metrics"][k]
    assert a.summary["sim_time_s"] == b.summary["sim_time_s"]


def test_plot_writes_the_paper_style_figures(tmp_path):
    """`taskflow run --plot` on the complete placement: path, commands, camera velocities, metrics."""
    from taskflow.cli import main

    code = main(["run", str(ROOT / "viki_hyco.yaml"), "--out", str(tmp_path / "run"), "--plot",
                 "--quiet"])
    assert code == 0
    for name in ("path.png", "commands.png", "camera_velocities.png", "metrics.png"):
        png = tmp_path / "run" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000, name
    assert main(["plot", str(tmp_path / "run")]) == 0  # the stand-alone command rewrites them


def _placed_without_touching(r):
    """Ground truth: placed in the manipulation zone within 3 cm per axis, the car never touched the object."""
    assert_outcome(r, "succeeded")
    m = r.summary["metrics"]
    assert abs(m["final_error_x_m"]) <= 0.03 and abs(m["final_error_y_m"]) <= 0.03
    assert m["contact"] is False and m["min_clearance_m"] > 0.2


def test_half_the_frames_missed_in_15_frame_bursts_still_places_the_object():
    """Seed 1 at 50 % dropout in bursts of 15 frames timed out in forward positioning when the first
    detection fixed the fallback target (each burst dragged the car off where the servo converges);
    the target now follows the evidence."""
    r = run(COMPLETE, 1, ["world.params.dropout=0.5", "world.params.dropout_burst=15"])
    _placed_without_touching(r)
    assert r.summary["metrics"]["dropout_fraction"] > 0.3


def test_a_car_that_cannot_close_the_last_pixels_completes_by_the_settle_rule(tmp_path):
    """Seed 7 of the shipped distribution with the evidence-following target stalled in forward
    positioning until its 45 s timeout: the car stopped ~2 mm from the goal with the feature error at
    2.0-3.5 px (a sideways offset a car cannot remove) and the still camera kept the detector missing.
    The settle rule (the last detections put the object within 1 cm of the goal, the view has not moved,
    the car has stopped) ends the state; the object still ends in the zone (ground truth)."""
    import json

    r = run_mission(load_mission(COMPLETE, []), seed=7, out_dir=tmp_path / "run")
    _placed_without_touching(r)
    rows = [json.loads(line) for line in (tmp_path / "run" / "transitions.jsonl").read_text().splitlines()]
    forward_end = next(t for t in rows if t["from"] == "forward")
    assert forward_end["to"] == "rotate" and forward_end["label"].startswith("goal_error < 1 cm")
    assert forward_end["t"] < 20.0


def test_an_object_at_0_45_rad_and_1_1_m_cut_by_the_image_border_is_placed_without_contact():
    """Near and far to the side, the object's box starts cut by the image border (biased centre and
    width): it steers the servo but does not move the fallback target."""
    r = run(COMPLETE, 8, ["world.params.object_bearing=0.45", "world.params.object_distance=1.1"])
    _placed_without_touching(r)


def test_an_object_at_the_edge_of_the_view_seen_only_cut_is_not_driven_into():
    """Issue 25: seed 14 of the right edge row (bearing in [-0.52, -0.44] rad, 1.5-2.6 m) saw the bottle only
    in boxes cut by the image border; eq. 18 put it 0.5 m beyond where it stood, the keep-out trusted that,
    and when the detections stopped the car drove blind into it at 5.1 s.  Now a cut box places the object
    at the floor point under its inner column (no farther than the object) and the car keeps clear
    (ground truth; the first 20 s, which cover the old touch and the forward positioning)."""
    edge = ["world.params.object_bearing={uniform: [-0.52, -0.44]}", "world.params.object_distance={uniform: [1.5, 2.6]}"]
    r = run_on_world(load_mission(COMPLETE, edge), seed=14, max_time=20.0)
    m = r.summary["metrics"]
    assert m["detections"] > 0 and m["first_detection_s"] == 0.0  # the object is visible from the start
    assert m["contact"] is False and m["min_clearance_m"] > 0.05
    assert r.summary["properties"]["never_touches"]["verdict"] == "held"


@pytest.mark.parametrize("seed", [16, 19])
def test_at_the_paper_like_level_a_long_burst_after_the_goal_does_not_drive_the_car_off(seed):
    """Seeds 16 and 19 of 50 % dropout in 15-frame bursts at the paper-like level ended in the backward state's
    45 s timeout (a false failure): the car had reached the goal (goal_error 1-5 mm), a long burst followed one
    detection that put the object 1-2 cm off, and the fallback drove there — ground truth 1.4 cm (seed 16) from
    the zone, neither completion rule then holding.  With the object anchored on the evidence mean
    (`target_update: evidence`) both are placed in the zone."""
    r = run(COMPLETE, seed, ["world.params.dropout=0.5", "world.params.fidelity=paper", "world.params.dropout_burst=15"])
    _placed_without_touching(r)
    assert r.summary["metrics"]["final_error_m"] < 0.01
