"""The user-journey matrix: every shipped mission through every consumer of its run record, as a user
chains the commands.

For each mission in ``missions/*.yaml`` (fast mode: geometric perception where the world has one, a
short ``--max-time`` where the mission is long), through ``taskflow.cli.main`` in-process:
``run`` → ``plot`` → ``export`` (the MCAP read back with the ``mcap`` library: every transition record
and every tick's messages) → the replay page's data endpoints (``serve_replay`` on 127.0.0.1, an
ephemeral port: every GET the page makes, checked against the run record) → ``graph`` (Mermaid: exit 0
and not empty; dot: through Graphviz ``dot -Tsvg``). Then once with an operator script (pause, resume,
inject, hold, resume, pre-empt) followed by the same consumers, and once through ``batch`` (2 trials,
twice) → ``plot`` of a batch → ``compare``. Every kind of record the engine writes (operator, region,
foreach item, retry, timeout, sub-mission, done) is in at least one journey (:data:`ENGINE_KINDS`, checked by
``test_the_journeys_cover_every_record_kind``), so each is read by every consumer. About 2 minutes on a
quiet 2-core machine.
"""

from __future__ import annotations

import json
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from diagram_parsers import dot_errors, mermaid_errors
from mcap.reader import make_reader

from taskflow.cli import main
from taskflow.mission.loader import CompiledMission, load_mission
from taskflow.operate.replay import serve_replay

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"
GEOMETRIC = ("--set", "world.params.perception=geometric")  # quad_room's fast mode (the ViKi missions ship in it)

#: the kinds of record the engine writes that a consumer must read (beyond start, guard and event)
ENGINE_KINDS = frozenset({"operator", "region", "foreach item", "retry", "timeout", "sub-mission", "done"})


@dataclass(frozen=True)
class Journey:
    """One shipped mission's journey: ``args`` for ``taskflow run``, its ``outcome`` at seed 0, and the
    record kinds its run writes (:func:`record_kinds`)."""

    mission: str
    outcome: str
    kinds: frozenset[str]
    args: tuple[str, ...] = ()
    name: str = ""
    frames: bool = False  # a rendered mode: camera frames in the record


def _j(mission: str, outcome: str, kinds: set[str], *args: str, name: str = "", frames: bool = False) -> Journey:
    return Journey(mission, outcome, frozenset(kinds), tuple(args), name or mission, frames)


JOURNEYS = [
    _j("car_waypoints", "succeeded", {"foreach item", "done"}),
    _j("car_waypoints_unreachable", "failed", {"timeout"}),
    _j("husky_viki_approach", "succeeded", set()),
    _j("husky_waypoints", "succeeded", {"foreach item", "done"}),
    _j("screw_fastening", "succeeded", {"region", "sub-mission", "foreach item", "done"}),
    _j("screw_fastening_trolley", "failed", {"region", "sub-mission", "foreach item", "retry", "done"}),
    _j("viki_backward", "succeeded", set()),
    _j("viki_forward", "succeeded", set()),
    _j("viki_hyco", "succeeded", set()),
    _j("viki_mgbm", "failed", {"timeout"}),
    _j("viki_vs_only", "failed", set()),
    _j("visual_path_obstacles", "succeeded", set(), *GEOMETRIC),
    _j("visual_path_oval", "timeout", set(), *GEOMETRIC, "--max-time", "25"),
    _j("visual_path_oval_feedforward", "timeout", set(), *GEOMETRIC, "--max-time", "25"),
    _j("visual_path_oval_feedforward_tuned", "timeout", set(), *GEOMETRIC, "--max-time", "25"),
    _j("visual_path_pose_regulation", "succeeded", set(), *GEOMETRIC),
    _j("visual_path_pose_regulation", "timeout", set(), "--max-time", "2", name="visual_path_pose_regulation-rendered",
       frames=True),
]

