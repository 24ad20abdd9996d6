"""Tests for taskflow_sim.viki.depth (ViKi-HyCo eq. 11-18: LiDAR projection, fusion, object localisation)."""

import numpy as np
import pytest
from taskflow_sim.viki.depth import (
    blind_spot_mask,
    blind_spot_radius,
    fuse_depth,
    interpolate_lidar_layers,
    lidar_ranges_to_points,
    object_depth,
    object_position,
    project_lidar_points,
    shrunk_box,
)

INTR = (500.0, 480.0, 320.0, 239.0)
VLP16 = np.deg2rad(np.arange(-15.0, 16.0, 2.0))

# LiDAR axes (x fwd, y left, z up) -> camera axes (x right, y down, z fwd): rows are camera axes.
R_CL = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def T_camera_lidar(R=R_CL, t=(0.0, 0.3, -0.1)):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


# ----------------------------------------------------------------------------- eq. 16-18
def test_shrunk_box_by_hand():
    assert shrunk_box((100, 50, 200, 150)) == (120, 70, 180, 130)
    # w = 21, h = 25: 0.2 w = 4.2, 0.2 h = 5 -> floor(14.2), floor(25), floor(26.8), floor(40)
    assert shrunk_box((10, 20, 31, 45)) == (14, 25, 26, 40)
    assert shrunk_box((10, 20, 31, 45), 0.0) == (10, 20, 31, 45)
    with pytest.raises(ValueError):
        shrunk_box((10, 20, 31, 45), 1.0)
    with pytest.raises(ValueError):
        shrunk_box((31, 20, 10, 45))


def test_object_depth_is_the_mean_of_non_zero_depths_in_the_shrunk_box():
    img = np.zeros((100, 120))
    bbox = (10, 20, 31, 45)  # shrunk box: u 14..26, v 25..40 (inclusive)
    assert object_depth(img, bbox) is None
    img[25, 14] = 2.0
    img[40, 26] = 4.0  # both inclusive corners
    img[30, 20] = np.nan  # no data
    img[24, 14] = 100.0  # just outside
    img[25, 27] = 100.0  # just outside
    assert object_depth(img, bbox) == pytest.approx(3.0)


def test_object_depth_outside_the_image_is_none():
    img = np.ones((50, 60))
    assert object_depth(img, (100, 100, 140, 140)) is None
    assert object_depth(img, (50, 40, 90, 80)) == pytest.approx(1.0)  # partly inside: clipped


def test_object_position_reprojects_to_the_box_centre():
    bbox = (400.0, 300.0, 460.0, 380.0)
    P = object_position(bbox, 3.2, INTR)
    fx, fy, cu, cv = INTR
    assert P[2] == pytest.approx(3.2)
    assert fx * P[0] / P[2] + cu == pytest.approx(430.0)
    assert fy * P[1] / P[2] + cv == pytest.approx(340.0)
    with pytest.raises(ValueError):
        object_position(bbox, 0.0, INTR)


# ----------------------------------------------------------------------------- eq. 11-12
def test_lidar_point_lands_on_the_right_pixel_with_the_right_range():
    P = np.array([[5.0, 1.0, -0.5]])  # LiDAR frame
    img = project_lidar_points(P, T_camera_lidar(), INTR, 640, 480)
    Pc = R_CL @ P[0] + np.array([0.0, 0.3, -0.1])  # (-1.0, 0.8, 4.9)
    u = round(500.0 * Pc[0] / Pc[2] + 320.0)  # 218
    v = round(480.0 * Pc[1] / Pc[2] + 239.0)  # 317
    assert (u, v) == (218, 317)
    assert img[v, u] == pytest.approx(np.sqrt(25.0 + 1.0 + 0.25))
    assert np.count_nonzero(img) == 1
    img_z = project_lidar_points(P, T_camera_lidar(), INTR, 640, 480, value="camera_z")
    assert img_z[v, u] == pytest.approx(4.9)
    img_r = project_lidar_points(P, T_camera_lidar(), INTR, 640, 480, value="camera_range")
    assert img_r[v, u] == pytest.approx(np.linalg.norm(Pc))


def test_lidar_projection_keeps_the_nearest_and_drops_unseen_points():
    P = np.array(
        [
            [4.0, 0.0, 0.0],
            [
                8.0,
                0.0,
                0.0,
            ],  # behind the first one on the same pixel ray (t = 0 for this test)
            [-3.0, 0.0, 0.0],  # behind the camera
            [1.0, 50.0, 0.0],  # outside the image
            [np.nan, 0.0, 0.0],
        ]
    )
    img = project_lidar_points(P, T_camera_lidar(t=(0, 0, 0)), INTR, 640, 480)
    assert img[239, 320] == pytest.approx(4.0)
    assert np.count_nonzero(img) == 1
    with pytest.raises(ValueError):
        project_lidar_points(P, T_camera_lidar(), INTR, 640, 480, value="depth")


