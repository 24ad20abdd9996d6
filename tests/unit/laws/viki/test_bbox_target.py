"""Tests for taskflow_tasks.viki.bbox_target (ViKi-HyCo eq. 19 and the MGBM-YOLO static desired box)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from taskflow_tasks.viki.bbox_target import desired_bbox, static_desired_bbox
from taskflow_tasks.viki.image_features import CameraIntrinsics

K = CameraIntrinsics(520.0, 500.0, 320.0, 239.0)


def project_board(X, Y, Z, W, H, quantise):
    """Box of a fronto-parallel W x H board centred at (X, Y, Z) in the camera frame.

    ``quantise`` rounds the edges to whole pixels, as a detector on a pixel grid does.
    """
    u = K.fx * np.array([X - W / 2, X + W / 2]) / Z + K.cu
    v = K.fy * np.array([Y - H / 2, Y + H / 2]) / Z + K.cv
    b = np.array([u[0], v[0], u[1], v[1]])
    return np.round(b) if quantise else b


@settings(max_examples=60, deadline=None)
@given(
    W=st.floats(0.05, 0.6),
    H=st.floats(0.05, 0.6),
    Z_o=st.floats(1.0, 8.0),
    Z_d=st.floats(0.8, 4.0),
    X=st.floats(-1.0, 1.0),
    Y=st.floats(-0.5, 0.5),
    quantise=st.booleans(),
)
def test_eq19_reproduces_the_box_of_the_object_at_the_desired_depth(W, H, Z_o, Z_d, X, Y, quantise):
    current = project_board(X, Y, Z_o, W, H, quantise)
    # The same object at depth Z_d, placed so that its box is centred on the desired centre.
    Xd, Yd = 0.2 * Z_d, 0.35 * Z_d
    truth = project_board(Xd, Yd, Z_d, W, H, quantise=False)
    centre = ((truth[0] + truth[2]) / 2, (truth[1] + truth[3]) / 2)
    got = desired_bbox(current, Z_o, Z_d, centre)
    k = Z_o / Z_d
    # Each rounded edge moves by <= 0.5 px, so the current size is off by <= 1 px, scaled by k;
    # the desired box spreads that error over both of its edges.
    tol = (0.5 * k if quantise else 0.0) + 1e-9
    np.testing.assert_allclose(got, truth, atol=tol)


def test_eq19_by_hand():
    got = desired_bbox((100, 50, 140, 130), Z_o=4.0, Z_d=2.0, desired_centre=(320, 400))
    np.testing.assert_allclose(got, [280, 320, 360, 480])  # twice the size, centred at (320, 400)


def test_eq19_is_recomputed_from_the_current_box_shape():
    a = desired_bbox((0, 0, 10, 40), 2.0, 2.0, (50, 50))
    b = desired_bbox((0, 0, 40, 10), 2.0, 2.0, (50, 50))
    np.testing.assert_allclose(a, [45, 30, 55, 70])
    np.testing.assert_allclose(b, [30, 45, 70, 55])


def test_static_box_is_the_projection_of_the_known_object_at_the_desired_depth():
    W, H, Z_d = 0.07, 0.12, 1.6
    got = static_desired_bbox((W, H), Z_d, K, (320, 300))
    assert got[2] - got[0] == pytest.approx(K.fx * W / Z_d)
    assert got[3] - got[1] == pytest.approx(K.fy * H / Z_d)
    np.testing.assert_allclose(((got[0] + got[2]) / 2, (got[1] + got[3]) / 2), (320, 300))


@pytest.mark.parametrize(
    "args",
    [
        ((0, 0, 10, 10), 0.0, 1.0, (0, 0)),
        ((0, 0, 10, 10), 1.0, -1.0, (0, 0)),
        ((10, 0, 0, 10), 1.0, 1.0, (0, 0)),
        ((0, 0, 10), 1.0, 1.0, (0, 0)),
        ((0, 0, 10, 10), 1.0, 1.0, (0, 0, 0)),
    ],
)
def test_desired_bbox_rejects_bad_input(args):
    with pytest.raises(ValueError):
        desired_bbox(*args)


def test_static_box_rejects_bad_input():
    with pytest.raises(ValueError):
        static_desired_bbox((0.1, -0.1), 1.0, K, (0, 0))
    with pytest.raises(ValueError):
        static_desired_bbox((0.1, 0.1), 0.0, K, (0, 0))
