"""The live-run helpers of tests/operate/test_control*.py: a run in a thread with its control endpoint
(:class:`LiveRun`,
started through the fixture ``live`` of tests/conftest.py), the toy and scripted runs the tests start, and a raw
POST to the endpoint."""

from __future__ import annotations

import json
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

from taskflow.execution.runtime import run_mission
from taskflow.execution.summary import RunResult
from taskflow.mission.loader import load_mission
from taskflow.operate.control_http import ControlClient, ControlServer
from taskflow.testing import Script, drive

HERE = Path(__file__).resolve().parent
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
VIKI = HERE.parent / "missions" / "viki_hyco.yaml"
PAUSE_AT_1 = [{"t": 1.0, "action": "pause", "who": "script"}]


def records(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "transitions.jsonl").read_text().splitlines()]


def operator_records(run_dir: Path) -> list[dict[str, Any]]:
    return [r for r in records(run_dir) if r["cause"] == "operator"]


class LiveRun:
    """A run in a thread with its control endpoint; ``client`` is found through RUN_DIR/control.json."""

    def __init__(self, start: Callable[[], RunResult], run_dir: Path) -> None:
        self.result: RunResult | None = None
        self.error: BaseException | None = None

        def target() -> None:
            try:
                self.result = start()
            except BaseException as exc:
                self.error = exc

        self.thread = threading.Thread(target=target, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 30
        while not (run_dir / "control.json").is_file():
            assert self.thread.is_alive() and time.monotonic() < deadline, f"no control.json ({self.error})"
            time.sleep(0.01)
        self.client = ControlClient.for_run(run_dir)

    def wait(self, pred: Callable[[dict[str, Any]], bool], timeout: float = 20.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            s = self.client.state()
            if pred(s):
                return s
            assert time.monotonic() < deadline, f"state never matched: {s}"
            time.sleep(0.01)

    def finish(self, timeout: float = 30.0) -> RunResult:
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the run did not end"
        if self.error is not None:
            raise self.error
        assert self.result is not None
        return self.result




def toy_run(live: Callable[..., LiveRun], tmp_path: Path, operator: list[dict[str, Any]] | None = None,
            **kw: Any) -> LiveRun:
    mission = load_mission(TOY)
    out = tmp_path / "run"
    return live(lambda: run_mission(mission, out_dir=out, control=ControlServer("127.0.0.1:0"), max_time=3600,
                                    operator=PAUSE_AT_1 if operator is None else operator, **kw), out)


# -- scripted backend: a settle state waiting 10 s for its tool ------------------------------------------

WAITING = Script(metrics=lambda s: {"pos_error": 0.0, "visible": 1.0}, actions={"tool": (10.0, "tool_done")})


def scripted_run(live: Callable[..., LiveRun], tmp_path: Path, worlds: list[Any]) -> LiveRun:
    mission = load_mission(TOY)
    out = tmp_path / "run"
    # approach 0.5 s → settle at 0.7 s (its tool runs 10 s): the script pauses the run at 2 s, in settle
    return live(lambda: drive(mission, WAITING, max_time=600, out_dir=out, on_world=worlds.append,
                              control=ControlServer("127.0.0.1:0"), operator=[{"t": 2.0, "action": "pause", "who": "script"}]), out)



def _post(url: str, body: dict[str, Any], headers: dict[str, str] | None = None,
          token: str | None = None) -> tuple[int, dict[str, Any]]:
    headers = {"Content-Type": "application/json"} if headers is None else headers
    if token is not None:
        headers = {**headers, "Authorization": f"Bearer {token}"}
    req = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST", headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as exc:
        raw = exc.read()
        return exc.code, json.loads(raw) if exc.headers.get_content_type() == "application/json" else {"text": raw.decode()}
