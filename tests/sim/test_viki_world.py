"""The viki_ground world on PyBullet: both perception modes agree, cameras, events, rates, dropout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar
from taskflow_sim.viki.world import VikiGround

ROBOT = Racecar(Racecar.Params())
STILL = {"v": np.zeros(1), "steer": np.zeros(1)}


def make(seed=0, **params):
    w = VikiGround(ROBOT, VikiGround.Params(**params), seed=seed)
    w.reset()
    return w


@pytest.mark.parametrize("kind, camera, bearing, yaw", [
    ("can", "front", 0.1, 0.0), ("carton", "front", -0.2, 0.6), ("bottle", "rear", math.pi + 0.1, 0.0),
])
def test_geometric_and_rendered_boxes_and_depths_agree(kind, camera, bearing, yaw):
    out = {}
    for mode in ("geometric", "rendered"):
        w = make(perception=mode, object_kind=kind, object_distance=1.3, object_bearing=bearing, object_yaw=yaw,
                 initial_camera=camera, image_size=(320, 180), pixel_noise=0.0, depth_noise=0.0)
        try:
            d = w.observe().sensors["detection"]
            c = 0.5 * (np.array(d.bbox[:2]) + np.array(d.bbox[2:]))
            out[mode] = (np.array(d.bbox), d.depth, d.depth_at(*c), d.intrinsics)
            if mode == "rendered" and camera == "front":
                assert w.sensors.lidar is not None and w.sensors.lidar.scans == 1 and len(w.sensors.lidar.points_w) > 0
        finally:
            w.close()
    g, r = out["geometric"], out["rendered"]
    assert g[3] == r[3] and g[3][2:] == (160.0, 89.0)
    assert np.max(np.abs(g[0] - r[0])) <= 1.0
    assert g[1] == pytest.approx(r[1], abs=0.01) and g[2] == pytest.approx(r[2], abs=0.01)


def test_placement_ground_truth_and_summary():
    w = make(start=(1.0, 2.0, 0.5), object_distance=2.0, object_bearing=0.2, goal=(1.0, 0.0))
    try:
        gt = w.ground_truth()
        assert (w.object.x, w.object.y) == pytest.approx((1.0 + 2 * math.cos(0.7), 2.0 + 2 * math.sin(0.7)))
        assert (gt["obj_x"], gt["obj_y"]) == pytest.approx((2 * math.cos(0.2), 2 * math.sin(0.2)), abs=1e-6)
        assert (gt["err_x"], gt["err_y"]) == pytest.approx((gt["obj_x"] - 1.0, gt["obj_y"]))
        s = w.summary_metrics()
        assert s["final_error_x_m"] == pytest.approx(gt["err_x"]) and s["object_kind"] == "can"
    finally:
        w.close()
    w = make(object_xy=(3.0, -1.0))
    try:
        assert (w.object.x, w.object.y) == (3.0, -1.0)
    finally:
        w.close()


def test_camera_rate_events_and_switching():
    w = make(object_distance=2.0)
    try:
        first = w.observe()
        assert first.events == ("target_found",) and first.sensors["detection"].fresh
        fresh = 1
        for _ in range(20):  # 1 s at 20 Hz
            w.apply(STILL)
            w.advance(0.05)
            o = w.observe()
            fresh += o.sensors["detection"].fresh
            assert o.events == ()
        assert fresh == 16  # frames at t = 0, 1/15, ..., 1 s: 15 Hz
        w.select_sensors(())  # the kinematic state: no camera at all
        w.apply(STILL)
        w.advance(0.05)
        o = w.observe()
        assert "detection" not in o.sensors and o.sensors["camera"] is None and o.events == ()
        w.select_sensors(("rear_camera",))  # the object is in front: the rear camera misses it
        w.apply(STILL)
        w.advance(0.05)
        o = w.observe()
        assert o.sensors["detection"].camera == "rear" and not o.sensors["detection"].detected
        assert o.events == ()  # nothing was seen by this camera, so nothing is lost
        w.apply(STILL)  # nothing selected since: the rear camera stays active
        w.advance(0.05)
        assert w.observe().sensors["camera"] == "rear"
        w.select_sensors(("front_camera", "lidar"))
        w.apply(STILL)
        w.advance(0.05)
        assert w.observe().events == ("target_found",)
        with pytest.raises(ValueError, match="one camera at a time of front_camera, rear_camera"):
            w.select_sensors(("front_camera", "rear_camera"))
        with pytest.raises(ValueError, match="asked for top_camera"):
            w.select_sensors(("top_camera",))
        with pytest.raises(ValueError, match="keys"):
            w.apply({"v": np.zeros(1)})
    finally:
        w.close()


def test_object_out_of_view_is_not_detected():
    w = make(object_distance=2.0, object_bearing=math.pi / 2)
    try:
        o = w.observe()
        assert not o.sensors["detection"].detected and o.events == ()
    finally:
        w.close()


def drive_trace(seed, **params):
    w = make(seed=seed, object_distance=2.4, dropout=0.3, **params)
    boxes = []
    try:
        for k in range(60):
            if k:  # frames are taken as the world steps (reset takes the first): observe every one
                w.advance(0.05)
            o = w.observe()
            d = o.sensors["detection"]
            if d.fresh:
                boxes.append(d.bbox)
            w.apply({"v": np.array([0.3]), "steer": np.array([0.05 * math.sin(k / 7)])})
        return boxes, w.summary_metrics()
    finally:
        w.close()


def test_dropout_is_seeded_and_counted():
    a, sa = drive_trace(5)
    b, sb = drive_trace(5)
    c, _ = drive_trace(6)
    assert a == b and a != c
    assert sa["detections_missed"] == sum(x is None for x in a) > 0
    assert sa["detections"] + sa["detections_missed"] == sa["frames"] == len(a)
    assert 0.1 < sa["dropout_fraction"] < 0.5


def _same(a, b):
    assert a.t == b.t and a.events == b.events and a.sensors == b.sensors and a.state.keys() == b.state.keys()
    for k in a.state:
        np.testing.assert_array_equal(a.state[k], b.state[k])


@pytest.mark.parametrize("params", [
    {"dropout": 0.3, "odom_slip": 0.05, "odom_scale_error": 0.02},
    {"latency": 0.12, "dropout": 0.2},
])
def test_observe_is_pure_two_calls_agree_and_the_run_does_not_change(params):
    """observe() only reads: two calls in a row return equal observations, and a run that observes
    twice per tick sees the same observations as one that observes once (frames and drift happen as it steps)."""
    runs = []
    for twice in (False, True):
        w = make(seed=3, object_distance=2.4, **params)
        seen = []
        try:
            for k in range(30):
                if k:
                    w.advance(0.05)
                o = w.observe()
                if twice:
                    _same(o, w.observe())
                seen.append(o)
                w.apply({"v": np.array([0.3]), "steer": np.array([0.05 * math.sin(k / 7)])})
            runs.append((seen, w.summary_metrics()))
        finally:
            w.close()
    (a, sa), (b, sb) = runs
    assert sa == sb and len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.t == y.t and x.events == y.events
        np.testing.assert_array_equal(x.state["pose"], y.state["pose"])
        dx, dy = x.sensors.get("detection"), y.sensors.get("detection")
        assert (dx is None) == (dy is None) and (dx is None or (dx.bbox, dx.seq, dx.fresh) == (dy.bbox, dy.seq, dy.fresh))
