"""Every record kind the engine writes is read by every reader of a run record.

Real runs of the toy missions (tests/toys.py) through the command line: the operator's actions of an
operator script (pause, hold, resume, inject, preempt: ``OperatorRecord`` lines without ``from``/``to``),
state changes caused by start, timeout, guard, event, done, next_item, retry and the operator's pre-emption,
foreach items (retried ones too) and parallel regions.  Each record is then read back by the end-of-run summary, ``taskflow
plot`` (the operator's actions marked on the time axis), ``taskflow export`` (read back with the
``mcap`` reader) and the replay page's endpoints.
"""

from __future__ import annotations

import contextlib
import io
import json
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from taskflow.cli import main
from taskflow.operate.replay import serve_replay
from taskflow.readers.plots import metrics_figure
from taskflow.readers.recorded import load_run

MISSIONS = Path(__file__).resolve().parents[1] / "machine" / "missions"
FULL_SCRIPT = """\
- {t: 1.0, action: pause, who: script}
- {t: 1.0, action: hold, who: ann}
- {t: 1.0, action: resume, who: ann}
- {t: 1.5, action: inject, who: ann, args: {event: target_lost}}
- {t: 2.0, action: preempt, who: bob, args: {to: operate.home}}
"""
REGION_SCRIPT = """\
- {t: 0.5, action: hold, who: ann}
- {t: 1.0, action: resume, who: ann}
- {t: 2.0, action: preempt, who: bob, args: {to: stopped}}
"""
SUB_MISSION = {  # a mission using a sub-mission in a foreach loop (as tests/machine/test_submission.py)
    "m.yaml": """\
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
parameters: {spots: [1.0, 0.5], tol: 2 cm}
machine:
  initial: pick
  states:
    pick:
      foreach: {in: spots, as: spot}
      use: lib/goto.yaml
      with: {target: $spot, reach: $tol}
      transitions: [{to: fin, done: true}]
    fin: {final: succeeded}
""",
    "lib/goto.yaml": """\
submission: goto_and_visit
description: go to $target, then to each of $vias
parameters: {target: ~, reach: 1 cm, vias: [0.25]}
profiles:
  gains: {soft: {kp: 2.0}}
machine:
  bind: {gains: soft}
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: $target}}
      transitions: [{to: vias, when: "pos_error < $reach"}]
    vias:
      foreach: {in: vias, as: via}
      initial: step
      transitions: [{to: arrived, done: true}]
      states:
        step:
          task: {name: toy_goto, params: {target: $via}}
          transitions: [{to: ok, when: "pos_error < $reach"}]
        ok: {final: succeeded}
    arrived: {final: succeeded}
""",
}
SUB_SCRIPT = """\
- {t: 0.5, action: pause, who: script}
- {t: 0.5, action: resume, who: ann}
"""
CASES = {  # name: (mission, operator script or None, extra arguments, the causes its record must hold)
    "operator": ("toy_full.yaml", FULL_SCRIPT, [], {"start", "timeout", "event", "operator", "guard", "done"}),
    "items": ("toy_full.yaml", None, [], {"start", "timeout", "guard", "event", "next_item", "done"}),
    "regions": ("toy_regions.yaml", REGION_SCRIPT, [], {"start", "operator", "timeout"}),
    "sub-mission": ("m.yaml", SUB_SCRIPT, [], {"start", "guard", "next_item", "done"}),
    "retry": ("toy_retry.yaml", None, [], {"start", "timeout", "retry", "guard", "next_item", "done"}),
}
WRITTEN = {"sub-mission": SUB_MISSION}  # cases whose mission files the test writes


def _lines(run: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run / "transitions.jsonl").read_text().splitlines() if line.strip()]


