"""Figures that tell the truth: the car's path is drawn at the point its guards measure, with the
waypoints; every axis carries its unit; guard thresholds and transitions are drawn where they are."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.readers.plots import command_figure, metrics_figure, path_figure, plot_recorded
from taskflow.readers.recorded import load_run
from taskflow.readers.scene import mission_scene
from taskflow.registry import ROBOTS
from taskflow.units import UNITS

ROOT = Path(__file__).resolve().parents[2]
CAR = ROOT / "missions" / "car_waypoints.yaml"


@pytest.fixture(scope="module")
def car_run(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    out = tmp_path_factory.mktemp("car") / "run"
    result = run_mission(load_mission(CAR), out_dir=out)
    assert result.succeeded
    return load_run(out)


def _line(ax, prefix: str):  # type: ignore[no-untyped-def]
    found = [ln for ln in ax.get_lines() if str(ln.get_label()).startswith(prefix)]
    assert found, f"no line labelled {prefix!r}: {[ln.get_label() for ln in ax.get_lines()]}"
    return found[0]


def test_car_path_is_drawn_at_the_control_point_d_ahead_of_the_axle(car_run) -> None:  # type: ignore[no-untyped-def]
    d = car_run.mission.spec.profiles["gains"]["fine"]["d"]
    assert d == 0.325
    ax = path_figure(car_run).axes[0]
    tr = car_run.trace
    settle = tr["state"] == "drive.settle"
    line = _line(ax, "drive.settle: control point d = 0.325 m ahead of the rear axle")
    np.testing.assert_allclose(line.get_xdata(), tr["gt.x"][settle] + d * np.cos(tr["gt.yaw"][settle]))
    np.testing.assert_allclose(line.get_ydata(), tr["gt.y"][settle] + d * np.sin(tr["gt.yaw"][settle]))
    axle = _line(ax, "robot pose (ground truth)")  # the rear axle, drawn apart in grey
    np.testing.assert_allclose(axle.get_xdata(), tr["gt.x"])


def test_car_figure_shows_every_waypoint_and_that_the_control_point_reached_it(car_run) -> None:  # type: ignore[no-untyped-def]
    ax = path_figure(car_run).axes[0]
    waypoints = car_run.mission.spec.parameters["waypoints"]
    marks = [(m.label, m.points[0]) for m in car_run.scene.markers if m.role == "waypoint"]
    assert marks == [(f"waypoint {i + 1}", tuple(w)) for i, w in enumerate(waypoints)]
    drawn = [ln for ln in ax.get_lines() if ln.get_marker() == "X"]
    assert sorted((float(ln.get_xdata()[0]), float(ln.get_ydata()[0])) for ln in drawn) == sorted(map(tuple, waypoints))
    cx, cy = car_run.control_track()
    t, x, y = car_run.trace["t"], car_run.trace["gt.x"], car_run.trace["gt.y"]
    for it in car_run.summary["iterations"]:  # when each waypoint's item ended (reached)
        i = int(np.searchsorted(t, it["t_end"])) - 1
        w = it["item"]
        assert math.hypot(cx[i] - w[0], cy[i] - w[1]) < 0.05  # the point the guard measures is on it
        assert math.hypot(x[i] - w[0], y[i] - w[1]) > 0.25  # the rear axle is d away: drawing it would lie


def test_metric_axes_carry_units_and_guard_thresholds_are_drawn_at_their_values(car_run) -> None:  # type: ignore[no-untyped-def]
    fig = metrics_figure(car_run)
    by_label = {ax.get_ylabel(): ax for ax in fig.axes}
    assert set(by_label) == {"pos_error [m]", "heading_error [rad]", "speed [m/s]"}
    horizontal = sorted(float(ln.get_ydata()[0]) for ln in by_label["pos_error [m]"].get_lines()
                        if ln.get_linestyle() == "--")
    assert horizontal == pytest.approx([0.03, 0.25])  # "pos_error < 3 cm", "pos_error < 25 cm"
    legend = [t.get_text() for t in by_label["pos_error [m]"].get_legend().get_texts()]
    assert "guard: pos_error < 0.03 m (settle → reached)" in legend


def test_command_axes_name_each_component_with_its_unit(car_run) -> None:  # type: ignore[no-untyped-def]
    assert [ax.get_ylabel() for ax in command_figure(car_run).axes] == ["v [m/s]", "steer [rad]"]


def test_transitions_are_vertical_lines_named_by_the_state_entered(car_run) -> None:  # type: ignore[no-untyped-def]
    top = metrics_figure(car_run).axes[0]
    fired = [r for r in car_run.transitions if r.cause != "start"]
    vlines = [ln for ln in top.get_lines() if ln.get_linestyle() == ":"]
    assert sorted(float(ln.get_xdata()[0]) for ln in vlines) == pytest.approx(sorted(r.t for r in fired))
    labels = " | ".join(t.get_text() for t in top.texts)
    for name in ("settle", "reached", "approach", "done"):
        assert name in labels


def test_legends_sit_outside_the_data(car_run) -> None:  # type: ignore[no-untyped-def]
    for fig in (path_figure(car_run), metrics_figure(car_run)):
        FigureCanvasAgg(fig).draw()
        for ax in fig.axes:
            leg = ax.get_legend()
            if leg is not None:
                assert not leg.get_window_extent().overlaps(ax.get_window_extent())


def test_plot_writes_the_figures(car_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    paths = plot_recorded(car_run)
    assert [p.name for p in paths] == ["path.png", "commands.png", "metrics.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)


@pytest.mark.parametrize("name", [n for n in ROBOTS.names() if not ROBOTS.get(n).__module__.startswith("toys")])
def test_every_robot_names_each_command_component_with_a_unit(name: str) -> None:
    robot = ROBOTS.get(name)
    assert set(robot.command_units) == set(robot.command_keys)
    for key, n in robot.command_keys.items():
        parts = robot.command_units[key]
        assert len(parts) == n and len({p for p, _ in parts}) == n
        assert all(unit in UNITS for _, unit in parts)


def test_the_visual_path_scene_has_its_keyframes_obstacles_and_walls() -> None:
    m = load_mission(ROOT / "missions" / "visual_path_obstacles.yaml")
    wp = m.world_params(0)
    scene = mission_scene(m, wp)
    roles = [mk.role for mk in scene.markers]
    assert roles.count("keyframe") == len(wp.keyframes) and roles.count("obstacle") == len(wp.obstacles) > 0
    assert roles.count("boundary") == 1 and scene.poses["robot"] == ("x", "y", "yaw")
    for mk, k in zip([mk for mk in scene.markers if mk.role == "keyframe"], wp.keyframes):
        assert mk.points[0] == k.pose[:2] and mk.yaw == k.pose[3]
    assert math.isclose(sum(1 for mk in scene.markers if mk.role == "start"), 1)