#: a toy mission on the real car world for the operator journey: it waits for an operator's event
OPERATED = """\
mission: operated_car
description: The car waits for the operator's go, then drives two waypoints.
robot: racecar
world: {name: flat_ground, params: {start: [0.0, 0.0, 0.0]}}
rate_hz: 20
max_time: 60 s
events: [operator_go]
parameters:
  waypoints: [[1.5, 0.3], [2.5, 1.2]]
profiles:
  gains:
    cruise: {k1: [1.0, 1.0], d: 0.325}
machine:
  initial: wait_for_go
  states:
    wait_for_go:
      transitions: [{to: drive, on: operator_go}]
    drive:
      bind: {gains: cruise}
      foreach: {in: waypoints, as: goal}
      initial: approach
      transitions:
        - {to: done, done: succeeded}
        - {to: error, done: failed}
      states:
        approach:
          task: {name: car_goto, params: {target: $goal}}
          transitions:
            - {to: reached, when: "pos_error < 5 cm", for: 0.2 s}
            - {to: stuck, after: 30 s}
        reached: {final: succeeded}
        stuck: {final: failed}
    done: {final: succeeded}
    error: {final: failed}
"""
OPERATOR_SCRIPT = """\
- {t: 0.5, action: pause, who: journey}
- {t: 0.5, action: resume, who: journey}
- {t: 1.0, action: inject, args: {event: operator_go}, who: journey}
- {t: 3.0, action: hold, who: journey}
- {t: 4.0, action: resume, who: journey}
- {t: 5.0, action: preempt, args: {to: drive}, who: journey}
"""


# -- helpers --------------------------------------------------------------------------------------


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    """``taskflow ARGV`` in-process: its exit code and everything it printed."""
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err, out + err
    return code, out + err


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def record_kinds(records: list[dict[str, Any]], mission: CompiledMission) -> set[str]:
    """The kinds of record in ``transitions.jsonl``: its causes, and ``region`` / ``sub-mission`` for a
    transition into a leaf of a parallel region / of a machine spliced in from a sub-mission file."""
    kinds = {"foreach item" if r["cause"] == "next_item" else r["cause"] for r in records}
    for r in records:
        for leaf in str(r.get("to", "")).split("|"):
            node = mission.states.get(leaf)
            if node is None:
                continue
            if any(a.owns is not None for a in node.ancestors()):
                kinds.add("region")
            if any(a.use is not None for a in node.ancestors()):
                kinds.add("sub-mission")
    return kinds


def get(url: str) -> tuple[bytes, str]:
    with urllib.request.urlopen(url, timeout=20) as r:
        assert r.status == 200, url
        return r.read(), r.headers.get("Content-Type", "")


def get_json(url: str) -> Any:
    body, kind = get(url)
    assert kind.startswith("application/json"), (url, kind)
    return json.loads(body)


def trace_rows(run: Path) -> list[list[str]]:
    return [line.split(",") for line in (run / "trace.csv").read_text().splitlines()]


# -- the consumers ----------------------------------------------------------------------------------


