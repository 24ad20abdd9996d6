"""``taskflow.verify.campaign``: a campaign's records as an absorbing Markov chain, solved with Storm, beside the
measured rates.

The campaigns here are written by the scripted backend (``taskflow.testing.drive``) into a campaign directory
as ``taskflow batch --keep-runs`` lays it out: a toy grasp whose every attempt draws its fate afresh (Markov:
the prediction agrees from every configuration), and the same machine under a script whose second attempt
always fails (the outcome depends on a history the configuration drops: the disagreement is reported at the
configuration that only the second attempt's runs enter).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from taskflow.campaigns.campaign import Campaign, CampaignSpec
from taskflow.execution.records import TransitionRecord
from taskflow.mission.loader import load_mission
from taskflow.mission.model import CompiledMission
from taskflow.testing import Script, ScriptState, drive
from taskflow.verify.campaign import (
    CampaignDataError,
    Configuration,
    absorption,
    configuration_of,
    estimate_chain,
    predict,
    read_run,
    storm_solve,
)

pytestmark = pytest.mark.machine

ROOT = Path(__file__).resolve().parents[2]

GRASP = """\
mission: toy_grasp
robot: toy_point
world: {name: toy_line}
rate_hz: 20
max_time: 30 s
profiles:
  gains:
    slow: {kp: 1.0}
machine:
  initial: approach
  states:
    approach:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions:
        - {to: grasp, when: "pos_error < 1 cm"}
        - {to: lost, after: 2 s}
    grasp:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions:
        - {to: placed, when: "feature_error < 1 px"}
        - {to: recover, when: "pos_error > 5 cm"}
        - {to: dropped, after: 1 s}
    recover:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions:
        - {to: grasp, when: "pos_error < 1 cm"}
        - {to: lost, after: 2 s}
    placed: {final: succeeded}
    dropped: {final: failed}
    lost: {final: failed}
"""

Fate = Callable[[np.random.Generator, int], str]  # (the run's generator, attempts so far) → ok | slip | drop


def _script(seed: int, fate: Fate) -> Script:
    """Each grasp attempt's fate is drawn when the attempt starts; approach and recover settle after 0.2 s."""
    rng = np.random.default_rng(seed)
    attempts: dict[float, str] = {}

    def metrics(s: ScriptState) -> dict[str, float]:
        if not s.state.endswith("grasp"):
            return {"pos_error": 0.0 if s.time_in_state > 0.2 else 1.0, "feature_error": 100.0}
        start = round(s.t - s.time_in_state, 6)
        if start not in attempts:
            attempts[start] = fate(rng, len(attempts))
        f, settled = attempts[start], s.time_in_state > 0.3
        return {"pos_error": 0.1 if f == "slip" and settled else 0.0,
                "feature_error": 0.0 if f == "ok" and settled else 50.0}

    return Script(metrics=metrics)


def markov_fate(rng: np.random.Generator, attempt: int) -> str:
    return str(rng.choice(["ok", "slip", "drop"], p=[0.5, 0.3, 0.2]))


def history_fate(rng: np.random.Generator, attempt: int) -> str:
    """The first attempt succeeds or slips, one in two; an attempt after a slip always drops."""
    return str(rng.choice(["ok", "slip"])) if attempt == 0 else "drop"


def _campaign(tmp_path: Path, fate: Fate, trials: int) -> tuple[CompiledMission, Path]:
    mission_file = tmp_path / "toy_grasp.yaml"
    mission_file.write_text(GRASP)
    mission = load_mission(str(mission_file))
    root = tmp_path / "batch"
    camp = Campaign.create(root, CampaignSpec(mission=str(mission_file), trials=trials, keep_runs=True))
    for seed in camp.spec.seeds():
        result = drive(mission, _script(seed, fate), out_dir=camp.run_dir(0, seed))
        camp.record(0, seed, result.summary, {})
    return mission, root


@pytest.fixture(scope="module")
def markov(tmp_path_factory: pytest.TempPathFactory) -> tuple[CompiledMission, Path]:
    return _campaign(tmp_path_factory.mktemp("markov"), markov_fate, 40)