def test_interpolation_gives_112_layers_for_16():
    az = np.linspace(-0.6, 0.6, 40)
    ranges = np.full((16, az.size), 7.0)
    rv, ev = interpolate_lidar_layers(ranges, VLP16, 112)
    assert rv.shape == (112, 40) and ev.shape == (112,)
    assert ev[0] == pytest.approx(VLP16[0]) and ev[-1] == pytest.approx(VLP16[-1])
    np.testing.assert_allclose(rv, 7.0)


def test_interpolation_is_linear_in_elevation_between_adjacent_beams():
    ranges = 5.0 + 3.0 * np.repeat(VLP16[:, None], 2, axis=1)  # linear in elevation
    rv, ev = interpolate_lidar_layers(ranges[::-1], VLP16[::-1], 112)  # any beam order
    np.testing.assert_allclose(rv, 5.0 + 3.0 * ev[:, None] * np.ones(2), atol=1e-12)


def test_interpolation_keeps_no_return_beams_as_gaps():
    ranges = np.full((16, 3), 6.0)
    ranges[7, 0] = 0.0
    ranges[7, 1] = np.inf
    rv, ev = interpolate_lidar_layers(ranges, VLP16, 112)
    near = (ev > VLP16[6] + 1e-9) & (ev < VLP16[8] - 1e-9)
    assert np.all(rv[near, 0] == 0.0) and np.all(rv[near, 1] == 0.0)
    np.testing.assert_allclose(rv[near, 2], 6.0)
    np.testing.assert_allclose(rv[~near, :], 6.0)


def test_ranges_to_points_round_trip():
    az = np.linspace(-1.0, 1.0, 7)
    ranges = np.random.default_rng(3).uniform(2.0, 9.0, (16, 7))
    ranges[3, 4] = 0.0
    pts = lidar_ranges_to_points(ranges, VLP16, az)
    assert pts.shape == (16 * 7 - 1, 3)
    np.testing.assert_allclose(np.sort(np.linalg.norm(pts, axis=1)), np.sort(ranges[ranges > 0]))
    p = lidar_ranges_to_points(ranges[:1, :1], VLP16[:1], az[:1])[0]
    assert np.arctan2(p[2], np.hypot(p[0], p[1])) == pytest.approx(VLP16[0])
    assert np.arctan2(p[1], p[0]) == pytest.approx(az[0])


# ----------------------------------------------------------------------------- eq. 13-15
def test_blind_spot_radius_is_the_papers_value():
    assert blind_spot_radius(1.10, np.deg2rad(-15.0)) == pytest.approx(4.1052, abs=1e-4)
    assert blind_spot_radius(0.5, np.deg2rad(15.0)) == pytest.approx(0.5 / np.tan(np.deg2rad(15)))


def test_blind_spot_mask_marks_ground_inside_the_radius():
    # Camera 0.4 m below and 0.2 m ahead of the LiDAR, pitched down 15 deg.
    p = np.deg2rad(15.0)
    Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    R_lc = Ry @ R_CL.T  # camera axes in LiDAR coordinates
    c_l = np.array([0.2, 0.0, -0.4])  # camera centre in the LiDAR frame
    T = np.eye(4)
    T[:3, :3] = R_lc.T
    T[:3, 3] = -R_lc.T @ c_l
    intr, W, H = (200.0, 200.0, 80.0, 59.0), 160, 120
    mask = blind_spot_mask(T, intr, W, H, lidar_height=1.10)
    R = blind_spot_radius(1.10)

    def pixel_of(ground_xy):
        P = np.array([*ground_xy, -1.10])
        Pc = T[:3, :3] @ P + T[:3, 3]
        return round(intr[1] * Pc[1] / Pc[2] + intr[3]), round(intr[0] * Pc[0] / Pc[2] + intr[2])

    cases = [
        ((1.5, 0.0), True),
        ((2.5, 0.0), True),
        ((3.9, 0.3), True),
        ((4.4, 0.0), False),
        ((6.0, -0.5), False),
    ]
    for xy, inside in cases:
        v, u = pixel_of(xy)
        assert 0 <= u < W and 0 <= v < H
        assert bool(mask[v, u]) is inside, (xy, np.hypot(*xy), R)
    assert not mask[0].any()  # top row sees beyond the disc / above the horizon
    # A custom radius moves the boundary.
    v, u = pixel_of((4.4, 0.0))
    assert blind_spot_mask(T, intr, W, H, lidar_height=1.10, radius=5.0)[v, u]


def test_fuse_depth_takes_the_camera_inside_the_mask_and_lidar_elsewhere():
    dl = np.array([[0.0, 9.0], [7.0, 0.0]])
    dc = np.array([[2.0, 3.0], [0.0, 1.5]])
    m = np.array([[True, False], [True, True]])
    # (0,0): camera (mask);  (0,1): LiDAR (no mask);  (1,0): camera has no data -> LiDAR;
    # (1,1): camera (mask).
    np.testing.assert_array_equal(fuse_depth(dl, dc, m), [[2.0, 9.0], [7.0, 1.5]])
    # Where dI_l is zero inside the mask (the paper's premise), it equals the printed eq. 15.
    dl2 = np.where(m, 0.0, dl)
    np.testing.assert_array_equal(fuse_depth(dl2, dc, m), dl2 + m * dc)
    with pytest.raises(ValueError):
        fuse_depth(dl, dc[:1], m)
