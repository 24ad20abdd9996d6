"""The quad_room world on PyBullet: lag dynamics, camera frames, keyframes (teach), collisions."""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
import taskflow_tasks.quad.visual_path  # noqa: F401 - registers the tasks the missions use
from pydantic import ValidationError
from taskflow_robots.quadcopter import Quadcopter, QuadcopterParams
from taskflow_sim.quad.params import QuadRoomParams
from taskflow_sim.quad.teaching import load_keyframe_dir
from taskflow_sim.quad.world import QuadRoom

from taskflow.cli import main as cli_main
from taskflow.errors import MissionError
from taskflow.messages import FeatureView, Image, Silhouette
from taskflow.mission.loader import load_mission

ROOT = Path(__file__).resolve().parents[2]
POSE_REG = ROOT / "missions" / "visual_path_pose_regulation.yaml"


def teach(path, out_dir):
    """``taskflow teach MISSION --out DIR``: the paths it prints, one a line."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli_main(["teach", str(path), "--out", str(out_dir)]) == 0
    return [Path(line) for line in buf.getvalue().splitlines()]
KF = [{"id": 0, "pose": [1.0, 0.0, 1.0, 0.0]}, {"id": 1, "pose": [1.5, 0.3, 0.8, 0.3]}]


def make_world(**params) -> QuadRoom:
    p = QuadRoomParams(room={"x0": -1, "x1": 3.5, "y0": -2, "y1": 2}, keyframes=KF, **params)
    w = QuadRoom(Quadcopter(QuadcopterParams(tau=0.2)), p, seed=0)
    w.reset()
    return w


@pytest.fixture(scope="module")
def world():
    w = make_world(obstacles=[{"x": 1.0, "y": 1.0, "width": 0.1}])
    yield w
    w.close()


def test_first_order_lag_and_body_frame(world):
    world.pose[:] = (0.0, 0.0, 1.0, math.pi / 2)
    world.vel[:] = 0.0
    world.apply({"nu": np.array([0.4, 0.0, 0.0, 0.0])})
    world.advance(0.2)  # one time constant
    assert world.vel[0] == pytest.approx(0.4 * (1 - math.exp(-1)), rel=0.02)
    world.advance(2.0)
    gt = world.ground_truth()
    assert gt["vx"] == pytest.approx(0.4, rel=1e-3)
    # body x points along +y of the world at yaw = 90 deg
    assert abs(gt["x"]) < 1e-9 and gt["y"] > 0.7
    with pytest.raises(ValueError):
        world.apply({"nu": np.array([0.1, 0.2])})
    world.apply({"nu": np.zeros(4)})
    world.advance(2.0)


def test_camera_frames_at_the_camera_rate(world):
    o1 = world.observe()
    o2 = world.observe()
    assert o1.sensors["frame_id"] == o2.sensors["frame_id"]  # no time passed: same frame
    world.advance(0.04)
    o3 = world.observe()
    assert o3.sensors["frame_id"] == o1.sensors["frame_id"] + 1
    msg = o3.sensors["image"]
    assert isinstance(msg, Image) and msg.frame == "camera" and msg.stamp == o3.sensors["frame_t"] == o3.t
    img = msg.pixels
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8 and img.std() > 20 and not img.flags.writeable
    kfs = o3.sensors["keyframes"]
    assert [k.frame for k in kfs] == ["keyframe_0", "keyframe_1"] and kfs[1].pixels is world.keyframe_images[1]
    assert "x" not in o3.state and "pose" not in o3.state  # no ground truth in observations


def test_ground_truth_epsilon_vanishes_at_the_keyframe_pose(world):
    assert world.epsilon_to_keyframe(1, pose=KF[1]["pose"]) == pytest.approx(0.0, abs=1e-6)
    assert world.epsilon_to_keyframe(1, pose=[1.4, 0.3, 0.8, 0.3]) > 2.0


def test_collision_events_and_clearance(world):
    world.pose[:] = (0.4, 1.0, 1.0, 0.0)
    world.vel[:] = 0.0
    world.apply({"nu": np.array([0.5, 0.0, 0.0, 0.0])})
    n0 = world.score.collisions
    seen = []
    for _ in range(50):
        world.advance(0.04)
        seen += list(world.observe().events)
    assert world.score.collisions == n0 + 1 and seen.count("collision") == 1
    s = world.summary_metrics()
    assert s["min_obstacle_clearance_m"] < 0 and s["collisions"] >= 1
    assert {"final_position_error_m", "final_yaw_error_deg", "final_epsilon_px", "min_clearance_m"} <= set(s)


def test_blackout_frames():
    w = make_world(blackout=[(0.0, 0.1)])
    try:
        assert w.observe().sensors["image"].pixels.max() == 0
        w.advance(0.12)
        assert w.observe().sensors["image"].pixels.max() > 0
    finally:
        w.close()


def test_teach_writes_keyframes_that_a_run_can_load(tmp_path):
    paths = teach(POSE_REG, out_dir=tmp_path / "kf")
    assert [p.name for p in paths] == ["kf_000.png", "keyframes.json"]
    meta = json.loads(paths[-1].read_text())
    assert meta["keyframes"][0]["pose"] == [1.5, 0.0, 0.5, 0.0]
    images, _ = load_keyframe_dir(tmp_path / "kf")
    m = load_mission(POSE_REG,
                     overrides=[f"world.params.keyframe_dir={tmp_path / 'kf'}"])
    w = m.world_cls(m.build_robot(), m.world_params(0), 0)
    w.reset()
    try:
        assert np.array_equal(w.keyframe_images[0], images[0])
        # the taught image is what the camera sees at that pose
        assert np.array_equal(w._require_sim().render((1.5, 0.0, 0.5, 0.0)), images[0])
    finally:
        w.close()


def test_missing_or_unreadable_keyframes_fail_at_load_time(tmp_path):
    teach(POSE_REG, out_dir=tmp_path / "kf")
    (tmp_path / "kf" / "kf_000.png").write_bytes(b"not a png")
    with pytest.raises(MissionError, match="unreadable"):
        load_mission(POSE_REG,
                     overrides=[f"world.params.keyframe_dir={tmp_path / 'kf'}"])
    (tmp_path / "kf" / "kf_000.png").unlink()
    with pytest.raises(MissionError, match="missing"):
        load_mission(POSE_REG,
                     overrides=[f"world.params.keyframe_dir={tmp_path / 'kf'}"])
    with pytest.raises(MissionError, match="keyframes.json"):
        load_mission(POSE_REG,
                     overrides=[f"world.params.keyframe_dir={tmp_path / 'nowhere'}"])
    with pytest.raises(ValidationError, match="ids"):
        QuadRoomParams(keyframes=[{"id": 1, "pose": [0, 0, 1, 0]}])


# ---------------------------------------------------------------------------------------------
# geometric (fast) camera, checked against the rendered one


@pytest.fixture(scope="module")
def geo_world():
    w = make_world(obstacles=[{"x": 2.0, "y": 0.3, "width": 0.25}, {"x": 2.2, "y": -0.6, "width": 0.3, "depth": 0.2,
                                                                    "yaw": 0.4}],
                   perception="geometric", pixel_noise=0.0)
    yield w
    w.close()


@pytest.mark.parametrize("pose", [(0.0, 0.0, 1.0, 0.0), (0.5, -0.4, 1.2, 0.35), (1.2, 0.2, 0.8, -0.5)])
def test_geometric_landmarks_lie_on_the_surfaces_the_renderer_shows(geo_world, pose):
    """Every landmark the geometric camera reports is on the surface PyBullet renders at its pixel
    (rendered depth = landmark depth): projection, intrinsics and column occlusion agree."""
    from taskflow_sim.quad.landmarks import project

    cam = geo_world.robot.params.camera
    geo_world.pose[:] = pose
    view = geo_world.camera.landmark_view(pose, 0.0, "camera")
    assert len(view) > 50
    _, depth = geo_world._require_sim().render_with_depth(pose)
    R, t = cam.pose_in_world(pose)
    z, uv = project(geo_world.landmarks[view.ids], R, t, cam.K())
    assert np.allclose(uv, view.uv)
    px = np.round(uv).astype(int)
    rendered = depth[px[:, 1], px[:, 0]]
    # a pixel's depth is exact up to the texture's slope over half a pixel; occluded ones would be far off
    assert np.median(np.abs(rendered - z) / z) < 0.01 and np.mean(np.abs(rendered - z) / z < 0.05) > 0.97


def test_geometric_column_silhouette_matches_the_segmented_image(geo_world):
    from taskflow_tasks.quad.perception import obstacle_edges

    for pose in [(0.0, 0.0, 1.0, 0.0), (0.6, 0.2, 1.0, 0.15), (0.8, -0.3, 1.0, -0.25)]:
        rgb = geo_world._require_sim().render(pose)
        det = obstacle_edges(rgb)
        geo = geo_world.camera.widest_column(pose)
        assert det is not None and geo is not None
        assert abs(geo[0] - det.p1[0]) <= 1.5 and abs(geo[1] - det.p2[0]) <= 1.5, (pose, geo, det)
        assert geo[2] == det.touches_border
    assert geo_world.camera.widest_column((0.0, 0.0, 1.0, math.pi)) is None  # columns behind the camera


def test_geometric_observations_carry_points_and_no_image(geo_world):
    geo_world.pose[:] = (0.0, 0.0, 1.0, 0.0)
    geo_world.advance(0.04)
    o = geo_world.observe()
    assert "image" not in o.sensors and "keyframes" not in o.sensors
    pts, kfs, obstacle = o.sensors["points"], o.sensors["keyframe_points"], o.sensors["obstacle"]
    assert isinstance(pts, FeatureView) and len(pts) > 50 and (pts.frame, pts.stamp) == ("camera", o.sensors["frame_t"])
    assert [k.frame for k in kfs] == ["keyframe_0", "keyframe_1"] and all(isinstance(k, FeatureView) for k in kfs)
    assert isinstance(obstacle, Silhouette) and obstacle.u_left < obstacle.u_right and obstacle.frame == "camera"
    assert geo_world.epsilon_to_keyframe(1, pose=KF[1]["pose"]) == pytest.approx(0.0, abs=1e-9)
    assert geo_world.epsilon_to_keyframe(1, pose=[1.4, 0.3, 0.8, 0.3]) > 2.0


def test_geometric_mode_refuses_keyframe_images(tmp_path):
    teach(POSE_REG, out_dir=tmp_path / "kf")
    with pytest.raises(ValidationError, match="geometric"):
        QuadRoomParams(keyframes=[{"id": 0, "pose": [1.5, 0.0, 0.5, 0.0]}], keyframe_dir=str(tmp_path / "kf"),
                       perception="geometric")


def test_path_deviation_is_the_distance_to_the_taught_polyline():
    w = make_world(start=(0.0, 0.0, 1.0, 0.0))  # path (0,0) → (1,0) → (1.5,0.3)
    try:
        assert w.score.path_deviation((0.5, 0.2)) == pytest.approx(0.2)
        assert w.score.path_deviation((-0.3, 0.4)) == pytest.approx(0.5)  # beyond the start: to the start point
        assert w.score.path_deviation((1.25, 0.15)) == pytest.approx(0.0, abs=1e-12)  # on the second segment
        w.pose[:] = (0.0, 0.0, 1.0, math.pi / 2)
        w.vel[:] = 0.0
        w.apply({"nu": np.array([0.3, 0.0, 0.0, 0.0])})  # sideways off the path, 0.3 m/s for 1 s
        for _ in range(25):
            w.advance(0.04)
        s = w.summary_metrics()
        assert s["path_deviation_max_m"] == pytest.approx(w.pose[1], rel=1e-9) and 0.2 < w.pose[1] < 0.3
        assert 0.0 < s["path_deviation_mean_m"] < s["path_deviation_max_m"]
    finally:
        w.close()


def test_3d_path_deviation_sees_a_climb_flown_below_its_apex_that_the_horizontal_one_cannot():
    w = make_world(start=(0.0, 0.0, 1.0, 0.0))  # path (0,0,1) → (1,0,1) → (1.5,0.3,0.8), heights included
    try:
        assert w.score.path_deviation_3d((0.5, 0.0, 1.0)) == pytest.approx(0.0, abs=1e-12)
        assert w.score.path_deviation_3d((0.5, 0.0, 0.9)) == pytest.approx(0.1)  # 10 cm under the first leg
        assert w.score.path_deviation((0.5, 0.0)) == pytest.approx(0.0, abs=1e-12)  # horizontally on it
        assert w.score.path_deviation_3d((1.25, 0.15, 0.9)) == pytest.approx(0.0, abs=1e-12)  # on the descent
        w.vel[:] = 0.0
        w.apply({"nu": np.array([0.0, 0.0, -0.3, 0.0])})  # straight down under the first leg, 0.3 m/s for 1 s
        for _ in range(25):
            w.advance(0.04)
        s = w.summary_metrics()
        drop = 1.0 - w.pose[2]
        assert 0.2 < drop < 0.3 and s["path_deviation_max_m"] == pytest.approx(0.0, abs=1e-9)
        assert s["path_deviation_3d_max_m"] == pytest.approx(drop, rel=1e-9)
        assert 0.0 < s["path_deviation_3d_mean_m"] < s["path_deviation_3d_max_m"]
    finally:
        w.close()
