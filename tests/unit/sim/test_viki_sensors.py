"""The detection message, the camera model and the dropout model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar
from taskflow_sim.viki.camera import CameraModel, DropoutModel, pixel_box, quantise_box

from taskflow.messages import Detection

RP = Racecar(Racecar.Params()).params


def test_detection_usable_and_stale():
    def make(bbox, depth):
        return Detection(stamp=1.0, frame="front_camera", camera="front", seq=3, bbox=bbox, depth=depth,
                         intrinsics=(1.0, 1.0, 0.0, 0.0), width=8, height=8)

    d = make((1.0, 2.0, 5.0, 9.0), 1.2)
    assert d.detected and d.fresh and not d.stale().fresh and d.stale().bbox == d.bbox
    assert d.stale().stamp == d.stamp and d.stale().frame == "front_camera"
    s = d.stale()
    assert s.stale() is s
    assert not make(None, None).detected
    assert not make((1.0, 2.0, 5.0, 9.0), 0.0).detected


def test_camera_model_principal_point_and_depth_scaled_rays():
    cam = CameraModel("front", RP.front_camera, 320, 180, 5.0)
    fx, fy, cu, cv = cam.intrinsics
    assert (cu, cv) == (160.0, 89.0) and fx == pytest.approx(180 / (2 * math.tan(0.5 * RP.front_camera.fov)))
    T_world_camera = cam.pose(np.eye(4))
    P = np.array([[1.5, 0.2, 0.05], [2.5, -0.4, 0.0]])
    uv, z = cam.project(T_world_camera, P)
    o, d = cam.rays(T_world_camera, uv[:, 0], uv[:, 1])
    np.testing.assert_allclose(o + z[:, None] * d, P, atol=1e-9)  # ray parameter = camera depth


def test_box_quantisation_matches_pixel_centre_coverage():
    assert quantise_box(154.13, 83.13, 165.87, 94.87) == (154.5, 83.5, 165.5, 94.5)
    assert pixel_box((154.5, 83.5, 165.5, 94.5)) == (155, 84, 165, 94)
    a, c, b, d = pixel_box(quantise_box(10.2, 10.2, 10.4, 10.4))  # thinner than a pixel: one pixel
    assert (a, c, b, d) == (10, 10, 10, 10)


def moving(k):
    T = np.eye(4)
    T[0, 3] = 0.01 * k
    return T


def test_dropout_fraction_and_bursts():
    m = DropoutModel(np.random.default_rng(3), 0.3, 3.0, 0.001, 0.002, 0.0)
    misses = np.array([m.frame(moving(k)) for k in range(40000)])
    assert not misses[0]  # a stream starts with a detection
    assert misses.mean() == pytest.approx(0.3, abs=0.02)
    edges = np.flatnonzero(np.diff(np.r_[0, misses.astype(int), 0]))
    bursts = edges[1::2] - edges[::2]
    assert bursts.mean() == pytest.approx(3.0, rel=0.08)


def test_a_still_camera_repeats_its_last_outcome():
    m = DropoutModel(np.random.default_rng(0), 0.5, 1.0, 0.001, 0.002, 0.0)
    out = [m.frame(moving(k)) for k in range(50)]
    while not out[-1]:  # move until a miss
        out.append(m.frame(moving(len(out))))
    still = moving(len(out) - 1)
    assert all(m.frame(still) for _ in range(200))  # the same image: missed forever
    m.reset()
    assert m.frame(still) is False  # a new stream starts detected
    noisy = DropoutModel(np.random.default_rng(0), 0.5, 1.0, 0.001, 0.002, 0.2)
    flips = [noisy.frame(np.eye(4)) for _ in range(300)]
    assert 0 < sum(flips) < 300  # with sensor noise a still image changes outcome now and then


def test_dropout_off_and_bad_parameters():
    m = DropoutModel(np.random.default_rng(0), 0.0, 1.0, 0.001, 0.002, 0.0)
    assert not any(m.frame(moving(k)) for k in range(100))
    with pytest.raises(ValueError):
        DropoutModel(np.random.default_rng(0), 1.0, 1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        DropoutModel(np.random.default_rng(0), 0.2, 0.5, 0.0, 0.0, 0.0)
