"""Campaigns: sweeps (grid, grouping, bad input), the campaign directory, interrupt + resume to the same
``batch.json``, the same per-trial results whatever the number of workers, ``taskflow compare`` and the
campaign figures.

Toy-mission batches run in this process (``--workers 1``: the toys are registered here only); the
interrupt/resume test runs the real ``viki_forward`` mission (the fastest shipped one, capped at 8 s
simulated) in ``taskflow batch`` subprocesses with a worker pool.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.campaign import Campaign, CampaignError, grid, parse_sweep
from taskflow.campaigns.compare import compare
from taskflow.campaigns.stats import fisher_exact, wilson_interval
from taskflow.cli import main

HERE = Path(__file__).parents[1]
ROOT = HERE.parent
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
FAST = str(ROOT / "missions" / "viki_forward.yaml")  # ~0.4 s a trial at 8 s simulated


# -- sweeps ------------------------------------------------------------------------------------------------


def test_parse_sweep_splits_at_top_level_commas_only() -> None:
    sweep = parse_sweep(["world.params.dropout=0, 0.25,0.5", "world.params.image_size=[320, 180],[640, 360]",
                         "world.params.perception='a,b',geometric"])
    assert sweep == [("world.params.dropout", ["0", "0.25", "0.5"]),
                     ("world.params.image_size", ["[320, 180]", "[640, 360]"]),
                     ("world.params.perception", ["'a,b'", "geometric"])]


def test_grid_is_every_combination_last_key_fastest() -> None:
    conds = grid([("a", ["1", "2"]), ("b", ["x", "y", "z"])])
    assert [c.values for c in conds] == [{"a": a, "b": b} for a in "12" for b in "xyz"]
    assert [c.index for c in conds] == list(range(6))
    assert conds[4].overrides == ["a=2", "b=y"] and conds[4].label == "a=2, b=y"
    assert conds[4].parsed_values() == {"a": 2, "b": "y"}
    assert [c.values for c in grid([])] == [{}] and grid([])[0].label == "all"


@pytest.mark.parametrize("items, overrides, message", [
    (["world.params.dropout"], [], "is not KEY=V1,V2"),
    (["=1,2"], [], "is not KEY=V1,V2"),
    (["world.params.dropout="], [], "is not KEY=V1,V2"),
    (["world.params.dropout=0,,1"], [], "an empty value"),
    (["world.params.dropout=0,1,"], [], "an empty value"),
    (["world.params.dropout=0,0.5,0"], [], "value '0' is given twice"),
    (["a=1,2", "a=3"], [], "--sweep a is given twice"),
    (["a=1,2"], ["a=5"], "also set with --set"),
    (["a=[1,2"], [], "unbalanced"),
    (["a=1,{b: [}"], [], "unbalanced"),
])
def test_bad_sweeps_say_what_is_wrong(items: list[str], overrides: list[str], message: str) -> None:
    with pytest.raises(CampaignError, match=message.replace("[", r"\[")):
        parse_sweep(items, overrides)


@pytest.mark.parametrize("sweep, message", [
    ("world.params.tool_ok=true,maybe", "--sweep world.params.tool_ok=maybe"),
    ("world.params.nowhere=1,2", "--sweep world.params.nowhere=1: unknown key 'nowhere'"),
    ("world.params.start=0,,1", "an empty value"),
])
def test_bad_sweeps_on_the_command_line_are_one_line_and_start_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], sweep: str, message: str) -> None:
    out = tmp_path / "b"
    assert main(["batch", str(TOY), "--trials", "2", "--workers", "1", "--out", str(out), "--sweep", sweep]) == 1
    captured = capsys.readouterr()
    assert message in captured.err and "Traceback" not in captured.err
    assert len(captured.err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_sweep_groups_trials_and_aggregates_by_condition(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sweep"
    code = main(["batch", str(TOY), "--trials", "3", "--workers", "1", "--seed", "4", "--out", str(out),
                 "--sweep", "world.params.tool_ok=true,false", "--sweep", "parameters.tol=1 cm,2 cm", "--plot"])
    assert code == 1  # half the conditions fail
    text = capsys.readouterr().out
    batch = json.loads((out / "batch.json").read_text())
    assert batch["sweep"] == {"world.params.tool_ok": [True, False], "parameters.tol": ["1 cm", "2 cm"]}
    assert [c["label"] for c in batch["conditions"]] == [
        "world.params.tool_ok=true, parameters.tol=1 cm", "world.params.tool_ok=true, parameters.tol=2 cm",
        "world.params.tool_ok=false, parameters.tol=1 cm", "world.params.tool_ok=false, parameters.tol=2 cm"]
    assert [(t["condition"], t["seed"]) for t in batch["trials"]] == [(c, s) for c in range(4) for s in (4, 5, 6)]
    for c in batch["conditions"]:
        agg = c["aggregate"]
        ok = 3 if c["values"]["world.params.tool_ok"] else 0
        assert agg["trials"] == 3 and agg["outcomes"].get("succeeded", 0) == ok
        assert agg["success_ci95"] == pytest.approx(list(wilson_interval(ok, 3)))
        for loop in agg["items"].values():
            assert loop["success_ci95"] == pytest.approx(list(wilson_interval(loop["succeeded"], loop["attempted"])))
        t = agg["metrics"]["sim_time_s"]
        assert t["ci95"][0] <= t["mean"] <= t["ci95"][1]
    assert batch["aggregate"]["trials"] == 12 and batch["aggregate"]["outcomes"]["succeeded"] == 6
    assert "condition 3: world.params.tool_ok=false, parameters.tol=2 cm" in text and "[" in text
    assert (out / "success_vs_world_params_tool_ok.png").stat().st_size > 0
    assert (out / "success_vs_parameters_tol.png").stat().st_size > 0
    # the same seeds in every condition: the conditions differ only by the swept values
    assert Campaign.open(out).missing() == []


# -- the campaign directory ------------------------------------------------------------------------------


def test_a_directory_holding_a_campaign_is_not_overwritten(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "c"
    assert main(["batch", str(TOY), "--trials", "1", "--workers", "1", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["batch", str(TOY), "--trials", "1", "--workers", "1", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"{out} already holds a campaign: finish it with taskflow batch --resume {out}" in err


@pytest.mark.parametrize("argv, message", [
    (["batch", "--resume", "{tmp}/none"], "no such directory"),
    (["batch", "--resume", "{tmp}"], "not a campaign directory (it has no campaign.json)"),
    (["batch", str(TOY), "--resume", "{tmp}"], "drop MISSION"),
    (["batch", "--resume", "{tmp}", "--trials", "3", "--set", "a=1"], "drop --trials, --set"),
    (["batch", str(TOY)], "--trials N is required"),
    (["batch", "--trials", "2"], "name a mission file, or --resume DIR"),
    (["batch", str(TOY), "--trials", "2", "--address", "127.0.0.1:6379"], "needs --backend ray"),
    (["batch", str(TOY), "--trials", "2", "--backend", "ray", "--address", "127.0.0.1:1", "--workers", "2"],
     "drop --workers"),
    (["compare", "{tmp}/none", "{tmp}"], "no such file or directory"),
    (["compare", "{tmp}", "{tmp}"], "has no batch.json"),
])
def test_campaign_usage_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            argv: list[str], message: str) -> None:
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_records_of_other_campaigns_or_half_written_are_ignored(tmp_path: Path) -> None:
    out = tmp_path / "c"
    run_batch(str(TOY), trials=2, workers=1, out=out)
    camp = Campaign.open(out)
    (out / "trials" / "c000-s00001.json").write_text('{"condition": 0, "seed": 1, "summ')  # cut short
    (out / "trials" / "c007-s00001.json").write_text("{}")  # not a condition of this campaign
    assert [s for _, s in camp.missing()] == [1]


def test_a_resume_runs_only_the_mission_file_the_campaign_started_with(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """``campaign.json`` records the sha256 of its mission file; a resume checks it before the file is parsed,
    so neither an edited mission (two missions in one batch.json) nor a ``campaign.json`` naming some other
    file (a record from elsewhere) runs, and nothing of that file's text is shown."""
    mission = tmp_path / "m.yaml"
    mission.write_text(TOY.read_text())
    out = tmp_path / "c"
    run_batch(str(mission), trials=2, workers=1, out=out)
    spec = json.loads((out / "campaign.json").read_text())
    assert len(spec["mission_sha256"]) == 64
    (out / "trials" / "c000-s00001.json").unlink()

    def resume() -> tuple[int, str]:
        capsys.readouterr()
        code = main(["batch", "--resume", str(out)])
        got = capsys.readouterr()
        return code, got.out + got.err

    secret = tmp_path / "secret.yaml"
    secret.write_text("hunter2_key: hunter2\nmission: x\n")
    for name, value in (("mission", str(secret)), ("mission_sha256", None)):
        edited = dict(spec)
        if value is None:
            del edited[name]
        else:
            edited[name] = value
        (out / "campaign.json").write_text(json.dumps(edited))
        code, text = resume()
        assert code == 1 and len(text.strip().splitlines()) == 1 and "hunter2" not in text, text
        assert ("sha256 differs" if value else "no mission_sha256") in text
    (out / "campaign.json").write_text(json.dumps(spec))
    mission.write_text(TOY.read_text().replace("max_time: 60 s", "max_time: 61 s"))
    assert mission.read_text() != TOY.read_text()
    code, text = resume()
    assert code == 1 and "is not the mission file this campaign started with" in text
    assert not (out / "trials" / "c000-s00001.json").exists()
    mission.write_text(TOY.read_text())  # the same bytes again: the resume runs the missing trial
    code, text = resume()
    assert code == 0 and (out / "trials" / "c000-s00001.json").is_file(), text


