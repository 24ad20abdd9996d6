"""The web view's server side without a browser (taskflow.operate.view, taskflow.operate.view_http): what the page is fed.

The page itself is driven in a real browser by tests/operate/test_view_browser.py.
"""

from __future__ import annotations

import json
import math
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from taskflow.cli import main
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.operate.replay import serve_replay
from taskflow.operate.view import RecordReader, RunView, ViewError, machine_json, open_run
from taskflow.readers.recorded import load_run
from taskflow.readers.scene import Scene, mission_scene
from taskflow.testing import Script, drive

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
MISSIONS = HERE.parent / "missions"


def _walk(node):
    yield node
    for c in node["children"]:
        yield from _walk(c)


def test_the_machine_carries_each_transition_with_its_guard_tree_in_base_units():
    mission = load_mission(TOY)
    m = machine_json(mission, Scene(), ["gt.x"])
    nodes = {n["path"]: n for n in _walk(m["root"])}
    assert nodes["operate"]["history"] and nodes["operate.visit"]["loop"] == "foreach goal in goals"
    assert nodes["done"]["kind"] == "final" and nodes["done"]["outcome"] == "succeeded"
    (guard,) = nodes["operate.visit.approach"]["transitions"]
    assert guard["kind"] == "guard" and guard["dwell"] == pytest.approx(0.2)
    assert guard["guard"]["tree"] == {"metric": "pos_error", "abs": False, "cmp": "<", "value": pytest.approx(0.01),
                                      "param": "tol"}  # $tol = 1 cm, in the metric's unit (m)
    (timeout,) = nodes["search"]["transitions"]
    assert timeout["kind"] == "timeout" and timeout["after"] == 0.5 and timeout["since"] == "search"
    assert {t["kind"] for t in nodes["operate"]["transitions"]} == {"event", "done"}
    assert m["xy"] is None and m["metric_units"]["pos_error"] == "m"


@pytest.fixture(scope="module")
def car_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("car") / "run"
    assert run_mission(load_mission(MISSIONS / "car_waypoints.yaml"), out_dir=out).succeeded
    return out


def _drawn_point(machine: dict, columns: list[str], row: list) -> tuple[float, float]:
    """The point the page draws for a trace row, from the view's JSON alone (view.js ``controlAt``)."""
    x, y, yaw = (row[columns.index(c)] for c in machine["xy"])
    cp = next((machine["control_points"][leaf] for leaf in row[1].split("|") if leaf in machine["control_points"]),
              None)
    if cp is None:
        return x, y
    (a, b), c, s = cp["offset"], math.cos(yaw), math.sin(yaw)
    return x + a * c - b * s, y + a * s + b * c


@pytest.mark.mission
def test_the_car_view_has_its_three_waypoints_and_draws_the_control_point_as_the_figure_does(car_run):
    view = open_run(car_run)
    machine = view.machine()
    waypoints = load_mission(car_run / "mission.yaml").spec.parameters["waypoints"]
    marks = [(m["label"], m["points"]) for m in machine["markers"] if m["kind"] == "waypoint"]
    assert marks == [(f"waypoint {i + 1}", [list(map(float, w))]) for i, w in enumerate(waypoints)]
    assert machine["xy"] == ["gt.x", "gt.y", "gt.yaw"] and machine["bodies"] == []
    assert set(machine["control_points"]) == {"drive.approach", "drive.settle"}
    assert machine["control_points"]["drive.settle"] == {
        "offset": [0.325, 0.0], "label": "control point d = 0.325 m ahead of the rear axle"}
    trace = view.reader.trace(0)
    assert trace["done"]
    drawn = np.array([_drawn_point(machine, trace["columns"], r) for r in trace["rows"]])
    run = load_run(car_run)  # what the figure (taskflow.readers.plots.path_figure) draws
    cx, cy = run.control_track()
    np.testing.assert_allclose(drawn[:, 0], cx)
    np.testing.assert_allclose(drawn[:, 1], cy)
    settle = run.trace["state"] == "drive.settle"
    ahead = np.hypot(cx - run.trace["gt.x"], cy - run.trace["gt.y"])
    np.testing.assert_allclose(ahead[settle], 0.325)  # d ahead of the rear axle, not the axle itself


def test_the_viki_view_has_the_object_where_the_world_places_it(tmp_path):
    from taskflow_sim.viki.scene import object_position

    mission = load_mission(MISSIONS / "viki_hyco.yaml")
    (tmp_path / "trace.csv").write_text("t,state,events,gt.x,gt.y,gt.yaw,gt.obj_x,gt.obj_y\n")
    (tmp_path / "summary.json").write_text(json.dumps({"seed": 3}))
    machine = RunView(mission, tmp_path, live=False).machine()
    (obj,) = [m for m in machine["markers"] if m["kind"] == "object"]
    world = mission.world_params(3)  # the object as drawn for the run's seed
    assert obj["points"] == [list(map(float, object_position(world)))] and obj["radius"] > 0
    assert obj["label"].startswith("object (")
    figure = [m for m in mission_scene(mission, world).markers if m.role == "object"]
    assert [[list(p) for p in m.points] for m in figure] == [obj["points"]]
    assert machine["bodies"] == []  # the robot-frame obj columns are no declared pose: the marker is the object


