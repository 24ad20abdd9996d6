"""The imperfection models of viki_ground's "paper" fidelity: drifting odometry, box bias, late detections."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar
from taskflow_sim.core.odometry_slip import SlipOdometry
from taskflow_sim.viki_world import VikiGround, VikiGroundParams, biased_box

ROBOT = Racecar(Racecar.Params())
STILL = {"v": np.zeros(1), "steer": np.zeros(1)}


def test_slip_odometry_scales_the_travel_and_keeps_the_heading():
    odo = SlipOdometry(np.random.default_rng(0), scale_error=0.01, slip_noise=0.0)
    odo.reset(np.array([1.0, 2.0, math.pi / 2]))
    # 1 m ahead (along +y), then a quarter turn in place, then 0.5 m ahead (along -x)
    np.testing.assert_allclose(odo.update(np.array([1.0, 3.0, math.pi / 2])), (1.0, 3.01, math.pi / 2), atol=1e-12)
    np.testing.assert_allclose(odo.update(np.array([1.0, 3.0, math.pi])), (1.0, 3.01, math.pi), atol=1e-12)
    np.testing.assert_allclose(odo.update(np.array([0.5, 3.0, math.pi])), (0.495, 3.01, math.pi), atol=1e-12)


def test_slip_noise_is_seeded_and_zero_error_is_the_truth():
    truth = [np.array([0.1 * k, 0.02 * k * k, 0.05 * k]) for k in range(10)]
    runs = []
    for _ in range(2):
        odo = SlipOdometry(np.random.default_rng(7), scale_error=0.0, slip_noise=0.05)
        odo.reset(truth[0])
        runs.append([odo.update(p) for p in truth[1:]])
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0][-1][:2], truth[-1][:2])  # noise moved it
    exact = SlipOdometry(np.random.default_rng(7), 0.0, 0.0)
    exact.reset(truth[0])
    for p in truth[1:]:
        np.testing.assert_allclose(exact.update(p), p, atol=1e-12)
    with pytest.raises(ValueError, match="scale error"):
        SlipOdometry(np.random.default_rng(0), -1.0, 0.0)


def test_box_bias_shifts_edges_and_stays_in_the_image():
    assert biased_box((10.5, 20.5, 50.5, 80.5), (-1.0, -1.0, 1.0, 1.0), 640, 360) == (9.5, 19.5, 51.5, 81.5)
    assert biased_box((-0.5, 20.5, 639.5, 80.5), (-1.0, 0.0, 1.0, 0.0), 640, 360) == (-0.5, 20.5, 639.5, 80.5)
    assert biased_box((10.5, 20.5, 11.5, 80.5), (3.0, 0.0, -3.0, 0.0), 640, 360) == (11.0, 20.5, 11.0, 80.5)


def test_latency_delivers_each_frame_that_much_later_stamped_at_capture():
    fast = VikiGround(ROBOT, VikiGroundParams(object_distance=2.0, latency=0.12), seed=0)
    fast.reset()
    try:
        o = fast.observe()  # t = 0: the first frame is captured, not delivered yet
        assert "detection" not in o.sensors and o.events == ()
        seen = []
        for _ in range(6):
            fast.apply(STILL)
            fast.advance(0.05)
            o = fast.observe()
            d = o.sensors.get("detection")
            seen.append((round(o.t, 3), None if d is None else round(d.stamp, 3), None if d is None else d.fresh))
        # 15 Hz frames on the 20 Hz ticks: captured at t = 0, 0.1, 0.15, 0.2, ...; each delivered at the
        # first tick >= capture + 0.12 s, stamped with its capture time
        assert seen == [(0.05, None, None), (0.1, None, None), (0.15, 0.0, True), (0.2, 0.0, False),
                        (0.25, 0.1, True), (0.3, 0.15, True)]
    finally:
        fast.close()


def test_the_paper_level_fills_the_models_and_ideal_leaves_them_off():
    ideal = VikiGroundParams()
    assert ideal.latency == 0.0 and ideal.box_bias == (0.0,) * 4 and ideal.odom_scale_error == 0.0
    paper = VikiGroundParams(fidelity="paper")
    assert paper.latency == pytest.approx(0.044) and paper.image_size == (1280, 720) and paper.odom_scale_error > 0
    assert VikiGroundParams(fidelity="paper", latency=0.0).latency == 0.0  # an explicit key wins
