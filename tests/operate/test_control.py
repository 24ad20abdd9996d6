"""Operator control of a running mission, through the real endpoint (taskflow.execution.control, taskflow.operate.control_http).

Each live test starts a run in a thread with the control server on 127.0.0.1 port 0, finds it through
RUN_DIR/control.json and talks HTTP to it with the client `taskflow ctl` uses.  A scripted pause
(operator script, sim time) holds the run still at a known tick so that the live actions land where the
test expects them; the machine tests use the scripted backend or the toy world, the last two ViKi-HyCo
on PyBullet.
"""


from __future__ import annotations

import json
import time
from typing import Any

import pytest
from control_live import (
    PAUSE_AT_1,
    TOY,
    WAITING,
    _post,
    operator_records,
    records,
    scripted_run,
    toy_run,
)

from taskflow.cli import main
from taskflow.errors import MissionError
from taskflow.execution.control import ControlError, load_operator_script
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.operate.control_http import ControlServer
from taskflow.readers.run_files import read_trace
from taskflow.testing import drive

# -- pause / resume ------------------------------------------------------------------------------------


def test_pause_freezes_the_sim_clock_without_spinning_and_resume_advances_it(live, tmp_path):
    run = toy_run(live, tmp_path, operator=[*PAUSE_AT_1, {"t": 2.0, "action": "pause", "who": "script"}])
    first = run.wait(lambda s: s["paused"])
    assert first["t"] == 1.0 and first["running"] and not first["held"]
    cpu0, wall0 = time.process_time(), time.perf_counter()
    time.sleep(0.6)
    second = run.client.state()
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    assert (second["t"], second["tick"]) == (first["t"], first["tick"])  # the sim clock stood still
    assert cpu < 0.3 * wall, f"the paused loop burnt {cpu:.2f} s CPU in {wall:.2f} s"
    run.client.send("resume", who="alice")
    later = run.wait(lambda s: s["t"] > 1.0)
    assert later["t"] == 2.0 and later["paused"]  # it ran on to the script's second pause
    run.client.send("preempt", who="alice")
    result = run.finish()
    assert result.outcome == "aborted" and "alice" in result.summary["reason"]
    ops = operator_records(tmp_path / "run")
    assert [(r["action"], r["who"], r["t"]) for r in ops] == [("pause", "script", 1.0), ("resume", "alice", 1.0),
                                                             ("pause", "script", 2.0), ("preempt", "alice", 2.0)]
    assert ops[-1]["action"] == "preempt" and ops[-1]["who"] == "alice" and ops[-1]["args"] == {}
    assert all({"t", "tick", "who", "action", "state"} <= r.keys() for r in ops)
    assert not (tmp_path / "run" / "control.json").exists()  # the endpoint is gone with the run


# -- hold ------------------------------------------------------------------------------------------------


def test_hold_stops_the_robot_while_the_world_goes_on(live, tmp_path):
    # the script pauses the held run again at 3 s: a held run runs flat out, and a live "pause" sent once the
    # snapshot showed 3 s could land after the mission's own 60 s limit on a fast machine (CI did)
    run = toy_run(live, tmp_path, operator=[*PAUSE_AT_1, {"t": 3.0, "action": "pause", "who": "script"}])
    paused = run.wait(lambda s: s["paused"])
    assert paused["state"] == "operate.visit.approach"  # the toy point is driving to its first goal
    run.client.send("hold", who="bob")
    held = run.wait(lambda s: s["paused"] and s["t"] >= 3.0)
    assert held["state"] == paused["state"] and held["held"] is False  # no task step, no transition while held
    run.client.send("preempt", who="bob")
    run.finish()
    tr = read_trace(tmp_path / "run")
    hold = ["hold" in str(e).split("|") for e in tr["events"]]
    t, x = tr["t"][hold], tr["gt.x"][hold]
    assert len(t) >= 40 and (t[1:] > t[:-1]).all()  # sim time advanced, tick by tick
    assert 0.0 < x[0] < 1.0 and (x == x[0]).all()  # stopped short of its goal, at rest (ground truth)
    moving = tr["gt.x"][tr["t"] < 1.0]
    assert moving[-1] > moving[-2]  # it was moving before the hold
    assert [r["action"] for r in operator_records(tmp_path / "run")] == ["pause", "hold", "pause", "preempt"]


# -- preempt -----------------------------------------------------------------------------------------------


def test_preempt_to_a_state_cancels_the_action_and_records_an_operator_transition(live, tmp_path):
    worlds: list[Any] = []
    run = scripted_run(live, tmp_path, worlds)
    assert run.wait(lambda s: s["paused"])["state"] == "operate.visit.settle"
    assert run.client.send("preempt", who="carol", to="searching") == {"queued": "preempt", "who": "carol"}
    result = run.finish()
    assert result.outcome == "failed"  # searching gives up after 3 s: its own transition still runs
    assert result.summary["states_visited"][-2:] == ["searching", "error"]
    assert worlds[0].cancelled == [(2.0, "tool")]
    recs = records(tmp_path / "run")
    op = next(r for r in recs if r["cause"] == "operator" and "from" in r)
    assert op == {"t": 2.0, "from": "operate.visit.settle", "to": "searching", "cause": "operator", "state": "",
                  "label": "preempt --to searching", "who": "carol"}
    action = recs[recs.index(op) - 1]
    assert action["action"] == "preempt" and action["args"] == {"to": "searching"} and action["tick"] == 40