def test_a_markov_campaign_agrees_with_its_prediction_from_every_configuration(markov: tuple[CompiledMission, Path]
                                                                               ) -> None:
    mission, root = markov
    pred = predict(mission, root)
    assert pred.agrees, pred.render()
    (cond,) = pred.conditions
    assert cond.runs == 40 and [s.configuration for s in cond.states] == ["approach", "grasp", "recover"]
    summaries = [json.loads((root / f"trial-{s:05d}" / "summary.json").read_text()) for s in range(40)]
    won = sum(s["outcome"] == "succeeded" for s in summaries)
    assert 10 < won < 40  # the script draws both outcomes
    line = {o.outcome: o for o in cond.outcomes}["succeeded"]
    # flow conservation: on the runs it was estimated from, the chain's P(outcome) is the measured rate
    assert line.k == won and line.predicted == pytest.approx(won / 40, abs=1e-6)
    assert line.interval[0] < line.predicted < line.interval[1]
    assert cond.expected_time[0] == pytest.approx(cond.expected_time[1], abs=1e-6)
    grasp = cond.states[1]
    # placed and dropped end the run as they are entered: grasp leads to the outcomes themselves
    assert grasp.visits > grasp.runs == 40 and set(grasp.successors) == {"succeeded", "failed", "recover"}
    assert "DISAGREES" not in pred.render() and "agrees" in pred.render()
    json.dumps(pred.as_dict())  # JSON-able


def test_an_outcome_that_depends_on_history_is_reported_as_a_disagreement(tmp_path: Path) -> None:
    mission, root = _campaign(tmp_path, history_fate, 40)
    pred = predict(mission, root)
    (cond,) = pred.conditions
    assert not pred.agrees
    assert all(o.agrees for o in cond.outcomes)  # from the start the chain always fits (flow conservation)
    recover = next(s for s in cond.states if s.configuration == "recover")
    ok = {o.outcome: o for o in recover.outcomes}["succeeded"]
    assert ok.k == 0 and ok.n == recover.runs > 10  # every run that slipped failed …
    assert 0.3 < ok.predicted < 0.7 and ok.interval[0] > ok.measured_interval[1]  # … the chain says one in two
    assert any(d.startswith("from recover: P(succeeded)") for d in cond.disagreements)
    text = pred.render()
    assert "DISAGREES" in text and "depends on more than its configuration" in text
    assert pred.as_dict()["agrees"] is False


def test_the_even_trials_predict_the_odd_ones(markov: tuple[CompiledMission, Path]) -> None:
    """The held-out prediction: a chain the measured rate did not shape, against the trials it has not seen."""
    mission, root = markov
    (cond,) = predict(mission, root).conditions
    held = {o.outcome: o for o in cond.held_out}
    assert set(held) == {"succeeded", "failed"} and held["succeeded"].n == 20
    summaries = [json.loads((root / f"trial-{s:05d}" / "summary.json").read_text()) for s in range(40)]
    even = sum(s["outcome"] == "succeeded" for s in summaries[0::2]) / 20
    odd = sum(s["outcome"] == "succeeded" for s in summaries[1::2])
    line = held["succeeded"]
    assert line.predicted == pytest.approx(even, abs=1e-6) and line.k == odd  # estimated on one half, measured on the other
    assert line.agrees  # the script's fate is Markov: the halves agree within their intervals
    few = predict_runs_on(mission, root, 8)
    assert few.held_out == ()  # below HELD_OUT_MIN runs there is no held-out half


def predict_runs_on(mission: CompiledMission, root: Path, n: int):  # type: ignore[no-untyped-def]
    from taskflow.campaigns.campaign import Campaign
    from taskflow.verify.campaign import _condition_runs, predict_runs

    camp = Campaign.open(root)
    (cond,) = list(camp.spec.conditions())
    return predict_runs(_condition_runs(mission, camp, cond, camp.records())[:n])