@pytest.fixture(scope="module", params=sorted(CASES))
def recorded(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    mission, script, extra, _ = CASES[request.param]
    out = tmp_path_factory.mktemp(request.param)
    for name, text in WRITTEN.get(request.param, {}).items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
    args = ["run", str(out / mission if request.param in WRITTEN else MISSIONS / mission), "--no-control", "--out", str(out / "run"), *extra]
    if script is not None:
        (out / "ops.yaml").write_text(script)
        args += ["--operator-script", str(out / "ops.yaml")]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(args) in (0, 1)  # regions: pre-empted into `stopped`, which fails
    return out / "run", buf.getvalue()


def test_the_record_holds_every_kind(recorded: tuple[Path, str], request: pytest.FixtureRequest) -> None:
    run, _ = recorded
    causes = {r["cause"] for r in _lines(run)}
    assert CASES[request.node.callspec.params["recorded"]][3] <= causes


def test_the_end_of_run_summary_lists_the_operator_actions(recorded: tuple[Path, str]) -> None:
    run, printed = recorded
    assert "no metric summary" not in printed and "task and sensor metrics" in printed
    ops = [r for r in _lines(run) if r["cause"] == "operator" and "action" in r]
    assert printed.count(" by ") >= len(ops)
    if ops:
        assert f"operator actions ({len(ops)}):" in printed
        for op in ops:
            arg = {"preempt": f" --to {op['args'].get('to')}", "inject": f" {op['args'].get('event')}"}.get(op["action"], "")
            assert f"{op['action']}{arg} by {op['who']} (tick {op['tick']}, in {op['state']})" in printed
    else:
        assert "operator actions" not in printed
    if "outcome: succeeded" not in printed:  # the chain of transitions names who pre-empted, to where
        for r in _lines(run):
            if r["cause"] == "operator" and "from" in r:
                assert f"{r['from']} → {r['to']}: pre-empted by {r['who']} (operator)" in printed, printed


def test_plot_succeeds_and_marks_the_operator_actions_on_the_time_axis(recorded: tuple[Path, str],
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    run, _ = recorded
    assert main(["plot", str(run)]) == 0
    assert (run / "metrics.png").stat().st_size > 0 and (run / "commands.png").stat().st_size > 0
    capsys.readouterr()
    fig = metrics_figure(load_run(run))
    top = fig.axes[0]
    marked = sorted({float(line.get_xdata()[0]) for line in top.lines if line.get_gid() == "operator"})
    assert marked == sorted({r["t"] for r in _lines(run) if r["cause"] == "operator" and "action" in r})
    names = [t.get_text() for t in top.texts if t.get_gid() == "operator"]
    for r in _lines(run):
        if r["cause"] == "operator" and "action" in r:
            assert any(r["action"] in n and r["who"] in n for n in names), (r, names)


def test_export_carries_the_operator_actions_and_every_transition(recorded: tuple[Path, str],
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from mcap.reader import make_reader

    run, _ = recorded
    assert main(["export", str(run), "--output", str(run / "t.mcap")]) == 0
    capsys.readouterr()
    got: dict[str, list[dict[str, Any]]] = {"/operator": [], "/transitions": []}
    with open(run / "t.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=list(got)):
            got[channel.topic].append(json.loads(message.data))
    records = _lines(run)
    assert got["/operator"] == [r for r in records if r["cause"] == "operator" and "action" in r]
    assert got["/transitions"] == [r for r in records if "from" in r]


def test_the_view_serves_every_record(recorded: tuple[Path, str]) -> None:
    run, _ = recorded
    server = serve_replay(run, "127.0.0.1:0")
    try:
        def get(path: str) -> Any:
            with urllib.request.urlopen(server.url + path, timeout=10) as r:
                return json.loads(r.read())

        assert get("/view/transitions?since=0")["records"] == _lines(run)
        assert get("/view/summary") == json.loads((run / "summary.json").read_text())
        assert get("/view/trace?since=0")["done"] and get("/view/machine")["mission"]
        assert get("/view/frames?since=0") == {"records": [], "next": 0}
    finally:
        server.stop()


def test_every_reader_tells_a_retry_apart(recorded: tuple[Path, str], request: pytest.FixtureRequest) -> None:
    """A ``retry`` record: the summary counts attempts, the report names each retry, the plot labels it."""
    from taskflow.readers.plots import _transition_labels
    from taskflow.readers.report import describe_transition

    run, printed = recorded
    retries = [r for r in _lines(run) if r["cause"] == "retry"]
    if request.node.callspec.params["recorded"] != "retry":
        assert not retries
        return
    assert [(r["from"], r["item"], r["attempt"]) for r in retries] == [("visit.late", 0, 2), ("visit.late", 1, 2),
                                                                       ("visit.late", 1, 3)]
    assert "items of visit: 2/2 succeeded (rule: 1, 1 required; 5 attempts, 2 items retried)" in printed
    summary = json.loads((run / "summary.json").read_text())
    assert [(it["attempts"], it["retried"]) for it in summary["iterations"]] == [(2, ["late"]), (3, ["late", "late"])]
    loaded = load_run(run)
    described = [describe_transition(r, {}) for r in loaded.transitions if r.cause == "retry"]
    assert described[0].endswith("visit.late → visit.go: retry of item 0 in visit, attempt 2 (the last ended 'failed')")
    assert any("go (attempt 3)" in text for _, text in _transition_labels(loaded))
