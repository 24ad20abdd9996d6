"""Broken command-line inputs, each with the fragment its one-line message must hold.

Every case is a ``taskflow`` command on a shipped mission (so a fresh process can run it without
the test-only toy plugins).  ``tests/test_cli_bad_input.py`` runs them in-process and checks the
message, the exit code 1 and the absence of a traceback; ``benchmarks/bad_input.py`` runs each in
a fresh process and prints its wall time and peak memory (the issue's 2 s / 200 MB budget).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CAR = str(ROOT / "missions" / "car_waypoints.yaml")
VIKI = str(ROOT / "missions" / "viki_hyco.yaml")
QUAD = str(ROOT / "missions" / "visual_path_pose_regulation.yaml")


@dataclass(frozen=True)
class BadInput:
    name: str
    argv: tuple[str, ...]
    fragment: str  # the message must contain it
    where: str = ""  # the line must start with it (FILE:LINE:COL, FILE: --set …, or "taskflow CMD: --flag")


def _states_file(tmp: Path, n: int) -> Path:
    lines = ["mission: huge", "robot: racecar", "world: flat_ground", "rate_hz: 20", "machine:", "  initial: s0",
             "  states:"]
    lines += [f"    s{i}: {{final: true}}" for i in range(n)]  # ~2 MB: under the size limit, over the node limit
    path = tmp / "huge.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _with_guard(tmp: Path, guard: str, name: str) -> Path:
    text = Path(CAR).read_text()
    old = 'when: "pos_error < 3 cm"'
    assert old in text, "car_waypoints.yaml changed: update tests/bad_inputs.py"
    path = tmp / name
    path.write_text(text.replace(old, f"when: {guard!r}", 1))
    return path


def cases(tmp: Path) -> list[BadInput]:
    """Every case; files they need are written under ``tmp``."""
    zero = tmp / "zero.yaml"
    if not zero.exists():
        os.symlink("/dev/zero", zero)
    batch_dir = tmp / "a_batch"
    batch_dir.mkdir(exist_ok=True)
    (batch_dir / "batch.json").write_text("{}\n")
    deep = "(" * 200 + "pos_error < 1 cm" + ")" * 200
    nots = "not " * 5000 + "pos_error < 1 cm"
    out = [
        BadInput("max-time-nan", ("run", CAR, "--max-time", "nan"), "must be a finite", "taskflow run: --max-time"),
        BadInput("max-time-inf", ("run", CAR, "--max-time", "inf"), "must be a finite", "taskflow run: --max-time"),
        BadInput("max-time-huge", ("run", CAR, "--max-time", "1e308"), "≤ 86400 s", "taskflow run: --max-time"),
        BadInput("max-time-negative", ("run", CAR, "--max-time", "-5"), "must be > 0 s", "taskflow run: --max-time"),
        BadInput("max-time-unit", ("run", CAR, "--max-time", "30 deg"), "expected a time", "taskflow run: --max-time"),
        BadInput("set-max-time-nan", ("validate", CAR, "--set", "max_time=.nan"), "must be a finite",
                 f"{CAR}: --set max_time=.nan"),
        BadInput("physics-1-hz", ("validate", CAR, "--set", "world.params.physics_hz=1"), "greater than or equal to 100",
                 f"{CAR}: --set world.params.physics_hz=1"),
        BadInput("rates-do-not-divide", ("validate", CAR, "--set", "rate_hz=7"), "does not divide the physics rate 240 Hz",
                 f"{CAR}: --set rate_hz=7"),
        BadInput("rate-with-wrong-unit", ("validate", CAR, "--set", "rate_hz=20 s"), "expected a frequency",
                 f"{CAR}: --set rate_hz=20 s"),
        BadInput("distribution-support", ("validate", VIKI, "--set", "world.params.dropout={uniform: [0.5, 1.5]}"),
                 "uniform bound 1.5 is not a valid value here", f"{VIKI}: --set world.params.dropout"),
        BadInput("distribution-normal-bounded", ("validate", VIKI, "--set", "world.params.dropout={normal: [0.2, 0.05]}"),
                 "normal [0.2, 0.05] (unbounded", f"{VIKI}: --set world.params.dropout"),
        BadInput("guard-syntax-in-set", ("validate", CAR, "--set",
                                         "machine.states.drive.states.settle.transitions.0.when=pos_error <"),
                 "the expression ends too early", f"{CAR}: --set machine.states.drive.states.settle.transitions.0.when"),
        BadInput("guard-deep-parentheses", ("validate", str(_with_guard(tmp, deep, "deep.yaml"))), "more than 32 levels",
                 f"{tmp / 'deep.yaml'}:"),
        BadInput("guard-not-chain", ("validate", str(_with_guard(tmp, nots, "nots.yaml"))), "more than 32 levels",
                 f"{tmp / 'nots.yaml'}:"),
        BadInput("device-file", ("validate", str(zero)), "is not a regular file", f"{zero}:"),
        BadInput("too-many-states", ("validate", str(_states_file(tmp, 100_000))), "more than 20000 YAML nodes",
                 f"{tmp / 'huge.yaml'}:1:1:"),
        BadInput("history-yes", ("validate", CAR, "--set", "machine.states.drive.history=yes"), "write true or false",
                 f"{CAR}: --set machine.states.drive.history=yes"),
        BadInput("quad-start-outside-room", ("validate", QUAD, "--set", "world.params.start=[40, 0, 1, 0]"),
                 "outside the room", f"{QUAD}: --set world.params.start"),
        BadInput("batch-zero-trials", ("batch", CAR, "--trials", "0"), "must be at least 1", "taskflow batch: --trials 0"),
        BadInput("batch-zero-workers", ("batch", CAR, "--trials", "2", "--workers", "0"), "must be at least 1",
                 "taskflow batch: --workers 0"),
        BadInput("batch-negative-workers", ("batch", CAR, "--trials", "2", "--workers", "-2"), "must be at least 1",
                 "taskflow batch: --workers -2"),
        BadInput("plot-missing-folder", ("plot", str(tmp / "nope")), "no such folder", f"taskflow plot: {tmp / 'nope'}"),
        BadInput("plot-batch-folder", ("plot", str(batch_dir)), "a batch folder", f"taskflow plot: {batch_dir}"),
    ]
    return out