def test_storm_solves_the_chain_as_the_fundamental_matrix_does(markov: tuple[CompiledMission, Path]) -> None:
    mission, root = markov
    camp = Campaign.open(root)
    runs = [read_run(mission, camp.run_dir(0, s), s, rec["summary"]) for (_, s), rec in sorted(camp.records().items())]
    chain = estimate_chain(runs)
    p, r = chain.matrices()
    h_storm, t_storm = storm_solve(p, r, chain.outcomes)
    h_np, t_np = absorption(p, r, len(chain.outcomes))
    assert np.allclose(h_storm, h_np, atol=1e-6)
    assert np.allclose(t_storm, t_np, atol=1e-5, equal_nan=True)
    # closed form: grasp → {dropped, placed, recover} one in three each, recover → grasp: P(placed) = 1/2 from
    # either; an attempt takes 1 s, a recovery 2 s
    p = np.array([[0.0, 1 / 3, 1 / 3, 1 / 3], [1.0, 0.0, 0.0, 0.0]])
    r = np.array([[0.0, 1.0, 1.0, 1.0], [2.0, 0.0, 0.0, 0.0]])
    h, t = storm_solve(p, r, ["failed", "succeeded"])
    assert h[0] == pytest.approx([0.5, 0.5], abs=1e-6) and h[1] == pytest.approx([0.5, 0.5], abs=1e-6)
    # conditioned on placing, an attempt places with 2/3 and recovers with 1/3: T = 1 + (1/3)(2 + T) = 2.5 s
    assert t[0, 1] == pytest.approx(2.5, abs=1e-5)
    assert np.allclose(t, absorption(p, r, 2)[1], atol=1e-6)


def _rec(t: float, source: str, target: str, cause: str, **kw: object) -> TransitionRecord:
    return TransitionRecord(t=t, source=source, target=target, cause=cause, **kw)  # type: ignore[arg-type]


def test_a_configuration_keeps_other_regions_leaves_the_item_index_and_the_history_resume_point() -> None:
    mission = load_mission(str(ROOT / "missions" / "screw_fastening_trolley.yaml"))
    op, watch = "cell.operation.", "cell.safety.watch"
    screws = op + "operate.screws."
    steps = [
        _rec(0.0, "__start__", "cell", "start"),
        _rec(0.1, op + "initial_search", op + "operate.s1_platform_approach", "event"),
        _rec(1.0, op + "operate.s1_platform_approach", screws + "s2_arm_approach", "guard"),
        _rec(2.0, screws + "s2_arm_approach", screws + "screw_fastened", "guard"),
        _rec(2.0, f"{screws}screw_fastened|{watch}", screws + "s2_arm_approach", "next_item",
             state=op + "operate.screws", outcome="succeeded", item=1),
        _rec(3.0, screws + "s2_arm_approach", op + "searching", "event"),
        _rec(4.0, op + "searching", screws + "s2_arm_approach", "event", resumed=True),
    ]
    c: Configuration | None = None
    labels = []
    for rec in steps:
        c = configuration_of(mission, c, rec, "x:1")
        labels.append(c.label)
    assert labels[0] == f"{op}initial_search | {watch}"
    assert labels[2] == f"{screws}s2_arm_approach | {watch} {{screws: item 0, 0 ok}}"
    assert labels[4] == f"{screws}s2_arm_approach | {watch} {{screws: item 1, 1 ok}}"
    assert labels[5] == f"{op}searching | {watch} {{screws: item 1, 1 ok}} (operate → {screws}s2_arm_approach)"
    assert labels[6] == labels[4]  # history resumes the item where it was left
    with pytest.raises(CampaignDataError, match="x:1:1: the record leaves 'cell.operation.searching'"):
        configuration_of(mission, c, _rec(5.0, op + "searching", op + "fastened", "event"), "x:1")


# -- bad input: a clear error naming the file, never a traceback ------------------------------------------------


def test_a_campaign_without_its_run_directories_says_to_keep_them(markov: tuple[CompiledMission, Path],
                                                                  tmp_path: Path) -> None:
    mission, root = markov
    spec = json.loads((root / "campaign.json").read_text())
    bare = tmp_path / "bare"
    camp = Campaign.create(bare, CampaignSpec.from_dict({**spec, "keep_runs": False}))
    for (c, s), rec in Campaign.open(root).records().items():
        camp.record(c, s, rec["summary"], rec["timing"])
    with pytest.raises(CampaignDataError, match=r"trial-00000: no run directory for trial seed 0 — .*--keep-runs"):
        predict(mission, bare)
    with pytest.raises(CampaignDataError, match="not a campaign directory"):
        predict(mission, tmp_path)


