"""Ctrl-C and SIGTERM on a real ``taskflow run`` / ``taskflow batch`` process: the run ends with the safe
stop recorded, the batch stops at once, writes what finished and leaves no worker behind; both exit with
the shell's code of the signal (130 after Ctrl-C, 143 after SIGTERM)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from taskflow.readers.run_files import read_trace

ROOT = Path(__file__).resolve().parents[2]
LONG = str(ROOT / "missions" / "car_waypoints_unreachable.yaml")  # 60 s simulated: still running when signalled


def _taskflow(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", "from taskflow.cli import main; raise SystemExit(main())", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _wait_for(path: Path, proc: subprocess.Popen[str], what: str, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not path.exists() or path.stat().st_size == 0:
        assert proc.poll() is None, f"finished before {what}: {proc.communicate()}"
        assert time.monotonic() - t0 < timeout, f"no {what} after {timeout} s"
        time.sleep(0.05)


def _group_gone(pgid: int, timeout: float = 10.0) -> bool:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


@pytest.mark.parametrize("sig, reason, code", [(signal.SIGINT, "interrupted (Ctrl-C)", 130),
                                               (signal.SIGTERM, "terminated (SIGTERM)", 143)])
def test_an_interrupted_run_is_recorded_with_its_safe_stop(tmp_path: Path, sig: int, reason: str, code: int) -> None:
    out = tmp_path / "run"
    proc = _taskflow("run", LONG, "--out", str(out), "--quiet")
    _wait_for(out / "trace.csv", proc, "trace", 60)
    while len((out / "trace.csv").read_text().splitlines()) < 2:  # the first block of ticks is on disk
        time.sleep(0.05)
    os.killpg(proc.pid, sig)  # Ctrl-C reaches the terminal's whole process group
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == code, stdout + stderr
    assert "Traceback" not in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "aborted" and summary["reason"] == reason
    trace = read_trace(out)
    stop = trace["events"] == "safe_stop"
    assert stop.sum() == 20 and stop[-20:].all()  # the 1 s safe stop follows, as after any outcome
    assert summary["stopped_at_s"] == pytest.approx(summary["sim_time_s"] + 1.0)
    assert abs(trace["gt.v"][-1]) < 1e-3  # the car is at rest


@pytest.mark.parametrize("how, workers", [("ctrl-c", "2"), ("sigterm", "2"), ("ctrl-c", "1"), ("sigterm", "1")])
def test_an_interrupted_batch_stops_at_once_and_records_what_finished(tmp_path: Path, how: str, workers: str) -> None:
    out = tmp_path / "batch"
    # 6 trials of 60 s simulated each on 2 workers (or in the batch's own process); interrupted while the
    # first ones run
    proc = _taskflow("batch", LONG, "--trials", "6", "--workers", workers, "--out", str(out), "--keep-runs")
    _wait_for(out / "trial-00000" / "trace.csv", proc, "a running trial", 120)
    if how == "ctrl-c":
        os.killpg(proc.pid, signal.SIGINT)  # parent and workers alike, as a terminal does
    else:
        proc.send_signal(signal.SIGTERM)  # the parent only, as a process manager does
    t0 = time.monotonic()
    stdout, stderr = proc.communicate(timeout=60)
    assert time.monotonic() - t0 < 30.0, "the batch did not stop promptly"
    assert proc.returncode == (130 if how == "ctrl-c" else 143), stdout + stderr  # as `taskflow run` exits
    assert "Traceback" not in stderr
    assert f"{'interrupted' if how == 'ctrl-c' else 'terminated'}: finished trials recorded in {out / 'batch.json'}" in stderr
    assert _group_gone(proc.pid), "worker processes were left running"
    batch = json.loads((out / "batch.json").read_text())
    assert batch["interrupted"] is True and batch["trials_requested"] == 6
    assert batch["aggregate"]["trials"] == len(batch["trials"]) < 6