def check_plot(capsys: pytest.CaptureFixture[str], run: Path) -> None:
    code, out = cli(capsys, "plot", run)
    assert code == 0, out
    pngs = {p.name for p in run.glob("*.png")}
    assert {"path.png", "metrics.png", "commands.png"} <= pngs, pngs
    assert all((run / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def check_export(capsys: pytest.CaptureFixture[str], run: Path, records: list[dict[str, Any]]) -> None:
    """The MCAP holds every transition record (the same fields) and one metrics message per tick."""
    code, out = cli(capsys, "export", run)
    assert code == 0, out
    by_topic: dict[str, list[Any]] = {}
    with (run / "telemetry.mcap").open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            by_topic.setdefault(channel.topic, []).append(json.loads(message.data))
    # state changes on /transitions, operator actions on /operator, each in the record's order
    assert by_topic.get("/transitions") == [r for r in records if "action" not in r]
    assert by_topic.get("/operator", []) == [r for r in records if "action" in r]
    ticks = len(trace_rows(run)) - 1
    assert len(by_topic["/metrics"]) == len(by_topic["/commands"]) == len(by_topic["/ground_truth"]) == ticks
    states = [row[1] for row in trace_rows(run)[1:]]
    assert [m["state"] for m in by_topic["/metrics"]] == states
    frames = read_jsonl(run / "frames.jsonl") if (run / "frames.jsonl").is_file() else []
    images = [m for topic, ms in by_topic.items() if topic.startswith("/camera/") for m in ms]
    assert len(images) == len(frames)


def check_view(run: Path, records: list[dict[str, Any]], mission: CompiledMission) -> None:
    """Every GET the replay page makes, from a ``taskflow view`` server on 127.0.0.1, against the record."""
    server = serve_replay(run, "127.0.0.1:0")
    try:
        url = server.url.rstrip("/")
        page, kind = get(url + "/")
        assert kind.startswith("text/html") and b"view.js" in page
        for asset in ("view.js", "view.css"):
            assert get(f"{url}/web/{asset}")[0] == (ROOT / "taskflow" / "operate" / "web" / asset).read_bytes()
        summary = json.loads((run / "summary.json").read_text())
        assert get_json(url + "/view/summary") == summary
        state = get_json(url + "/state")
        assert (state["outcome"], state["state"], state["running"]) == (summary["outcome"], summary["final_state"],
                                                                     False)
        machine = get_json(url + "/view/machine")
        paths: set[str] = set()
        stack = [machine["root"]]
        while stack:
            node = stack.pop()
            paths.add(node["path"])
            stack.extend(node["children"])
        visited = {leaf for r in records for leaf in str(r.get("to", "")).split("|") if leaf}
        assert visited <= paths, visited - paths  # the page can draw every state the run was in
        assert machine["columns_known"] and set(mission.states) <= paths
        rows: list[list[Any]] = []
        since, columns = 0, None
        while True:
            chunk = get_json(f"{url}/view/trace?since={since}")
            columns = chunk["columns"]
            rows += chunk["rows"]
            since = chunk["next"]
            if chunk["done"]:
                break
        csv = trace_rows(run)
        assert columns == csv[0] and len(rows) == len(csv) - 1
        assert [r[1] for r in rows] == [r[1] for r in csv[1:]]
        assert get_json(url + "/view/transitions?since=0")["records"] == records
        frames = get_json(url + "/view/frames?since=0")
        recorded = read_jsonl(run / "frames.jsonl") if (run / "frames.jsonl").is_file() else []
        assert len(frames["records"]) == len(recorded)
        for f in recorded[:3]:
            image, kind = get(f"{url}/view/frame?sensor={f['sensor']}&t={f['stamp']!r}")
            assert kind == "image/png" and image == (run / f["file"]).read_bytes()
    finally:
        server.stop()


MERMAID_SEEN: dict[str, str] = {}
"""The Mermaid text of every journey's mission (file → text), parsed by Mermaid's own parser together, in
one Node process, by the last test of this file."""


def check_graph(capsys: pytest.CaptureFixture[str], mission: Path) -> None:
    code, mermaid = cli(capsys, "graph", mission)
    assert code == 0 and mermaid.strip(), mermaid
    MERMAID_SEEN[str(mission)] = mermaid
    code, dot = cli(capsys, "graph", "--format", "dot", mission)
    assert code == 0 and dot.startswith("digraph"), dot
    assert dot_errors(dot) is None, dot_errors(dot)  # Graphviz lays it out, without a warning


def check_verify(capsys: pytest.CaptureFixture[str], mission: Path, records: list[dict[str, Any]], outcome: str) -> None:
    """`taskflow verify` proves the mission's checks, and the PyBullet run's own records are a path of the model."""
    code, out = cli(capsys, "verify", mission)
    assert code == 0, out
    from taskflow.verify.model import build_model

    build_model(load_mission(mission)).path_of(records, outcome=outcome)


def check_record(run: Path, out: str, outcome: str) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The run wrote a readable record, and its end-of-run report read it."""
    summary = json.loads((run / "summary.json").read_text())
    assert summary["outcome"] == outcome, summary["reason"]
    assert f"outcome: {outcome}" in out and "no metric summary" not in out and "unreadable" not in out, out
    assert "run record:" in out
    return summary, read_jsonl(run / "transitions.jsonl")


# -- the journeys ---------------------------------------------------------------------------------


@pytest.mark.parametrize("journey", JOURNEYS, ids=[j.name for j in JOURNEYS])
def test_a_shipped_mission_through_every_consumer(journey: Journey, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    file = MISSIONS / f"{journey.mission}.yaml"
    run = tmp_path / "run"
    code, out = cli(capsys, "run", file, "--seed", "0", "--out", run, "--no-control", "--quiet", *journey.args)
    assert code == (0 if journey.outcome == "succeeded" else 1), out
    _, records = check_record(run, out, journey.outcome)
    mission = load_mission(file)
    kinds = record_kinds(records, mission)
    assert journey.kinds <= kinds, journey.kinds - kinds
    assert (run / "frames.jsonl").is_file() == journey.frames
    check_plot(capsys, run)
    check_export(capsys, run, records)
    check_view(run, records, mission)
    check_graph(capsys, file)
    check_verify(capsys, file, records, journey.outcome)


def test_the_journeys_cover_every_record_kind() -> None:
    covered = set().union(*(j.kinds for j in JOURNEYS)) | {"operator"}  # the operator journey below
    assert covered >= ENGINE_KINDS, ENGINE_KINDS - covered


def test_an_operated_run_through_every_consumer(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Pause, resume, inject, hold, resume and pre-empt by script; then plot, export, view, graph."""
    file = tmp_path / "operated_car.yaml"
    file.write_text(OPERATED)
    script = tmp_path / "ops.yaml"
    script.write_text(OPERATOR_SCRIPT)
    run = tmp_path / "run"
    code, out = cli(capsys, "run", file, "--seed", "0", "--out", run, "--no-control", "--quiet",
                    "--operator-script", script)
    records = read_jsonl(run / "transitions.jsonl")
    actions = [(r["action"], r["who"]) for r in records if "action" in r]
    assert actions == [(a, "journey") for a in ("pause", "resume", "inject", "hold", "resume", "preempt")]
    preempt = [r for r in records if r.get("cause") == "operator" and "to" in r]
    assert len(preempt) == 1 and preempt[0]["to"] == "drive.approach" and preempt[0]["who"] == "journey"
    assert any(r.get("cause") == "event" and r.get("event") == "operator_go" for r in records)
    assert code == 0, out
    summary, records = check_record(run, out, "succeeded")
    assert [it["outcome"] for it in summary["iterations"]][-2:] == ["succeeded", "succeeded"]
    mission = load_mission(file)
    assert {"operator", "foreach item", "done", "event"} <= record_kinds(records, mission)
    check_plot(capsys, run)
    check_export(capsys, run, records)
    check_view(run, records, mission)
    check_graph(capsys, file)
    from taskflow.verify.model import build_model

    build_model(mission, operator=True).path_of(records, outcome="succeeded")  # held time, pre-emption and all


def test_two_batches_then_compare(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = MISSIONS / "car_waypoints.yaml"
    for name, seed in (("a", "0"), ("b", "10")):
        code, out = cli(capsys, "batch", file, "--trials", "2", "--workers", "2", "--seed", seed,
                        "--out", tmp_path / name)
        assert code == 0, out
        batch = json.loads((tmp_path / name / "batch.json").read_text())
        assert [t["seed"] for t in batch["trials"]] == [int(seed), int(seed) + 1]
        assert [t["outcome"] for t in batch["trials"]] == ["succeeded", "succeeded"]
        code, out = cli(capsys, "plot", tmp_path / name)
        assert code == 0 and list((tmp_path / name).glob("*.png")), out
    code, out = cli(capsys, "compare", tmp_path / "a", tmp_path / "b", "--json")
    assert code == 0, out
    (comparison,) = json.loads(out)
    assert comparison["success"]["a"] == comparison["success"]["b"] == [2, 2]
    for side in ("a", "b"):  # compare reads the batches' own aggregates
        batch = json.loads((tmp_path / side / "batch.json").read_text())
        assert comparison["metrics"]["pos_error"][f"mean_{side}"] == pytest.approx(
            batch["aggregate"]["metrics"]["pos_error"]["mean"])
    code, out = cli(capsys, "compare", tmp_path / "a", tmp_path / "b")
    assert code == 0 and "mission success: A 2/2" in out and "pos_error" in out, out


def test_every_journeys_diagram_is_accepted_by_mermaids_own_parser(capsys: pytest.CaptureFixture[str]) -> None:
    """The Mermaid of every mission a journey drew (and of every shipped one a selection left out) through the
    ``mermaid`` package's parser, in one Node process."""
    for file in sorted(MISSIONS.glob("*.yaml")):  # the shipped missions no journey drew (a -k selection)
        if str(file) not in MERMAID_SEEN:
            code, text = cli(capsys, "graph", file)
            assert code == 0, text
            MERMAID_SEEN[str(file)] = text
    files = sorted(MERMAID_SEEN)
    errors = mermaid_errors([MERMAID_SEEN[f] for f in files])
    assert {f: e for f, e in zip(files, errors) if e is not None} == {}
    assert len(files) >= len(list(MISSIONS.glob("*.yaml")))
