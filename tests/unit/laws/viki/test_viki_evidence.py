"""The evidence rules of ViKi-HyCo (taskflow_tasks.viki.evidence), against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_tasks.viki.evidence import box_cut_by_border, goal_offset, view_shift, view_shifts

from taskflow.spatial import planar_apply_inverse


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
