"""Every broken command-line input of ``tests/bad_inputs.py`` gets one line — ``FILE:LINE:COL``, ``FILE:
--set …`` or ``taskflow CMD: --flag …`` — exit code 1, and no traceback (run in-process here; the
fresh-process time and memory of each are measured by ``benchmarks/bad_input.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest
from bad_inputs import CAR, BadInput, cases

from taskflow.cli import main


@pytest.fixture(scope="module")
def table(tmp_path_factory: pytest.TempPathFactory) -> dict[str, BadInput]:
    return {c.name: c for c in cases(tmp_path_factory.mktemp("bad"))}


NAMES = ["max-time-nan", "max-time-inf", "max-time-huge", "max-time-negative", "max-time-unit", "set-max-time-nan",
         "physics-1-hz", "rates-do-not-divide", "rate-with-wrong-unit", "distribution-support", "distribution-signed-support",
         "distribution-normal-bounded", "guard-syntax-in-set", "guard-deep-parentheses", "guard-not-chain",
         "device-file", "too-many-states", "history-yes", "quad-start-outside-room", "batch-zero-trials",
         "batch-zero-workers", "batch-negative-workers", "plot-missing-folder", "plot-batch-folder",
         # the "ops" block: malformed operator scripts
         "ops-yaml-syntax", "ops-empty", "ops-not-a-list", "ops-unknown-action", "ops-unknown-argument",
         "ops-argument-not-text", "ops-negative-t", "ops-infinite-t", "ops-preempt-unknown-state",
         "ops-inject-undeclared-event", "ops-pause-never-resumed",
         # issue 20, "load"
         "use-fan-out", "use-depth", "use-huge-file", "states-200-deep", "use-outside-folder", "use-directory",
         "sweep-not-key-values", "sweep-empty-value", "sweep-bad-value", "sweep-not-a-mapping", "set-unknown-state",
         "set-creates-a-key", "set-bad-yaml", "run-seed-negative", "run-seed-too-big", "batch-seed-negative",
         "batch-seed-overflows", "teach-seed-negative", "check-steps-zero", "check-param-typo",
         "check-param-bad-value", "check-param-unknown-world", "view-port-out-of-range", "check-world-cannot-host",
         # issue 20, "bounds"
         "bound-racecar-v-max", "bound-screw-rate", "bound-guard-negative-distance", "bound-viki-camera-rate",
         "bound-viki-pixel-noise"]


def test_the_table_is_the_list_below(table: dict[str, BadInput]) -> None:
    assert sorted(table) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_bad_input_gets_one_line_and_exit_1(name: str, table: dict[str, BadInput],
                                             capsys: pytest.CaptureFixture[str]) -> None:
    case = table[name]
    rc = main(list(case.argv))
    out, err = capsys.readouterr()
    assert rc == 1, (out, err)
    assert "Traceback" not in out + err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(case.where), lines[0]
    assert case.fragment in lines[0], lines[0]


@pytest.mark.mission
def test_max_time_takes_units_like_the_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["run", CAR, "--max-time", "0.2 min", "--quiet", "--out", str(tmp_path / "r")]) == 1
    out, err = capsys.readouterr()
    assert "outcome: timeout (max_time 12 s reached)" in out and "Traceback" not in err


@pytest.mark.parametrize("override", ["rate_hz=20 Hz", "rate_hz=0.02 kHz", "max_time=1e3", "max_time=2 min"])
def test_units_and_yaml_1_2_numbers_in_overrides(override: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", CAR, "--set", override]) == 0, capsys.readouterr().err


def test_set_reads_values_as_yaml_1_2_like_the_file(capsys: pytest.CaptureFixture[str]) -> None:
    """`on:` inside a --set value stays the key `on` (YAML 1.1 made it the boolean True: "unknown key True")."""
    item = "machine.states.drive.transitions.1={to: error, on: stuck}"
    assert main(["validate", CAR, "--set", item]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{CAR}: --set {item}: unknown event 'stuck'"), err


@pytest.mark.parametrize("sweep", ["rate_hz", "rate_hz=20,,40", "rate_hz=20,7", "rate_hz.x=1,2"])
def test_batch_refuses_a_bad_sweep_before_importing_the_statistics(sweep: str, tmp_path: Path) -> None:
    """A bad --sweep is answered before scipy and the backends load (main imported them first: 2-8 s)."""
    import subprocess
    import sys

    code = ("import sys; from taskflow.cli import main; rc = main(sys.argv[1:]); "
            "print(rc, sorted(m for m in ('scipy', 'taskflow.campaigns.batch', 'taskflow.campaigns.backends') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code, "batch", CAR, "--trials", "2", "--sweep", sweep],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert done.stdout.strip() == "1 []", (done.stdout, done.stderr)
    assert len(done.stderr.splitlines()) == 1 and "--sweep" in done.stderr, done.stderr
