"""The web view's server side without a browser (taskflow.view, taskflow.view_http): what the page is fed.

The page itself is driven in a real browser by tests/test_view_browser.py.
"""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from taskflow.cli import main
from taskflow.loader import load_mission
from taskflow.testing import Script, drive
from taskflow.view import RecordReader, ViewError, machine_json, markers, open_run
from taskflow.view_http import serve_replay

HERE = Path(__file__).resolve().parent
TOY = HERE / "machine" / "missions" / "toy_full.yaml"


def _walk(node):
    yield node
    for c in node["children"]:
        yield from _walk(c)


def test_the_machine_carries_each_transition_with_its_guard_tree_in_base_units():
    mission = load_mission(TOY)
    m = machine_json(mission, mission.raw, ["gt.x"])
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


def test_markers_are_point_lists_and_rooms_never_a_single_robot_frame_goal():
    resolved = {"world": {"params": {"room": {"x0": -1, "x1": 3, "y0": -1, "y1": 2, "height": 2},
                                     "keyframes": [{"id": 0, "pose": [0.5, 0.0, 1.0, 0.0]},
                                                   {"id": 1, "pose": [1.0, 0.0, 1.0, 0.0]}],
                                     "goal": [-0.9, 0.0]}},
                "parameters": {"waypoints": [[1, 2], [3, 4], [5, 6]], "path": [{"id": 0, "pose": [0.5, 0.0, 1.0, 0.0]},
                                                                               {"id": 1, "pose": [1.0, 0.0, 1.0, 0.0]}]}}
    got = {m["name"]: m for m in markers(resolved)}
    assert got["room"]["box"] == [-1.0, 3.0, -1.0, 2.0]
    assert got["keyframes"]["points"] == [[0.5, 0.0], [1.0, 0.0]]
    assert got["waypoints"]["points"] == [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]
    assert "goal" not in got and "path" not in got  # the same points as keyframes are drawn once


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
    assert "not a run folder" in capsys.readouterr().err
    with pytest.raises(ViewError):
        open_run(tmp_path)


def test_run_view_needs_the_control_endpoint(capsys):
    assert main(["run", str(TOY), "--view", "--no-control"]) == 1
    assert "--view needs the control endpoint" in capsys.readouterr().err


def test_the_top_view_takes_the_robot_pose_and_known_bodies_with_their_frames():
    mission = load_mission(TOY)
    viki = machine_json(mission, {}, ["gt.x", "gt.y", "gt.yaw", "gt.obj_x", "gt.obj_y", "gt.err_x", "gt.err_y"])
    assert viki["xy"] == ["gt.x", "gt.y", "gt.yaw"]
    assert viki["bodies"] == [{"name": "obj", "x": "gt.obj_x", "y": "gt.obj_y", "frame": "robot"}]  # err is no body
    screw = machine_json(mission, {}, ["gt.base_x", "gt.base_y", "gt.base_yaw", "gt.part_x", "gt.part_y"])
    assert screw["xy"] == ["gt.base_x", "gt.base_y", "gt.base_yaw"] and screw["bodies"][0]["frame"] == "world"
    no_yaw = machine_json(mission, {}, ["gt.x", "gt.y", "gt.obj_x", "gt.obj_y"])
    assert no_yaw["xy"] == ["gt.x", "gt.y", ""] and no_yaw["bodies"] == []  # a robot-frame body needs the yaw


def test_a_live_view_learns_the_columns_once_the_header_is_written(tmp_path):
    from taskflow.view import RunView

    view = RunView(load_mission(TOY), tmp_path, live=True)
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
