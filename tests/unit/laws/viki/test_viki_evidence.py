"""The evidence rules of ViKi-HyCo (taskflow_tasks.viki.evidence), against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.racecar import RacecarParams
from taskflow_tasks.viki.evidence import box_cut_by_border, cut_box_near_point, goal_offset, view_shift, view_shifts

from taskflow.spatial import R_body_optical, planar_apply_inverse, transform


@pytest.mark.parametrize("bbox, cut", [
    ((100.5, 50.5, 140.5, 120.5), False),   # well inside a 640x360 image
    ((-0.5, 50.5, 40.5, 120.5), True),      # touches the left border
    ((1.5, 50.5, 40.5, 120.5), True),       # 2 px from it: within the margin
    ((2.5, 50.5, 40.5, 120.5), False),      # 3 px: whole
    ((100.5, 50.5, 637.5, 120.5), True),    # right: 2 px from W - 0.5 = 639.5
    ((100.5, 50.5, 636.5, 120.5), False),
    ((100.5, 1.5, 140.5, 120.5), True),     # top
    ((100.5, 50.5, 140.5, 357.5), True),    # bottom: 2 px from H - 0.5 = 359.5
    ((100.5, 50.5, 140.5, 356.5), False),
])
def test_box_cut_by_border_with_a_2px_margin(bbox, cut):
    assert box_cut_by_border(bbox, 640, 360, 2.0) is cut


def test_margin_zero_means_touching_and_bad_inputs_are_refused():
    assert box_cut_by_border((-0.5, 10.0, 20.0, 30.0), 640, 360, 0.0)
    assert not box_cut_by_border((0.5, 10.0, 20.0, 30.0), 640, 360, 0.0)
    with pytest.raises(ValueError, match="image size"):
        box_cut_by_border((0.5, 10.0, 20.0, 30.0), 0, 360, 2.0)
    with pytest.raises(ValueError, match="margin_px"):
        box_cut_by_border((0.5, 10.0, 20.0, 30.0), 640, 360, -1.0)


# a level camera 1 m up, 0.4 m ahead of the rear axle: pixel (u, v) looks along body (1, -(u - 320)/100, -(v - 180)/100)
LEVEL = transform(R_body_optical(), (0.4, 0.0, 1.0))
K = (100.0, 100.0, 320.0, 180.0)


@pytest.mark.parametrize("bbox, point", [
    ((-0.5, 100.0, 220.0, 280.0), (1.4, 1.0)),     # cut left: inner column 220, ray (1, 1, -1) meets the floor at t = 1
    ((420.0, 100.0, 639.5, 230.0), (2.4, -2.0)),   # cut right: inner column 420, ray (1, -1, -0.5): t = 2
    ((300.0, -0.5, 340.0, 280.0), (1.4, 0.0)),     # cut by the top only: the centre column 320
    ((-0.5, 100.0, 220.0, 150.0), None),           # bottom edge above the horizon: the ray never meets the floor
    ((100.0, 100.0, 220.0, 359.5), None),          # cut by the bottom: the base is below the image, no bound
    ((-0.5, 100.0, 639.5, 280.0), None),           # cut by both sides
])
def test_cut_box_near_point_against_hand_computed_rays(bbox, point):
    got = cut_box_near_point(bbox, 640, 360, 2.0, K, LEVEL)
    if point is None:
        assert got is None
    else:
        assert got is not None and got == pytest.approx(point, abs=1e-12)


@pytest.mark.parametrize("distance", [1.5, 2.0, 2.6])
@pytest.mark.parametrize("bearing", [0.46, 0.49, 0.52, -0.46, -0.49, -0.52])
def test_a_cylinder_cut_by_the_side_border_is_placed_no_farther_than_it_is(distance, bearing):
    """The racecar's front camera and a 4 cm bottle cut by the image's side: the floor point lies on the
    camera's side of the bottle, outside it and within 5 cm of its surface (eq. 18 put it 35-42 cm beyond)."""
    mount = RacecarParams().front_camera
    T = mount.T_body_camera()
    f = mount.focal_px()
    K_car = (f, f, mount.width / 2, mount.height / 2 - 1)
    r, h = 0.04, 0.25
    O = np.array([distance * math.cos(bearing), distance * math.sin(bearing)])
    a = np.linspace(0.0, 2 * math.pi, 96, endpoint=False)
    ring = O + r * np.stack([np.cos(a), np.sin(a)], axis=1)
    P = np.vstack([np.column_stack([ring, np.full(96, z)]) for z in (0.0, h)])
    Pc = (P - T[:3, 3]) @ T[:3, :3]  # camera frame: R^T (P - t)
    u, v = f * Pc[:, 0] / Pc[:, 2] + K_car[2], f * Pc[:, 1] / Pc[:, 2] + K_car[3]
    box = (max(u.min(), -0.5), max(v.min(), -0.5), min(u.max(), mount.width - 0.5), min(v.max(), mount.height - 0.5))
    assert box[0] < box[2] and box_cut_by_border(box, mount.width, mount.height, 2.0)  # a cut, visible box
    N = cut_box_near_point(box, mount.width, mount.height, 2.0, K_car, T)
    assert N is not None
    cam = T[:2, 3]
    assert np.hypot(*(N - cam)) < np.hypot(*(O - cam))  # nearer than the axis
    assert r < np.hypot(*(N - O)) < r + 0.05


def test_the_object_seen_from_the_robot_and_goal_offset():
    # robot at (1, 2) facing +y: a point at (1, 3) is 1 m ahead, one at (0, 2) is 1 m to the left
    pose = (1.0, 2.0, math.pi / 2)
    np.testing.assert_allclose(planar_apply_inverse(pose, (1.0, 3.0)), (1.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(planar_apply_inverse(pose, (0.0, 2.0)), (0.0, 1.0), atol=1e-12)
    np.testing.assert_allclose(goal_offset(pose, (1.0, 3.0), (1.0, 0.0)), (0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(goal_offset(pose, (0.9, 3.05), (1.0, 0.0)), (0.05, 0.1), atol=1e-12)


def test_view_shift_is_translation_plus_lever_arm_rotation():
    g = (-0.9, 0.0)
    assert view_shift((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), g) == 0.0
    assert view_shift((0.0, 0.0, 0.0), (0.003, 0.004, 0.0), g) == pytest.approx(0.005)
    # rotating by a about the rear axle moves the point 0.9 m behind by 2 * 0.9 * sin(a / 2)
    a = 0.02
    assert view_shift((0.0, 0.0, 0.0), (0.0, 0.0, a), g) == pytest.approx(2 * 0.9 * math.sin(a / 2))


def test_view_shifts_gives_each_stored_pose_its_own_shift():
    """Three poses then: the same one (0), 3 cm back along x (0.03), and turned by 0.1 rad in place with
    the point 1 m ahead (chord 2 sin(0.05) = 0.09996 m)."""
    now = (0.0, 0.0, 0.0)
    then = [(0.0, 0.0, 0.0), (-0.03, 0.0, 0.0), (0.0, 0.0, 0.1)]
    got = view_shifts(then, now, (1.0, 0.0))
    assert got.shape == (3,)
    assert got == pytest.approx([0.0, 0.03, 2 * math.sin(0.05)], abs=1e-12)
    assert [view_shift(p, now, (1.0, 0.0)) for p in then] == pytest.approx(got.tolist(), abs=0.0)