@pytest.mark.parametrize("line, message", [
    ('{"t": 0.0, "from": "__start__", "to": "approach", "cause": "warp"}', r":1:1: cause 'warp' — valid: start"),
    ('{"t": 0.0, "from": "__start__", "to": "nowhere", "cause": "start"}', r":1:1: state 'nowhere' is no state"),
    ('{"t": 0.0, "from": "__start__", "to": "grasp", "cause": "guard"}', r":1:1: the first record's cause is 'guard'"),
    ("not json", r"transitions.jsonl:1"),
])
def test_a_malformed_record_is_an_error_at_its_line(markov: tuple[CompiledMission, Path], tmp_path: Path,
                                                    line: str, message: str) -> None:
    mission, root = markov
    camp = Campaign.open(root)
    run = tmp_path / "run"
    run.mkdir()
    (run / "transitions.jsonl").write_text(line + "\n")
    with pytest.raises(CampaignDataError, match=message) as err:
        read_run(mission, run, 0, camp.records()[(0, 0)]["summary"])
    assert str(err.value).startswith(str(run / "transitions.jsonl"))


def test_records_of_another_mission_are_refused(markov: tuple[CompiledMission, Path]) -> None:
    _, root = markov
    other = load_mission(str(ROOT / "missions" / "viki_forward.yaml"))
    with pytest.raises(CampaignDataError, match="a trial of mission 'toy_grasp', not 'viki_forward'"):
        predict(other, root)


def test_a_confidence_outside_0_1_is_refused(markov: tuple[CompiledMission, Path]) -> None:
    mission, root = markov
    with pytest.raises(ValueError, match="confidence"):
        predict(mission, root, confidence=1.5)
    assert not math.isnan(predict(mission, root, confidence=0.9, samples=200).conditions[0].outcomes[0].predicted)


def test_a_run_cut_by_max_time_ends_in_its_outcome_from_the_configuration_it_was_in(tmp_path: Path) -> None:
    mission_file = tmp_path / "toy_grasp.yaml"
    mission_file.write_text(GRASP)
    mission = load_mission(str(mission_file))
    camp = Campaign.create(tmp_path / "batch", CampaignSpec(mission=str(mission_file), trials=6, keep_runs=True))
    for seed in camp.spec.seeds():  # half the runs are cut while grasping (at 0.5 s: approach takes 0.25 s)
        result = drive(mission, _script(seed, markov_fate), max_time=0.5 if seed % 2 else None,
                       out_dir=camp.run_dir(0, seed))
        camp.record(0, seed, result.summary, {})
    (cond,) = predict(mission, camp.root, samples=200).conditions
    timeout = {o.outcome: o for o in cond.outcomes}["timeout"]
    assert (timeout.k, timeout.n) == (3, 6) and timeout.predicted == pytest.approx(0.5, abs=1e-6)
    grasp = next(s for s in cond.states if s.configuration == "grasp")
    assert grasp.successors["timeout"] == 3
    t = {x.outcome: x for x in cond.times}["timeout"]
    # every cut run spent 0.5 s; the chain, which has no clock, lets a run slip and recover before its cut
    assert t.measured == pytest.approx(0.5) and t.predicted is not None and t.predicted > 0.55


def _settled(s: ScriptState) -> dict[str, float]:
    """Every error small once a state has run 0.3 s (each guard of the two missions below holds then)."""
    e = 0.0 if s.time_in_state > 0.3 else 1.0
    return {"pos_error": e, "camera_error.t": e, "camera_error.r": e, "ee_error.t": e, "ee_error.r": e,
            "joint_error": e, "tool_force": 0.0, "marker_age": 0.0, "target_seen": 1.0}  # searching resumes on it


