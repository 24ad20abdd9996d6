"""The remembered obstacle and the committed escape side of the visual-path collision task
(taskflow_tasks.quad.obstacle_memory), against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_robots.quadcopter import QuadCamera
from taskflow_tasks.quad.hierarchy import collision_jacobian
from taskflow_tasks.quad.obstacle_memory import (
    LEFT,
    RIGHT,
    RememberedObstacle,
    Sighting,
    associate,
    associate_view,
    circle_edges,
    closing_in,
    committed_edges,
    edge_rays,
    edges_in_body,
    escape_side,
    fit_circle,
    has_passed,
    propagate,
    remembered_collision,
)


def obstacle(cx: float, cy: float, width: float = 0.1, t: float = 0.0, side: int = 0) -> RememberedObstacle:
    """Edges across the body's x axis, ``width`` apart, centred on (cx, cy)."""
    return RememberedObstacle(np.array([cx, cy + width / 2]), np.array([cx, cy - width / 2]), width, t, side)


def test_edges_of_a_centred_obstacle_land_ahead_of_the_camera_in_the_body_frame():
    # edges at x = -0.1 and 0.1 (normalised), a 0.2 m cylinder: alpha = 2 atan 0.1,
    # rho = 0.1 / sin(atan 0.1) = sqrt(1.01); the camera sits 0.17 m ahead of the centre, 3 cm down
    p1, p2 = edges_in_body([-0.1, 0.0], [0.1, 0.0], 0.2, QuadCamera().T_body_camera())
    assert p1 == pytest.approx([0.17 + math.sqrt(1.01), 0.1])  # left edge: body +y
    assert p2 == pytest.approx([0.17 + math.sqrt(1.01), -0.1])


def test_edges_off_the_axis_keep_their_distance():
    # a 0.1 m cylinder 1 m from the camera at 40 deg to the right: its silhouette is wider than 0.1 in
    # normalised coordinates, but the angle between the edge rays gives back the distance
    b, half = math.radians(40.0), math.asin(0.05 / 1.0)
    x1, x2 = math.tan(b - half), math.tan(b + half)
    T = np.eye(4)
    T[:3, :3] = QuadCamera().R_body_camera()
    p1, p2 = edges_in_body([x1, 0.0], [x2, 0.0], 0.1, T)
    centre = 0.5 * (p1 + p2)
    assert centre == pytest.approx([math.cos(b), -math.sin(b)])
    assert np.hypot(*(p1 - p2)) == pytest.approx(0.1)
    with pytest.raises(ValueError):
        edges_in_body([0.1, 0.0], [0.1, 0.0], 0.1, T)


def test_propagation_follows_the_body_motion():
    ob = obstacle(1.0, 0.0)
    ahead = propagate(ob, [0.5, 0.0, 0.0, 0.0], 1.0)  # 0.5 m forward in 1 s
    assert ahead.centre == pytest.approx([0.5, 0.0]) and ahead.t == 1.0
    turned = propagate(ob, [0.0, 0.0, 0.0, math.pi / 2], 1.0)  # a quarter turn left: it is now on the right
    assert turned.p1 == pytest.approx([0.05, -1.0]) and turned.p2 == pytest.approx([-0.05, -1.0])
    assert propagate(ob, [0.0, 0.2, 0.0, 0.0], 2.0).centre == pytest.approx([1.0, -0.4])
    with pytest.raises(ValueError):
        propagate(turned, [0.0, 0.0, 0.0, 0.0], 0.5)


def test_an_obstacle_is_passed_once_both_edges_are_behind_the_margin():
    assert not has_passed(obstacle(-0.25, 0.5), 0.3)
    assert has_passed(obstacle(-0.35, 0.5), 0.3)
    assert not has_passed(RememberedObstacle(np.array([-0.5, 0.4]), np.array([-0.2, 0.5]), 0.1, 0.0), 0.3)
    # behind, but the drone is still inside its keep-out disc (slid past it, may back up): kept
    assert not has_passed(obstacle(-0.35, 0.2), 0.3, 0.55) and has_passed(obstacle(-0.35, 0.5), 0.3, 0.55)


def test_remembered_collision_is_eq_8_9_of_a_centred_obstacle():
    e, J = remembered_collision(obstacle(0.5, 0.0), 0.5)  # at the keep-out distance: d = 0.2 = W / keep_out
    assert e == pytest.approx(0.0) and pytest.approx(np.array([[0.4, 0, 0, 0, 0, 0]])) == J
    e, J = remembered_collision(obstacle(0.0, 0.4), 0.5)  # beside, inside: d = 0.25
    assert e == pytest.approx(0.25 - 0.2) and pytest.approx(np.array([[0.0, 0.625, 0, 0, 0, 0]])) == J
    # J predicts the change of W / rho when the body moves (passing by leaves it unchanged)
    ob = obstacle(0.3, 0.4)
    e0, J = remembered_collision(ob, 0.5)
    for v in ([0.2, 0.0], [0.0, 0.2], [-0.1, 0.3]):
        dt = 1e-6
        e1, _ = remembered_collision(propagate(ob, [*v, 0.0, 0.0], dt), 0.5)
        assert (J[0, :2] @ v) == pytest.approx((e1 - e0) / dt, rel=1e-4)
    assert (J[0, :2] @ [0.4, -0.3]) == pytest.approx(0.0)  # tangential motion