# -- interrupt and resume: the same batch.json ---------------------------------------------------------


def _batch(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", "from taskflow.cli import main; raise SystemExit(main())",
                             "batch", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


@pytest.mark.mission
def test_an_interrupted_campaign_resumes_to_the_batch_json_of_an_uninterrupted_one(tmp_path: Path) -> None:
    common = ["--trials", "8", "--max-time", "8 s", "--sweep", "world.params.dropout=0,0.3"]
    cut, whole = tmp_path / "cut", tmp_path / "whole"
    proc = _batch(FAST, *common, "--workers", "2", "--out", str(cut))
    t0 = time.monotonic()
    while len(list((cut / "trials").glob("*.json"))) < 2:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 120, "no trial finished"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C, as a terminal sends it
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and f"taskflow batch --resume {cut}" in stderr
    partial = json.loads((cut / "batch.json").read_text())
    n_done = len(list((cut / "trials").glob("*.json")))
    assert partial["interrupted"] is True and 2 <= len(partial["trials"]) == n_done < 16

    # finish it in the batch's own process (one worker); the uninterrupted run uses a pool of two
    done = subprocess.run([sys.executable, "-m", "taskflow.cli", "batch", "--resume", str(cut), "--workers", "1"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr
    assert json.loads((cut / "timing.json").read_text())["trials_run"] == 16 - n_done  # only the missing ones
    ref = subprocess.run([sys.executable, "-m", "taskflow.cli", "batch", FAST, *common, "--workers", "2",
                          "--out", str(whole)], capture_output=True, text=True, timeout=300)
    assert ref.returncode in (0, 1), ref.stderr
    assert (cut / "batch.json").read_bytes() == (whole / "batch.json").read_bytes()
    batch = json.loads((whole / "batch.json").read_text())
    assert batch["interrupted"] is False and len(batch["trials"]) == 16


def _children(pid: int) -> list[int]:
    """The forked pool workers of ``pid`` (its children with its own command line)."""
    kids = []
    cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and (stat.parent / "cmdline").read_bytes() == cmdline:
            kids.append(int(stat.parent.name))
    return kids


@pytest.mark.mission
def test_a_lost_worker_leaves_the_finished_trials_and_the_campaign_resumes(tmp_path: Path) -> None:
    out = tmp_path / "lost"
    proc = _batch(FAST, "--trials", "6", "--max-time", "8 s", "--workers", "2", "--out", str(out))
    t0 = time.monotonic()
    while not list((out / "trials").glob("*.json")):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 120, "no trial finished"
        time.sleep(0.02)
    workers = _children(proc.pid)
    assert workers, "no worker process found"
    os.kill(workers[0], signal.SIGKILL)  # as the kernel's out-of-memory killer would
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "Traceback" not in stderr, stdout + stderr
    assert "a worker process died" in stderr and f"taskflow batch --resume {out}" in stderr
    errors = [line for line in stderr.strip().splitlines() if not line.startswith("batch viki_forward: ")]  # progress
    assert len(errors) == 1
    partial = json.loads((out / "batch.json").read_text())
    assert partial["interrupted"] is True and 1 <= len(partial["trials"]) < 6
    assert main(["batch", "--resume", str(out), "--workers", "1"]) in (0, 1)
    assert len(json.loads((out / "batch.json").read_text())["trials"]) == 6


# -- compare -----------------------------------------------------------------------------------------------


def _fake_batch(path: Path, successes: list[bool], errors: list[float], items: tuple[int, int] | None = None) -> Path:
    trials = [{"outcome": "succeeded" if ok else "failed", "condition": 0, "metrics": {"final_error_m": e}}
              for ok, e in zip(successes, errors)]
    agg: dict[str, Any] = {"trials": len(trials), "items": {}}
    if items is not None:
        agg["items"] = {"screws": {"succeeded": items[0], "attempted": items[1]}}
    path.mkdir()
    (path / "batch.json").write_text(json.dumps({"mission": "m", "trials": trials, "aggregate": agg,
                                                 "conditions": [{"index": 0, "label": "all", "aggregate": agg}]}))
    return path


def test_compare_uses_fisher_and_mann_whitney(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _fake_batch(tmp_path / "a", [True] * 10, [0.001 * i for i in range(10)], items=(39, 40))
    b = _fake_batch(tmp_path / "b", [True] * 3 + [False] * 7, [0.02 + 0.001 * i for i in range(10)], items=(20, 40))
    assert main(["compare", str(a), str(b), "--json"]) == 0
    (r,) = json.loads(capsys.readouterr().out)
    assert r["success"]["fisher_p"] == pytest.approx(fisher_exact(10, 10, 3, 10)) and r["success"]["differs"]
    assert r["items"]["screws"]["fisher_p"] == pytest.approx(fisher_exact(39, 40, 20, 40))
    m = r["metrics"]["final_error_m"]
    # every error of A is below every error of B: U = 0; at 10 against 10 scipy uses the normal
    # approximation with continuity correction: z = (0 - 50 + 0.5) / sqrt(10 * 10 * 21 / 12), p = 2 Phi(z)
    z = (0 - 50 + 0.5) / math.sqrt(10 * 10 * 21 / 12)
    assert m["U"] == 0.0 and m["p"] == pytest.approx(math.erfc(-z / math.sqrt(2))) and m["differs"]
    assert main(["compare", str(a), str(a)]) == 0
    text = capsys.readouterr().out
    assert "no significant difference" in text and "0 of 1 metrics differ" in text
    assert main(["compare", str(a), str(b), "--metric", "speed"]) == 1
    assert "--metric speed: not a numeric metric of both campaigns; they have final_error_m" in capsys.readouterr().err


def test_compare_pairs_conditions_of_the_same_grid(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    run_batch(str(TOY), trials=2, workers=1, out=a, sweep=["world.params.tool_ok=true,false"])
    run_batch(str(TOY), trials=2, workers=1, out=b, sweep=["world.params.tool_ok=true,false"], seed=10)
    results = compare(json.loads((a / "batch.json").read_text()), json.loads((b / "batch.json").read_text()))
    assert [(r["a"], r["b"]) for r in results] == [("world.params.tool_ok=true",) * 2, ("world.params.tool_ok=false",) * 2]
    assert [r["success"]["rate_a"] for r in results] == [1.0, 0.0]
    figure = tmp_path / "both.png"
    assert main(["compare", str(a), str(b), "--plot", str(figure)]) == 0
    assert figure.stat().st_size > 0
    c = tmp_path / "c"
    run_batch(str(TOY), trials=1, workers=1, out=c, sweep=["world.params.start=0,0.1"])
    with pytest.raises(CampaignError, match="swept different grids"):
        compare(json.loads((a / "batch.json").read_text()), json.loads((c / "batch.json").read_text()))
    plain = tmp_path / "plain"
    run_batch(str(TOY), trials=1, workers=1, out=plain)
    assert main(["compare", str(a), str(plain), "--plot", str(tmp_path / "x.png")]) == 1  # nothing swept in one


def test_timing_holds_each_trial_s_cpu_time_and_the_trials_per_cpu_hour(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """What a trial costs, independent of cores and load: each trial's CPU time in its process (mission load,
    world, loop, records), their sum and the campaign's trials per CPU-hour in ``timing.json`` and its table;
    ``batch.json`` (which depends on the mission and seeds alone) holds none of it."""
    out = tmp_path / "b"
    # exit 1: not every trial succeeds in 2 s (the batch's rule); the figures are written either way
    assert main(["batch", FAST, "--trials", "3", "--workers", "2", "--max-time", "2 s", "--out", str(out)]) == 1
    timing = json.loads((out / "timing.json").read_text())
    cpu = [t["cpu_s"] for t in timing["trials"]]
    assert len(cpu) == 3 and all(0.05 < c < 60.0 for c in cpu)  # a 2 s ViKi trial: PyBullet steps in the worker
    assert timing["trial_cpu_s"] == pytest.approx(sum(cpu))
    assert timing["trials_per_cpu_hour"] == pytest.approx(3 * 3600.0 / sum(cpu))
    assert timing["per_trial_cpu_s"] == pytest.approx(sum(cpu) / 3)
    assert "trials per CPU-hour" in capsys.readouterr().out
    assert "cpu_s" not in (out / "batch.json").read_text()