@pytest.mark.parametrize("mission_file, script", [
    (ROOT / "tests" / "machine" / "missions" / "toy_full.yaml",
     Script(metrics=_settled, events=[(2.1, "target_lost"), (2.6, "target_found")],
            actions={"tool": (0.2, "tool_done")})),
    (ROOT / "missions" / "screw_fastening_trolley.yaml",
     Script(metrics=_settled, events=[(0.05, "target_found"), (4.0, "target_lost"), (4.5, "target_found")],
            actions={"screwdriver": lambda p: (0.2, "tool_activated") if p["phase"] == "activate"
                     else (0.5, "screw_done")})),
])
def test_the_configurations_are_the_engines_active_leaves_at_every_step(tmp_path: Path, mission_file: Path,
                                                                        script: Script) -> None:
    """The independent oracle: ``trace.csv``'s state column, the engine's active leaves each tick (``|`` between
    regions), through a run with regions, history resumed inside a ``foreach`` and the next items."""
    mission = load_mission(str(mission_file))
    result = drive(mission, script, out_dir=tmp_path / "run")
    assert result.outcome == "succeeded"
    from taskflow.readers.run_files import read_trace, read_transitions

    records = [r for r, _, _ in read_transitions(tmp_path / "run") if isinstance(r, TransitionRecord)]
    assert any(r.resumed for r in records) and any(r.cause == "next_item" for r in records)
    c: Configuration | None = None
    ours, labels = [], []
    for k, rec in enumerate(records):
        c = configuration_of(mission, c, rec)
        labels.append(c.label)
        if k + 1 == len(records) or records[k + 1].t > rec.t + 1e-9:
            ours.append("|".join(c.leaves))
    trace = [str(s) for s in read_trace(tmp_path / "run")["state"]]
    engine = [s for i, s in enumerate(trace) if i == 0 or s != trace[i - 1]]
    assert ours[: len(engine)] == engine and len(ours) - len(engine) <= 1  # the final leaf may have no trace row
    lost = next(k for k, r in enumerate(records) if r.event == "target_lost")
    back = next(k for k, r in enumerate(records) if r.resumed)
    assert labels[lost - 1] == labels[back] and "item 2, 2 ok" in labels[back]  # history resumes the item …
    assert "item 2, 2 ok" in labels[lost] and "→" in labels[lost]  # … and the search remembers it
    assert labels[back] in [s for s, _ in read_run(mission, tmp_path / "run", 0, result.summary).steps]


def test_a_large_chain_s_sparse_posterior_equals_the_dense_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past ``DENSE_MAX`` configurations the posterior is solved sample by sample on sparse matrices (the dense
    batch took 2 minutes and 1 GB for a 141-configuration trolley campaign): the same draws, the same solution —
    probabilities, unseen mass and expected times — to rounding, on a random chain with cycles, both outcomes and
    a configuration from which one outcome cannot be reached (its times NaN in both)."""
    import random

    from taskflow.verify import campaign as cp

    rnd = random.Random(5)
    n = cp.DENSE_MAX + 20
    counts: dict[int, dict[int, int]] = {}
    times: dict[int, dict[int, list[float]]] = {}
    for i in range(n):
        succ = {rnd.randrange(n + 2) for _ in range(rnd.randint(1, 3))} | {min(i + 1, n)}  # forward, so it ends
        if i == n - 1:
            succ = {n}  # only the first outcome from the last configuration
        counts[i] = {j: rnd.randint(1, 5) for j in succ}
        times[i] = {j: [rnd.uniform(0.1, 2.0) for _ in range(c)] for j, c in counts[i].items()}
    chain = cp.Chain([f"c{i}" for i in range(n)], ["failed", "succeeded"], counts, times)
    sparse = cp.sample_posterior(chain, 50, seed=3)
    monkeypatch.setattr(cp, "DENSE_MAX", 10**6)
    dense = cp.sample_posterior(chain, 50, seed=3)
    assert np.allclose(sparse.h, dense.h, atol=1e-12) and np.allclose(sparse.unseen, dense.unseen, atol=1e-12)
    assert np.array_equal(np.isnan(sparse.t), np.isnan(dense.t)) and np.isnan(dense.t).any()
    assert np.allclose(np.nan_to_num(sparse.t), np.nan_to_num(dense.t), atol=1e-9)
    assert np.allclose(sparse.h.sum(axis=-1), 1.0)  # every configuration ends in some outcome
