"""Tests for taskflow_tasks.viki.image_features (ViKi-HyCo eq. 7-9, feature choice of section II-E)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from taskflow_tasks.viki.image_features import (
    CameraIntrinsics,
    as_intrinsics,
    bbox_corners,
    bbox_features,
    feature_error,
    point_interaction_matrix,
)


def _project(P, fx, fy):
    """Pinhole projection relative to the principal point, px."""
    return np.array([fx * P[0] / P[2], fy * P[1] / P[2]])


def _moved_point(P, V, dt):
    """Static point P seen from the camera after it moved with body twist V for dt (1st order)."""
    R = Rotation.from_rotvec(V[3:] * dt).as_matrix()
    return R.T @ (P - V[:3] * dt)


@pytest.mark.parametrize("fx, fy", [(500.0, 500.0), (620.0, 480.0)])
def test_interaction_matrix_matches_finite_difference_of_projection(fx, fy):
    rng = np.random.default_rng(0)
    dt = 1e-6
    for _ in range(20):
        P = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(1.0, 6.0)])
        V = rng.normal(size=6)
        uv = _project(P, fx, fy)
        L = point_interaction_matrix(uv, P[2], fx, fy)
        ahead = _project(_moved_point(P, V, dt), fx, fy)
        behind = _project(_moved_point(P, V, -dt), fx, fy)
        numeric = (ahead - behind) / (2 * dt)
        np.testing.assert_allclose(L @ V, numeric, rtol=1e-5, atol=1e-4)


def test_interaction_matrix_is_the_papers_eq7_for_equal_focal_lengths():
    f, u, v, Z = 600.0, 35.0, -20.0, 2.5  # the paper's l is f here
    eq7 = np.array(
        [
            [-f / Z, 0, u / Z, u * v / f, -(f + u**2 / f), v],
            [0, -f / Z, v / Z, f + v**2 / f, -u * v / f, -u],
        ]
    )
    np.testing.assert_allclose(point_interaction_matrix([u, v], Z, f), eq7)


def test_interaction_matrix_stacks_two_rows_per_point_eq9():
    uv = np.array([[10.0, 5.0], [-30.0, 12.0], [4.0, -8.0], [0.0, 0.0]])
    L = point_interaction_matrix(uv, [1.0, 2.0, 3.0, 4.0], 500.0)
    assert L.shape == (8, 6)
    for i in range(4):
        np.testing.assert_allclose(
            L[2 * i : 2 * i + 2], point_interaction_matrix(uv[i], i + 1.0, 500.0)
        )


@pytest.mark.parametrize("Z", [0.0, -1.0])
def test_interaction_matrix_rejects_non_positive_depth(Z):
    with pytest.raises(ValueError):
        point_interaction_matrix([1.0, 2.0], Z, 500.0)


def test_corners_follow_eq16_order():
    c = bbox_corners((10, 20, 30, 60))
    np.testing.assert_array_equal(c, [[10, 20], [10, 60], [30, 60], [30, 20]])
    np.testing.assert_array_equal(bbox_features((10, 20, 30, 60)), [10, 20, 10, 60, 30, 60, 30, 20])


@pytest.mark.parametrize("bad", [(1, 2, 3), (30, 20, 10, 60), (10, 60, 30, 20)])
def test_corners_reject_bad_boxes(bad):
    with pytest.raises(ValueError):
        bbox_corners(bad)


def test_feature_error_is_the_max_absolute_component():
    f = np.array([100.0, 50.0, 100.0, 80.0, 140.0, 80.0, 140.0, 50.0])
    f_d = f + np.array([0.5, -1.9, 0.0, 0.3, -0.2, 1.0, 0.0, 0.0])
    assert feature_error(f, f_d) == pytest.approx(1.9)
    assert feature_error(f, f_d) < 2.0  # the paper's "-2 < f - f_d < 2 px" test
    with pytest.raises(ValueError):
        feature_error(f, f[:6])


def test_intrinsics_from_tuple_or_matrix():
    K = np.array([[500.0, 0, 320.0], [0, 510.0, 239.0], [0, 0, 1]])
    assert as_intrinsics(K) == CameraIntrinsics(500.0, 510.0, 320.0, 239.0)
    assert as_intrinsics((500, 510, 320, 239)) == CameraIntrinsics(500.0, 510.0, 320.0, 239.0)
    with pytest.raises(ValueError):
        as_intrinsics((500, 510, 320))
    with pytest.raises(ValueError):
        as_intrinsics((0, 510, 320, 240))