def test_the_reader_returns_only_complete_lines(tmp_path):
    (tmp_path / "trace.csv").write_text("t,state,events,m.a\n0.0,s,,1.0\n0.05,s,,na")
    reader = RecordReader(tmp_path)
    first = reader.trace(0)
    assert first["columns"] == ["t", "state", "events", "m.a"] and first["rows"] == [[0.0, "s", "", 1.0]]
    with open(tmp_path / "trace.csv", "a") as f:
        f.write("n\n0.1,s,ev,2.5\n")
    later = reader.trace(first["next"])
    assert later["rows"] == [[0.05, "s", "", None], [0.1, "s", "ev", 2.5]] and later["next"] == 3


def test_a_replay_serves_the_record_and_refuses_operator_actions(tmp_path):
    out = tmp_path / "run"
    drive(load_mission(TOY), Script(metrics=lambda s: {"pos_error": 0.0, "visible": 1.0},
                                    actions={"tool": (0.2, "tool_done")}), max_time=60, out_dir=out)
    server = serve_replay(out, "127.0.0.1:0")
    try:
        def get(path: str) -> dict:
            with urllib.request.urlopen(server.url + path, timeout=10) as r:
                return dict(json.loads(r.read()))

        state = get("/state")
        assert state["replay"] and not state["running"] and state["outcome"] == "succeeded"
        trace = get("/view/trace?since=0")
        assert trace["done"] and len(trace["rows"]) == len((out / "trace.csv").read_text().splitlines()) - 1
        assert get("/view/transitions")["records"][0]["cause"] == "start"
        with urllib.request.urlopen(server.url + "/", timeout=10) as r:
            page = r.read().decode()
        assert "/web/view.js" in page and "http" not in page.replace("http-equiv", "")  # nothing from elsewhere
        req = urllib.request.Request(server.url + "/pause", data=b"{}", method="POST",
                                     headers={"Content-Type": "application/json"})
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req, timeout=10)
        assert err.value.code == 409
    finally:
        server.stop()


def test_view_of_what_is_not_a_run_is_one_line_and_exit_1(tmp_path, capsys):
    assert main(["view", str(tmp_path / "nope")]) == 1
    assert "no such folder" in capsys.readouterr().err
    assert main(["view", str(tmp_path)]) == 1
    assert "neither a run folder (it has no trace.csv) nor a batch folder" in capsys.readouterr().err
    with pytest.raises(ViewError):
        open_run(tmp_path)


def test_run_view_needs_the_control_endpoint(capsys):
    assert main(["run", str(TOY), "--view", "--no-control"]) == 1
    assert "--view needs the control endpoint" in capsys.readouterr().err


def test_the_top_view_takes_the_declared_poses_that_the_trace_records():
    mission = load_mission(TOY)
    scene = Scene(poses={"robot": ("base_x", "base_y", "base_yaw"), "part": ("part_x", "part_y", "part_yaw")})
    screw = machine_json(mission, scene, ["gt.base_x", "gt.base_y", "gt.base_yaw", "gt.part_x", "gt.part_y"])
    assert screw["xy"] == ["gt.base_x", "gt.base_y", "gt.base_yaw"]
    assert screw["bodies"] == [{"name": "part", "x": "gt.part_x", "y": "gt.part_y"}]
    no_yaw = machine_json(mission, scene, ["gt.base_x", "gt.base_y"])
    assert no_yaw["xy"] == ["gt.base_x", "gt.base_y", ""] and no_yaw["bodies"] == []
    assert machine_json(mission, scene, ["gt.x", "gt.y"])["xy"] is None  # undeclared columns are not guessed at


def test_a_live_view_learns_the_columns_once_the_header_is_written(tmp_path):
    view = RunView(load_mission(MISSIONS / "car_waypoints.yaml"), tmp_path, live=True)
    (tmp_path / "trace.csv").write_text("")  # the recorder's header is still in its buffer
    assert view.machine()["columns_known"] is False and view.machine()["live"] is True
    (tmp_path / "trace.csv").write_text("t,state,events,gt.x,gt.y\n")
    assert view.machine()["columns_known"] is True and view.machine()["xy"] == ["gt.x", "gt.y", ""]


def test_run_view_prints_the_page_address_and_how_to_replay(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(TOY), "--view", "--quiet", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "view: http://127.0.0.1:" in captured.err
    assert f"replay it: taskflow view {out}" in captured.out
    assert not (out / "control.json").exists()  # removed when the run ended