def test_preempt_without_a_target_aborts_naming_who(tmp_path):
    mission = load_mission(TOY)
    result = drive(mission, WAITING, max_time=60, out_dir=tmp_path / "run",
                   operator=[{"t": 1.5, "action": "preempt", "who": "dora"}])
    assert result.outcome == "aborted" and result.summary["reason"] == "pre-empted by dora (operator)"
    assert result.summary["sim_time_s"] == 1.5


# -- inject ------------------------------------------------------------------------------------------------


def test_an_injected_event_fires_its_transition_at_that_tick(live, tmp_path):
    worlds: list[Any] = []
    run = scripted_run(live, tmp_path, worlds)
    run.wait(lambda s: s["paused"])
    run.client.send("inject", who="erin", event="tool_done")
    run.client.send("pause", who="erin")  # the same tick: the injection is applied, the run stays frozen
    run.client.send("resume", who="erin")
    assert run.finish().outcome == "succeeded"  # the other two items' tools finish on their own
    recs = records(tmp_path / "run")
    fired = next(r for r in recs if r.get("event") == "tool_done")
    assert fired["t"] == 2.0 and fired["from"] == "operate.visit.settle" and fired["cause"] == "event"
    injected = next(r for r in recs if r.get("action") == "inject")
    assert injected == {"t": 2.0, "tick": 40, "cause": "operator", "action": "inject", "who": "erin",
                        "state": "operate.visit.settle", "args": {"event": "tool_done"}}


# -- bad requests ------------------------------------------------------------------------------------------



def test_unknown_state_or_undeclared_event_is_a_400_and_ctl_exits_non_zero(live, tmp_path, capsys):
    run = toy_run(live, tmp_path)
    run.wait(lambda s: s["paused"])
    url, token = run.client.url, run.client.token
    code, body = _post(url + "/preempt", {"to": "operate.vist", "who": "x"}, token=token)
    assert code == 400 and "no state 'operate.vist'" in body["error"] and "did you mean 'operate.visit'" in body["error"]
    code, body = _post(url + "/inject", {"event": "operator_confirmed"}, token=token)
    assert code == 400 and "'operator_confirmed' is not declared" in body["error"]
    assert "valid: arrived, target_found, target_lost, tool_done, tool_failed" in body["error"]
    code, body = _post(url + "/pause", {"to": "search"}, token=token)
    assert code == 400 and "unknown argument 'to'" in body["error"]
    # what a page of another origin could send without a CORS preflight, or through DNS rebinding
    code, body = _post(url + "/preempt", {}, {"Content-Type": "text/plain"}, token=token)
    assert code == 415 and "application/json" in body["error"]
    code, body = _post(url + "/preempt", {}, {"Content-Type": "application/json", "Host": "evil.example:80"}, token=token)
    assert code == 400 and body == {"text": "Invalid host header"}

    assert main(["ctl", str(tmp_path / "run"), "inject", "bogus"]) == 1
    assert "inject: event 'bogus' is not declared" in capsys.readouterr().err
    assert main(["ctl", "--url", url, "--token", str(token), "preempt", "--to", "nowhere"]) == 1
    assert "no state 'nowhere'" in capsys.readouterr().err
    assert main(["ctl", str(tmp_path / "run"), "state"]) == 0
    assert json.loads(capsys.readouterr().out)["paused"] is True
    assert main(["ctl", str(tmp_path / "run"), "preempt", "--who", "frank"]) == 0
    assert "preempt queued by frank" in capsys.readouterr().out
    assert run.finish().summary["reason"] == "pre-empted by frank (operator)"
    assert main(["ctl", str(tmp_path / "run"), "pause"]) == 1  # the run has ended: no control.json
    assert "the run has ended" in capsys.readouterr().err
    assert [r["who"] for r in operator_records(tmp_path / "run")] == ["script", "frank"]  # refused ones: no record


def test_bad_operator_scripts_are_refused_before_the_run(tmp_path, capsys):
    mission = load_mission(TOY)
    bad = tmp_path / "ops.yaml"
    bad.write_text("- {t: 1, action: pause}\n- {t: 2, action: paws}\n- {t: -1, action: resume, whom: me}\n")
    with pytest.raises(MissionError) as exc:
        load_operator_script(bad, mission)
    text = str(exc.value)
    assert f"{bad}:2:" in text and "'paws'" in text and f"{bad}:3:" in text and "unknown key 'whom'" in text
    bad.write_text("- {t: 1, action: inject, args: {event: nope}}\n")
    with pytest.raises(MissionError, match=r"ops.yaml:1:.*'nope' is not declared"):
        load_operator_script(bad, mission)
    with pytest.raises(ControlError, match="never resumed"):
        run_mission(mission, record=False, operator=PAUSE_AT_1)
    with pytest.raises(ControlError, match="no state 'nope'"):
        run_mission(mission, record=False, operator=[{"action": "preempt", "args": {"to": "nope"}}])
    bad.write_text("- {t: 1, action: pause}\n")
    assert main(["run", str(TOY), "--no-control", "--operator-script", str(bad), "--out", str(tmp_path / "r")]) == 1
    assert "never resumed" in capsys.readouterr().err


def test_the_endpoint_binds_localhost_and_refuses_a_port_in_use():
    first = ControlServer()
    try:
        assert first.url.startswith("http://127.0.0.1:")
        with pytest.raises(ControlError, match="cannot listen"):
            ControlServer("127.0.0.1:" + first.url.rsplit(":", 1)[1])
    finally:
        first.stop()
    with pytest.raises(ControlError, match="not HOST:PORT"):
        ControlServer("localhost")
