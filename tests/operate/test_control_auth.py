"""Who may drive the robot (the run's token), and the endpoint's lifecycle (a stale control.json, --gui
without a display) — taskflow.operate.control_http through the real HTTP server, `taskflow ctl` and `taskflow run`.

Every request goes to 127.0.0.1: a server bound to 0.0.0.0 is reached through the loopback address.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

from taskflow.cli import main
from taskflow.execution.runtime import run_mission
from taskflow.execution.summary import RunResult
from taskflow.mission.loader import load_mission
from taskflow.operate.control_http import ControlServer
from taskflow.operate.replay import serve_replay

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
CAR = HERE.parent / "missions" / "car_waypoints.yaml"
PAUSE_AT_1 = [{"t": 1.0, "action": "pause", "who": "script"}]


def request(url: str, method: str = "GET", token: str | None = None, body: dict[str, Any] | None = None,
            ) -> tuple[int, Any]:
    headers = {"Content-Type": "application/json"}
    if token is not None:
        headers["Authorization"] = f"Bearer {token}"
    data = json.dumps(body or {}).encode() if method == "POST" else None
    req = urllib.request.Request(url, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            raw = resp.read()
            return resp.status, json.loads(raw) if resp.headers.get_content_type() == "application/json" else raw
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def via_loopback(url: str) -> str:
    """The address of a server bound to 0.0.0.0, reached through 127.0.0.1 (no traffic off the machine)."""
    return "http://127.0.0.1:" + url.rsplit(":", 1)[1]


def records(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "transitions.jsonl").read_text().splitlines()]


def start_toy(out: Path, control: str | ControlServer = "127.0.0.1:0",
              operator: list[dict[str, Any]] = PAUSE_AT_1) -> tuple[threading.Thread, dict[str, Any]]:
    """The toy mission in a thread, paused by its script at t = 1 s (or run with ``operator``); returns the thread
    and a box for its result."""
    mission = load_mission(TOY)
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            endpoint = ControlServer(control) if isinstance(control, str) else control
            box["result"] = run_mission(mission, out_dir=out, control=endpoint, max_time=3600, operator=operator)
        except BaseException as exc:
            box["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    _until(lambda: (out / "control.json").is_file() or "error" in box, "control.json")
    return thread, box


def _until(pred: Callable[[], Any], what: str, timeout: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout
    while not (value := pred()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)
    return value


def _end(thread: threading.Thread, url: str, token: str, box: dict[str, Any]) -> RunResult:
    request(url + "/preempt", "POST", token, {"who": "teardown"})
    thread.join(30)
    assert not thread.is_alive() and "error" not in box, box.get("error")
    return box["result"]


# -- the token -------------------------------------------------------------------------------------------


def test_an_action_without_the_runs_token_is_refused_changes_nothing_and_is_logged(tmp_path, capsys):
    out = tmp_path / "run"
    # a held run runs flat out: the script pauses it again at 3 s, before the toy mission's own 60 s limit ends it
    thread, box = start_toy(out, operator=[*PAUSE_AT_1, {"t": 3.0, "action": "pause", "who": "script"}])
    info = json.loads((out / "control.json").read_text())
    url, token = info["url"], info["token"]
    try:
        assert stat.S_IMODE(os.stat(out / "control.json").st_mode) == 0o600  # its owner's only
        assert isinstance(token, str) and len(token) >= 32 and info["pid"] == os.getpid()
        _until(lambda: request(url + "/state")[1]["paused"], "the script's pause")  # a GET on loopback: no token
        errs: list[str] = []
        code, body = request(url + "/preempt", "POST", None, {"who": "mallory"})
        assert code == 401 and "needs its token" in body["error"]
        code, body = request(url + "/preempt", "POST", token[::-1], {"who": "mallory"})
        assert code == 403 and "wrong token" in body["error"]
        code, body = request(url + "/resume?token=" + token[:-1] + "x", "POST", None, {"who": "mallory"})
        assert code == 403
        time.sleep(0.3)  # a refused action that had been queued would be applied within a wait of the paused loop
        state = request(url + "/state")[1]
        assert (state["paused"], state["running"], state["t"]) == (True, True, 1.0)
        errs.append(capsys.readouterr().err)  # the refusals' lines so far
        assert main(["ctl", "--url", url, "--token", "not-it", "pause"]) == 1  # taskflow ctl with a wrong token
        assert "taskflow ctl: wrong token for this run" in capsys.readouterr().err
        assert main(["ctl", str(out), "pause", "--token", token]) == 1  # RUN_DIR brings its own token
        assert "--token goes with --url" in capsys.readouterr().err
        assert main(["ctl", str(out), "hold", "--who", "trent"]) == 0  # RUN_DIR: the token from control.json
        assert "hold queued by trent" in capsys.readouterr().out
        _until(lambda: (s := request(url + "/state")[1])["paused"] and s["t"] >= 3.0, "the hold, then the script's pause")
    finally:
        result = _end(thread, url, token, box)
    assert result.outcome == "aborted" and result.summary["reason"] == "pre-empted by teardown (operator)"
    ops = [(r["action"], r["who"]) for r in records(out) if r["cause"] == "operator" and "action" in r]
    assert ops == [("pause", "script"), ("hold", "trent"), ("pause", "script"),
                   ("preempt", "teardown")]  # mallory: nothing recorded
    refused = [json.loads(line) for line in (out / "refused.jsonl").read_text().splitlines()]
    assert [(r["method"], r["path"], r["status"], r["why"]) for r in refused] == [
        ("POST", "/preempt", 401, "no token"), ("POST", "/preempt", 403, "wrong token"),
        ("POST", "/resume", 403, "wrong token"), ("POST", "/pause", 403, "wrong token")]
    assert all(r["client"].startswith("127.0.0.1:") for r in refused)
    err = "".join(errs) + capsys.readouterr().err
    assert err.count("taskflow: refused POST /preempt from 127.0.0.1:") == 2 and "no token (HTTP 401)" in err
    assert token not in err and not (out / "control.json").exists()


def test_off_loopback_every_request_needs_the_token_the_pages_files_excepted(tmp_path):
    out = tmp_path / "run"
    server = ControlServer("0.0.0.0:0", view=True)
    thread, box = start_toy(out, server)
    url, token = via_loopback(server.url), json.loads((out / "control.json").read_text())["token"]
    try:
        assert token == server.token
        for path in ("/state", "/mission", "/", "/view/machine", "/view/trace"):
            assert request(url + path)[0] == 401, path
            assert request(url + path, token="x" + token[1:])[0] == 403, path
        code, state = _until(lambda: (r := request(url + "/state", token=token))[1]["paused"] and r, "the pause")
        assert code == 200 and state["t"] == 1.0
        code, page = request(f"{url}/?token={token}")  # the page, as the run prints its address
        assert code == 200 and b"taskflow view" in page
        assert request(url + "/view/trace", token=token)[0] == 200
        assert request(url + "/web/view.js")[0] == 200  # the package's static file: the same for every run
    finally:
        _end(thread, url, token, box)
    refused = [json.loads(line) for line in (out / "refused.jsonl").read_text().splitlines()]
    assert [r["status"] for r in refused] == [401, 403] * 5


def test_a_replay_off_loopback_needs_its_token_and_on_loopback_none(tmp_path, capsys):
    out = tmp_path / "run"
    thread, box = start_toy(out)
    info = json.loads((out / "control.json").read_text())
    _end(thread, info["url"], info["token"], box)
    remote = serve_replay(out, "0.0.0.0:0")
    try:
        url = via_loopback(remote.url)
        assert remote.token is not None and remote.token != info["token"]  # its own, drawn at start
        assert request(url + "/view/summary")[0] == 401
        assert request(url + "/view/summary", token="nope")[0] == 403
        code, summary = request(url + "/view/summary", token=remote.token)
        assert code == 200 and summary["outcome"] == "aborted"
        assert request(f"{url}/view/trace?token={remote.token}")[0] == 200
        assert request(url + "/pause", "POST", remote.token)[0] == 409  # a replay drives nothing
    finally:
        remote.stop()
    assert "taskflow: refused GET /view/summary from 127.0.0.1:" in capsys.readouterr().err
    local = serve_replay(out, "127.0.0.1:0")
    try:
        assert local.token is None and request(local.url + "/view/summary")[0] == 200
    finally:
        local.stop()


def test_taskflow_view_prints_the_token_with_the_pages_address_off_loopback(tmp_path, monkeypatch, capsys):
    import taskflow.operate.replay as replay

    out = tmp_path / "run"
    thread, box = start_toy(out)
    info = json.loads((out / "control.json").read_text())
    _end(thread, info["url"], info["token"], box)
    servers: list[Any] = []
    real = replay.serve_replay
    monkeypatch.setattr(replay, "serve_replay", lambda *a, **k: servers.append(real(*a, **k)) or servers[-1])
    monkeypatch.setattr(replay, "wait_forever", lambda server: server.stop())  # instead of waiting for Ctrl-C
    assert main(["view", str(out), "--host", "0.0.0.0", "--port", "0"]) == 0
    err = capsys.readouterr().err
    assert f"view: {servers[0].url}/?token={servers[0].token}  (replay of {out}" in err


def test_control_json_is_created_owner_only_whatever_the_umask(tmp_path):
    from taskflow.operate.control_http import write_private

    old = os.umask(0)
    try:
        write_private(tmp_path / "control.json", "{}\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "control.json").st_mode) == 0o600
    assert not (tmp_path / "control.json.tmp").exists()


# -- a stale control.json ----------------------------------------------------------------------------------


def test_ctl_on_a_run_killed_with_sigkill_says_it_is_not_running(tmp_path, capsys):
    script = tmp_path / "ops.yaml"
    script.write_text("- {t: 0.5, action: pause, who: script}\n")
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "taskflow.cli", "run", str(CAR), "--out", str(out), "--quiet",
                             "--frames", "0", "--operator-script", str(script)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _until(lambda: (out / "control.json").is_file() or proc.poll() is not None, "the run's control.json")
        assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
        assert json.loads((out / "control.json").read_text())["pid"] == proc.pid
        while True:  # wait for the pause, through ctl
            assert main(["ctl", str(out), "state"]) == 0
            if json.loads(capsys.readouterr().out)["paused"]:
                break
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
        if proc.stderr:
            proc.stderr.close()
    assert (out / "control.json").is_file()  # kill -9: nothing could remove it
    assert main(["ctl", str(out), "pause"]) == 1
    assert capsys.readouterr().err == f"taskflow ctl: run {out} is not running (process {proc.pid} ended)\n"


def _stale(run_dir: Path, url: str, pid: int, start: str | None) -> None:
    run_dir.mkdir()
    (run_dir / "control.json").write_text(json.dumps({"url": url, "mission": "m", "token": "t", "pid": pid,
                                                      "process_start": start}))


def test_ctl_tells_a_reused_pid_and_a_refused_connection_from_a_running_run(tmp_path, capsys):
    from taskflow.operate.control_http import process_start

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    closed = f"http://127.0.0.1:{sock.getsockname()[1]}"
    sock.close()  # nobody listens there now
    me, started = os.getpid(), process_start(os.getpid())
    assert started is not None
    _stale(tmp_path / "reused", closed, me, str(int(started) + 1))  # this pid, but a process started later
    assert main(["ctl", str(tmp_path / "reused"), "state"]) == 1
    assert capsys.readouterr().err == f"taskflow ctl: run {tmp_path / 'reused'} is not running (process {me} ended)\n"
    _stale(tmp_path / "refused", closed, me, started)  # the process lives (a crash in its endpoint): port closed
    assert main(["ctl", str(tmp_path / "refused"), "hold"]) == 1
    err = capsys.readouterr().err
    assert err == (f"taskflow ctl: run {tmp_path / 'refused'} is not running (its endpoint {closed} refuses the "
                   "connection)\n")


def test_gui_without_a_display_is_refused_before_anything_starts(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    out = tmp_path / "run"
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "taskflow.cli", "run", str(CAR), "--gui", "--out", str(out)],
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith("taskflow run: --gui: no display (DISPLAY is not set) — ")
    assert len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not out.exists()  # no run directory, no control.json
    assert time.monotonic() - t0 < 30


def test_a_runs_token_is_hex_and_taskflow_ctl_takes_it_after_token() -> None:
    """A token that began with ``-`` (``token_urlsafe`` draws one in 64) was read by ``taskflow ctl --token``
    as an option and the command failed: tokens are hex digits, and every one parses as ``--token``'s value."""
    from taskflow.cli import build_parser
    from taskflow.operate.control_http import new_token

    parser = build_parser()
    for _ in range(300):
        token = new_token()
        assert len(token) == 64 and set(token) <= set("0123456789abcdef")
        args = parser.parse_args(["ctl", "--url", "http://127.0.0.1:1", "--token", token, "state"])
        assert args.token == token
