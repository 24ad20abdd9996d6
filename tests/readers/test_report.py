"""The terminal summary: every metric with its unit, counted; final values from the world, the task's
last values labelled as such; for a failure, the chain of transitions and what caused each."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.cli import main
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.readers.recorded import RecordedRun, load_run
from taskflow.readers.report import format_report
from taskflow.units import suffix_unit

FULL = Path(__file__).parents[1] / "machine" / "missions" / "toy_full.yaml"


def _run(tmp_path: Path, overrides: list[str]) -> RecordedRun:
    result = run_mission(load_mission(FULL, overrides=overrides), out_dir=tmp_path / "run")
    assert result.summary["outcome"] in ("succeeded", "failed")
    return load_run(tmp_path / "run")


@pytest.fixture
def failed(tmp_path: Path) -> RecordedRun:
    return _run(tmp_path, ["world.params.tool_ok=false"])


def _section(text: str, head: str) -> list[str]:
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(head))
    out = []
    for line in lines[i + 1:]:
        if not line.startswith("  "):
            break
        out.append(line)
    return out


def test_a_failure_shows_the_chain_of_transitions_and_their_causes(failed: RecordedRun) -> None:
    text = format_report(failed)
    assert text.startswith("outcome: failed")
    chain = _section(text, "how it got there")
    assert f"how it got there ({len(failed.transitions)} transitions):" in text
    assert len(chain) == len(failed.transitions)
    guard = next(r for r in failed.transitions if r.cause == "guard")
    value = guard.metrics["pos_error"]  # type: ignore[index]
    assert any("guard 'pos_error < $tol for 0.2 s'" in line and f"pos_error = {value:.6g} m" in line for line in chain)
    assert any("event 'tool_failed'" in line and "settle → operate.visit.broken" in line for line in chain)
    assert chain[-1].rstrip().endswith("operate.visit.broken → error: sub-machine operate.visit finished 'failed'")


def test_every_metric_is_listed_with_its_unit_and_counted(failed: RecordedRun) -> None:
    text = format_report(failed)
    task = _section(text, "task and sensor metrics")
    names = failed.metric_columns()
    assert f"task and sensor metrics ({len(names)} metrics;" in text and len(task) == len(names) == 4
    units = {"pos_error": " m ", "feature_error": " px ", "yaw_error": " rad ", "visible": " - "}
    for name, unit in units.items():
        line = next(line for line in task if line.split()[0] == name)
        assert unit in line and "last in operate." in line, line
    world = _section(text, "ground truth and world summary")
    assert "(1 metrics)" in text and world[0].split()[0] == "final_x"


def test_nothing_is_truncated(failed: RecordedRun) -> None:
    failed.summary["metrics"].update({f"extra_{i:02d}_m": float(i) for i in range(40)})
    text = format_report(failed)
    world = _section(text, "ground truth and world summary")
    assert "(41 metrics)" in text and len(world) == 41
    assert all(line.split()[-1] == "m" for line in world[1:])


def test_task_values_are_last_values_in_their_state_never_final(tmp_path: Path) -> None:
    run = _run(tmp_path, [])
    text = format_report(run)
    assert "how it got there" not in text  # a success needs no explanation
    for line in _section(text, "task and sensor metrics"):
        state, t = line.split("last in ")[1].split(" at t = ")
        i = int((abs(run.trace["t"] - float(t.split()[0]))).argmin())
        assert run.trace["state"][i] == state


def test_suffix_units() -> None:
    assert [suffix_unit(n) for n in ("final_error_m", "gt_speed_mps", "err_mm", "yaw_deg", "frames", "rate_radps")] == \
        ["m", "m/s", "mm", "deg", None, "rad/s"]


def test_taskflow_run_prints_the_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", str(FULL), "--out", str(tmp_path / "r"), "--quiet", "--set", "world.params.tool_ok=false"])
    out = capsys.readouterr().out
    assert code == 1
    assert "how it got there" in out and "task and sensor metrics (4 metrics;" in out and f"run record: {tmp_path / 'r'}" in out
