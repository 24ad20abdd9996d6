"""`taskflow verify`, `taskflow graph --counterexample` and `taskflow validate --verify` as a user runs them:
exit codes, the verdict table, JSON, a counterexample replayed into a run record the readers open, the
highlighted diagram accepted by Graphviz and Mermaid's own parsers, and clear errors for bad values."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from diagram_parsers import dot_errors, mermaid_errors

from taskflow.readers.recorded import load_run

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]
POSE = ROOT / "missions" / "viki_hyco.yaml"
PLANTED = """mission: planted
robot: racecar
world: viki_ground
rate_hz: 20
profiles:
  viki_gains:
    front: {lam: [0.85, 0.3, 1.0, 1.0, 1.0], k1: [2.0, 1.0]}
machine:
  initial: approach
  states:
    approach:
      task: {name: viki_hyco, params: {camera: front, desired: [1.0, 0.0], mode: hybrid}}
      bind: {gains: front}
      transitions:
        - {to: searching, on: target_lost}
        - {to: done, when: "feature_error < 2 px", for: 0.3 s}
        - {to: failed, after: 20 s}
    searching:
      transitions:
        - {to: approach, on: target_found}
    done: {final: succeeded}
    failed: {final: failed}
"""


def taskflow(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "taskflow.cli", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=120)


@pytest.fixture
def planted(tmp_path: Path) -> Path:
    f = tmp_path / "planted.yaml"
    f.write_text(PLANTED)
    return f


def test_a_sound_mission_verifies_with_exit_0_and_json() -> None:
    r = taskflow("verify", str(POSE), "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["ok"] is True and {c["name"] for c in doc["checks"]} == {
        "no_trap", "timed_exit", "duration", "outcomes", "region_conflicts",
        "property:rear_after_turn", "property:placed_after_backward",  # the mission's declared properties
        "property:never_touches"}
    verdicts = {c["name"]: c["verdict"] for c in doc["checks"]}
    assert verdicts["property:never_touches"] == "monitored"  # the world's ground truth: only a run decides it
    assert doc["model"]["configurations"] > 1


def test_a_planted_defect_fails_with_exit_1_and_is_replayed_into_a_readable_record(planted: Path,
                                                                                  tmp_path: Path) -> None:
    r = taskflow("verify", str(planted))
    assert r.returncode == 1
    assert "timed_exit        fails" in r.stdout and "waits in searching forever" in r.stdout
    out = tmp_path / "cex"
    r = taskflow("verify", str(planted), "--replay", str(out), "--check", "timed_exit")
    assert "the engine followed the counterexample" in r.stdout, r.stdout + r.stderr
    run = load_run(out)
    assert [t.target for t in run.transitions] == ["approach", "searching"]
    assert run.summary["outcome"] == "timeout"
    rep = taskflow("plot", str(out))  # every reader opens the replayed record
    assert rep.returncode == 0, rep.stderr


def test_the_counterexample_is_drawn_and_both_formats_parse(planted: Path) -> None:
    dot = taskflow("graph", str(planted), "--format", "dot", "--counterexample", "timed_exit")
    assert dot.returncode == 0, dot.stderr
    assert 'color="#d62728"' in dot.stdout
    assert dot_errors(dot.stdout) is None
    mer = taskflow("graph", str(planted), "--counterexample", "timed_exit")
    assert "class approach,searching counterexample" in mer.stdout and "linkStyle" in mer.stdout
    assert mermaid_errors([mer.stdout]) == [None]


def test_a_property_counterexample_is_drawn_and_replayed_by_name(tmp_path: Path) -> None:
    f = tmp_path / "prop.yaml"
    f.write_text(PLANTED.replace("machine:\n", 'properties:\n  never_search:\n    never: "state(searching)"\nmachine:\n', 1))
    dot = taskflow("graph", str(f), "--format", "dot", "--counterexample", "property:never_search")
    assert dot.returncode == 0 and 'color="#d62728"' in dot.stdout, dot.stderr
    r = taskflow("verify", str(f), "--replay", str(tmp_path / "cex"), "--check", "property:never_search")
    assert "the engine followed the counterexample" in r.stdout, r.stdout + r.stderr
    bad = taskflow("graph", str(f), "--counterexample", "nope")
    assert bad.returncode == 1 and "--counterexample 'nope' — valid: no_trap," in bad.stderr
    assert "property:never_search" in bad.stderr and "Traceback" not in bad.stderr
    bad = taskflow("verify", str(f), "--replay", str(tmp_path / "x"), "--check", "outcomes")
    assert "--check outcomes: no such check has a counterexample" in bad.stderr and "property:never_search" in bad.stderr


def test_validate_verify_reports_both(planted: Path) -> None:
    r = taskflow("validate", "--verify", str(planted), str(POSE))
    assert r.returncode == 1
    assert "planted.yaml: ok" in r.stdout and "timed_exit fails" in r.stdout
    assert "viki_hyco.yaml: ok" in r.stdout and "verified" in r.stdout


@pytest.mark.parametrize(("args", "message"), [
    (["--max-time", "ten"], "--max-time 'ten'"),
    (["--max-states", "0"], "--max-states 0: must be at least 1"),
    (["--max-states", "3"], "more than 3 configurations"),
    (["--graph-nonsense"], "unrecognized arguments"),
])
def test_bad_values_get_one_clear_line(args: list[str], message: str) -> None:
    r = taskflow("verify", str(POSE), *args)
    assert r.returncode != 0
    assert message in r.stderr and "Traceback" not in r.stderr