def test_closing_in_looks_ahead_by_the_activation_time():
    ob = obstacle(1.0, 0.0)
    assert not closing_in(ob, [0.3, 0.0, 0.0, 0.0], 0.55, 0.5)  # 1 - 0.15 = 0.85 m in 0.5 s
    assert closing_in(ob, [1.0, 0.0, 0.0, 0.0], 0.55, 0.5)  # 1 - 0.5 = 0.5 m
    assert not closing_in(ob, [-1.0, 0.0, 0.0, 0.0], 0.55, 0.5)  # moving away
    assert closing_in(obstacle(0.0, 0.5), [0.0, 0.0, 0.0, 0.0], 0.55, 0.5)  # already inside


def test_escape_side_is_away_from_the_obstacle_or_the_fixed_side_when_centred():
    assert escape_side([0.1, 0.0], [0.3, 0.0], 0.05, RIGHT) == LEFT  # right of the axis: pass on the left
    assert escape_side([-0.3, 0.0], [-0.1, 0.0], 0.05, LEFT) == RIGHT
    assert escape_side([-0.02, 0.0], [0.03, 0.0], 0.05, LEFT) == LEFT  # centre 0.005: the fixed rule
    assert escape_side([-0.02, 0.0], [0.03, 0.0], 0.05, RIGHT) == RIGHT
    with pytest.raises(ValueError):
        escape_side([0.0, 0.0], [0.1, 0.0], 0.05, 0)


def test_committed_edges_break_the_symmetry_of_eq_9():
    a, b = committed_edges([-0.05, 0.01], [0.05, 0.01], LEFT, 0.1)
    assert a == pytest.approx([0.05, 0.01]) and b == pytest.approx([0.15, 0.01])
    a, b = committed_edges([-0.05, 0.0], [0.05, 0.0], RIGHT, 0.1)
    assert a == pytest.approx([-0.15, 0.0]) and b == pytest.approx([-0.05, 0.0])
    a, b = committed_edges([0.2, 0.0], [0.4, 0.0], LEFT, 0.1)  # already far enough right: unchanged
    assert a == pytest.approx([0.2, 0.0]) and b == pytest.approx([0.4, 0.0])
    assert committed_edges([-0.05, 0.0], [0.05, 0.0], 0, 0.1)[0] == pytest.approx([-0.05, 0.0])
    # eq. 9 of a centred obstacle has no yaw term (wy): nothing turns the drone; at the committed edges
    # it is -d (x1 + x2) = -0.1 * 0.2, so forward motion in the task's null space turns it left (wy < 0)
    assert collision_jacobian([-0.05, 0.0], [0.05, 0.0], 1.0, 1.0)[0, 4] == pytest.approx(0.0)
    assert collision_jacobian(*committed_edges([-0.05, 0.0], [0.05, 0.0], LEFT, 0.1), 1.0, 1.0)[0, 4] == \
        pytest.approx(-0.02)


def test_a_view_is_matched_to_the_nearest_remembered_obstacle_within_the_gate():
    rems = [obstacle(1.0, 0.0), obstacle(3.0, 0.0)]
    assert associate(rems, obstacle(1.2, 0.1), 0.5) == 0
    assert associate(rems, obstacle(2.9, -0.2), 0.5) == 1
    assert associate(rems, obstacle(2.0, 0.0), 0.5) is None
    assert associate([], obstacle(1.0, 0.0), 0.5) is None


def sighting(origin, centre, radius) -> Sighting:
    """The exact edge rays of a circle seen from ``origin`` (left edge: counter-clockwise of the centre)."""
    v = np.asarray(centre, float) - np.asarray(origin, float)
    rho, b = float(np.hypot(*v)), math.atan2(v[1], v[0])
    h = math.asin(radius / rho)
    return Sighting(np.asarray(origin, float), np.array([math.cos(b + h), math.sin(b + h)]),
                    np.array([math.cos(b - h), math.sin(b - h)]))


@pytest.mark.parametrize("centre, radius", [((1.0, 0.1), 0.03), ((1.2, 0.0), 0.08), ((0.9, -0.15), 0.055)])
def test_the_width_comes_from_the_views_not_from_the_prior(centre, radius):
    """One view: the prior's radius at the distance its angle gives; views along a 0.3 m approach (looming
    for a column dead ahead, parallax for one beside the line) give back the true centre and radius."""
    prior = 0.065
    one = sighting((0.0, 0.0), centre, radius)
    c1, r1 = fit_circle([one], prior)
    assert r1 == pytest.approx(prior, rel=1e-6)
    bearing = math.atan2(centre[1], centre[0])
    assert math.atan2(c1[1], c1[0]) == pytest.approx(bearing, abs=1e-9)  # on the line of sight
    views = [sighting((x, 0.0), centre, radius) for x in np.linspace(0.0, 0.3, 10)]
    c, r = fit_circle(views, prior)
    assert c == pytest.approx(centre, abs=5e-3) and r == pytest.approx(radius, rel=0.03)  # the weak prior pulls by mm
    left, right = circle_edges(c, r, (0.0, 0.0))
    assert np.hypot(*(left - right)) == pytest.approx(2 * r) and left[1] > right[1]


def test_edge_rays_of_the_forward_camera_and_association_by_bearing():
    cam = QuadCamera()
    rays = edge_rays([-0.1, 0.0], [0.1, 0.0], cam.T_body_camera())
    assert rays.origin == pytest.approx([0.17, 0.0])
    assert rays.left == pytest.approx([math.cos(math.atan(0.1)), math.sin(math.atan(0.1))])  # image left: body +y
    assert rays.right == pytest.approx([math.cos(math.atan(0.1)), -math.sin(math.atan(0.1))])
    ahead, aside = obstacle(1.2, 0.0, 0.2), obstacle(0.8, 0.6, 0.1)
    assert associate_view([aside, ahead], rays, 0.05) == 1
    assert associate_view([aside], rays, 0.05) is None  # 37 deg away: another column
    with pytest.raises(ValueError):
        fit_circle([], 0.05)
