"""ViKi-HyCo's ground-truth clearance to the object: the car's footprint measured from its model, the
footprint distance against a sampled oracle, and the summary of a normal run and of a run into the object (its
``contact`` metric and the mission's ``never_touches`` property, broken by the world's ``contact`` event)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import taskflow_robots.racecar  # noqa: F401 - registers racecar
from taskflow_robots.racecar import Racecar
from taskflow_sim.core.bodies import BodyOptions, make_body
from taskflow_sim.viki.clearance import Footprint, footprint_clearance, measure_footprint
from taskflow_sim.viki.objects import SHAPES, PlacedObject
from taskflow_tasks.core.keep_out import RACECAR_BODY

from taskflow.mission.loader import load_mission
from taskflow.testing import run_on_world

FORWARD = Path(__file__).resolve().parents[2] / "missions" / "viki_forward.yaml"


def test_the_racecar_footprint_covers_its_wheels_and_front_camera():
    fp = measure_footprint(make_body(Racecar(Racecar.Params()), BodyOptions()))
    # rear wheels (radius 0.05 about the rear axle, outer faces at ±0.145) to the ZED camera box's front face
    assert (fp.x_min, fp.x_max) == pytest.approx((-0.05, 0.4065), abs=1e-3)
    assert (fp.y_min, fp.y_max) == pytest.approx((-0.145, 0.145), abs=1e-3)
    # the keep-out's default body (the ViKi tasks' keep_out_body) covers it
    x0, x1, y0, y1 = RACECAR_BODY
    assert x0 <= fp.x_min and x1 >= fp.x_max and y0 <= fp.y_min and y1 >= fp.y_max


def _outline(obj: PlacedObject, n: int = 400) -> np.ndarray:
    """Dense points on the object's base outline (world)."""
    s = obj.shape
    if s.shape == "cylinder":
        a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
        return np.stack([obj.x + s.size[0] * np.cos(a), obj.y + s.size[0] * np.sin(a)], axis=1)
    hx, hy = 0.5 * s.size[0], 0.5 * s.size[1]
    return _rect_outline(obj.x, obj.y, obj.yaw, -hx, hx, -hy, hy, n)


def _rect_outline(x, y, yaw, u0, u1, v0, v1, n=400) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n // 4, endpoint=False)
    local = np.concatenate([np.stack([u0 + (u1 - u0) * t, np.full_like(t, v0)], 1),
                            np.stack([np.full_like(t, u1), v0 + (v1 - v0) * t], 1),
                            np.stack([u1 - (u1 - u0) * t, np.full_like(t, v1)], 1),
                            np.stack([np.full_like(t, u0), v1 - (v1 - v0) * t], 1)])
    c, s = math.cos(yaw), math.sin(yaw)
    return local @ np.array([[c, s], [-s, c]]) + [x, y]


def _inside_rect(pts, x, y, yaw, box) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    d = pts - [x, y]
    u, v = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    return (u >= box[0]) & (u <= box[1]) & (v >= box[2]) & (v <= box[3])


@pytest.mark.parametrize("kind", ["can", "carton"])
def test_footprint_distance_matches_a_sampled_oracle(kind):
    """The oracle: dense points on both outlines; they overlap when a point of one lies in the other
    (or the object's centre lies in the car), else the distance is the closest pair of points."""
    rng = np.random.default_rng(7)
    fp = Footprint(-0.05, 0.4065, -0.145, 0.145)
    box = (fp.x_min, fp.x_max, fp.y_min, fp.y_max)
    for _ in range(60):
        robot = (float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-math.pi, math.pi)))
        obj = PlacedObject(SHAPES[kind], float(rng.uniform(-0.5, 0.8)), float(rng.uniform(-0.5, 0.5)),
                           float(rng.uniform(-math.pi, math.pi)))
        got = footprint_clearance(fp, robot, obj)
        car_pts, obj_pts = _rect_outline(*robot, *box), _outline(obj)
        r = SHAPES[kind].footprint_radius() if kind == "can" else None
        overlap = _inside_rect(obj_pts, *robot, box).any() or _inside_rect(np.array([[obj.x, obj.y]]), *robot, box).any()
        if r is not None:
            overlap |= bool((np.hypot(car_pts[:, 0] - obj.x, car_pts[:, 1] - obj.y) <= r).any())
        else:
            hx, hy = 0.5 * SHAPES[kind].size[0], 0.5 * SHAPES[kind].size[1]
            overlap |= bool(_inside_rect(car_pts, obj.x, obj.y, obj.yaw, (-hx, hx, -hy, hy)).any())
        if overlap:
            assert got == 0.0
        else:
            want = float(np.min(np.linalg.norm(car_pts[:, None, :] - obj_pts[None, :, :], axis=2)))
            assert got == pytest.approx(want, abs=3e-3)  # the oracle's point spacing


def test_a_normal_run_keeps_clear_of_the_object_and_a_run_into_it_reports_the_contact():
    normal = run_on_world(load_mission(FORWARD), seed=0)
    m = normal.summary["metrics"]
    assert normal.outcome == "succeeded" and m["contact"] is False
    assert normal.summary["properties"]["never_touches"] == {"pattern": "absence", "verdict": "held", "t": None}
    # the car ends with the object 1 m ahead of its rear axle: the front of its footprint is 0.41 m ahead
    radius = SHAPES[m["object_kind"]].footprint_radius()
    assert 0.4 < m["min_clearance_m"] <= m["object_x_m"] - 0.4065 - radius + 1e-3
    # the mission's goal 0.3 m ahead of the rear axle lies inside the car: without the keep-out it drives
    # into the object (what the clearance must report)...
    bad_goal = ["parameters.goal=[0.3, 0.0]"]
    into = run_on_world(load_mission(FORWARD, [*bad_goal, "machine.states.forward.task.params.keep_out_margin=0"]),
                        seed=0, max_time=12.0)
    m = into.summary["metrics"]
    assert m["contact"] is True and m["min_clearance_m"] == 0.0
    # the world's contact event (ground truth) breaks the mission's `never: event(contact)` at the touch
    touched = into.summary["properties"]["never_touches"]
    assert touched["verdict"] == "violated" and 0.0 < touched["t"] < 12.0
    assert m["object_x_m"] < 0.4065 + SHAPES[m["object_kind"]].footprint_radius() + 0.005  # pinned at the car's front
    # ...and with the mission's keep-out (the car's footprint, 0.3 m margin) the same bad goal keeps clear
    kept = run_on_world(load_mission(FORWARD, bad_goal), seed=0, max_time=12.0).summary["metrics"]
    assert kept["contact"] is False and kept["min_clearance_m"] > 0.1
