"""Every feature of the machine, each on a small mission, through the real loader and executor.

Most tests drive the machine with a :class:`taskflow.testing.Script`; a few run the toy world and
task (real code paths: task stepping, profiles, actions, blend) to check behaviour end to end.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from taskflow.execution.blends import blend_weight
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission, load_mission_text
from taskflow.testing import Script, assert_outcome, assert_path, drive, time_in

HERE = Path(__file__).parent
FULL = HERE / "missions" / "toy_full.yaml"

HEAD = """
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
parameters:
  goals: [1.0, 2.0, 3.0]
  tol: 1 cm
"""
PROFILES = """profiles:
  gains: {slow: {kp: 1.0}, fast: {kp: 4.0}}
"""


def mission(machine: str, head: str = HEAD):  # type: ignore[no-untyped-def]
    """A mission from the common head; the gain profiles are added when the machine binds them
    (an unused profile kind is itself a load error)."""
    return load_mission_text(head + (PROFILES if "bind:" in machine else "") + machine, "test.yaml")


def transitions_of(result):  # type: ignore[no-untyped-def]
    return [(round(r.t, 6), r.source, r.target) for r in result.executor.transitions_fired]


# -- nesting and initial states --------------------------------------------------------------------


def test_nested_initial_chain_is_entered():
    m = mission("""
machine:
  initial: a
  states:
    a:
      initial: b
      transitions: [{to: z, after: 1 s}]
      states:
        b:
          initial: c
          states:
            c: {transitions: [{to: d, after: 0.25 s}]}
            d: {transitions: [{to: c, after: 10 s}]}
    z: {final: succeeded}
""")
    r = drive(m, Script())
    assert_outcome(r, "succeeded")
    assert_path(r, ["a.b.c", "a.b.d", "z"])
    # the parent's `after` counts from entering `a`, not from entering the leaf
    assert transitions_of(r)[-1] == (1.0, "a.b.d", "z")


# -- guards with units and dwell ---------------------------------------------------------------


def test_guard_units_convert_and_dwell_waits():
    m = mission("""
machine:
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions: [{to: ok, when: "pos_error < 2 cm and feature_error < 3 px", for: 0.5 s}]
    ok: {final: succeeded}
""")
    # pos_error crosses 2 cm at 0.9 s (1.5 cm), feature_error ≥ 3 px until 1.0 s, then both hold
    def metrics(s):  # type: ignore[no-untyped-def]
        return {"pos_error": 0.02 - 0.005 * (s.t > 0.85), "feature_error": 5.0 if s.t < 1.0 else 1.0}

    r = drive(m, Script(metrics=metrics))
    assert transitions_of(r)[-1][0] == pytest.approx(1.5)


def test_dwell_restarts_when_the_guard_breaks():
    m = mission("""
machine:
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions: [{to: ok, when: "pos_error < 1 cm", for: 0.3 s}]
    ok: {final: succeeded}
""")
    # true 0.0–0.2, false at 0.25, true again from 0.3 → fires at 0.6
    r = drive(m, Script(metrics=lambda s: {"pos_error": 0.05 if abs(s.t - 0.25) < 1e-6 else 0.0}))
    assert transitions_of(r)[-1][0] == pytest.approx(0.6)


def test_missing_metric_never_satisfies_a_guard():
    m = mission("""
machine:
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: slow}
      transitions:
        - {to: ok, when: "pos_error < 1 m"}
        - {to: bad, after: 2 s}
    ok: {final: succeeded}
    bad: {final: failed}
""")
    r = drive(m, Script(metrics=lambda s: {}))
    assert_outcome(r, "failed")


# -- after, events, outer-first priority -----------------------------------------------------------------


def test_event_preempts_guard_in_same_tick():
    m = mission("""
machine:
  initial: op
  states:
    op:
      initial: work
      transitions:
        - {to: lost, on: target_lost}
        - {to: ok, done: true}
      states:
        work:
          task: {name: toy_goto, params: {target: 1.0}}
          bind: {gains: slow}
          transitions: [{to: fin, when: "pos_error < 1 cm"}]
        fin: {final: succeeded}
    lost: {transitions: [{to: op, on: target_found}, {to: failed, after: 1 s}]}
    failed: {final: failed}
    ok: {final: succeeded}
""")
    r = drive(m, Script(metrics=lambda s: {"pos_error": 0.0 if s.t >= 0.5 else 1.0}, events=[(0.5, "target_lost")]))
    assert_outcome(r, "failed")
    assert_path(r, ["op.work", "lost", "failed"])
    assert time_in(r, "lost") == pytest.approx(1.0)


# -- sub-machine completion --------------------------------------------------------------------


DONE = """
machine:
  initial: op
  states:
    op:
      initial: a
      transitions:
        - {to: good, done: succeeded}
        - {to: bad, done: failed}
      states:
        a: {transitions: [{to: yes, when: "pos_error < 1 m"}, {to: no, after: 1 s}]}
        yes: {final: succeeded}
        no: {final: failed}
    good: {final: succeeded}
    bad: {final: aborted}
"""


@pytest.mark.parametrize("error,path,outcome", [(0.0, ["op.a", "op.yes", "good"], "succeeded"),
                                                (5.0, ["op.a", "op.no", "bad"], "aborted")])
def test_done_transition_matches_the_outcome(error, path, outcome):
    m = mission(DONE.replace("      initial: a\n", "      initial: a\n      task: {name: toy_goto, params: {target: 0.0}}\n"
                             "      bind: {gains: slow}\n", 1))
    r = drive(m, Script(metrics=lambda s: {"pos_error": error}))
    assert_path(r, path)
    assert_outcome(r, outcome)


# -- history -------------------------------------------------------------------------------


def test_history_resumes_the_interrupted_substate_and_foreach_item():
    m = load_mission(FULL)
    # lose the target while approaching the second goal, find it again 1 s later
    script = Script(
        metrics=lambda s: {"pos_error": 0.0 if s.time_in_state > 0.5 else 1.0},
        events=[(2.0, "target_lost"), (3.0, "target_found")],
        actions={"tool": (0.25, "tool_done")},
    )
    r = drive(m, script)
    assert_outcome(r, "succeeded")
    path = r.summary["states_visited"]
    i = path.index("searching")
    assert path[i - 1] == path[i + 1], "resumed a different sub-state"
    # three goals visited exactly once each, despite the interruption
    assert [it["item"] for it in r.summary["iterations"]] == [1.0, 2.0, 3.0]


def test_resume_false_restarts_the_submachine():
    m = load_mission(FULL, overrides=["machine.states.searching.transitions.0.resume=false"])
    script = Script(
        metrics=lambda s: {"pos_error": 0.0 if s.time_in_state > 0.5 else 1.0},
        events=[(2.0, "target_lost"), (3.0, "target_found")],
        actions={"tool": (0.25, "tool_done")},
    )
    r = drive(m, script)
    items = [it["item"] for it in r.summary["iterations"]]
    assert items[0] == 1.0 and items.count(1.0) == 2, "a fresh entry starts the loop again"


def test_searching_timeout_goes_to_error():
    m = load_mission(FULL)
    r = drive(m, Script(metrics=lambda s: {"pos_error": 1.0}, events=[(1.0, "target_lost")]))
    assert_outcome(r, "failed")
    assert r.summary["final_state"] == "error"
    assert time_in(r, "searching") == pytest.approx(3.0)


# -- foreach --------------------------------------------------------------------------------


def test_foreach_exposes_each_item_to_the_task_in_order():
    m = load_mission(FULL)
    r = run_mission(m, record=False)
    assert_outcome(r, "succeeded")
    entries = r.executor.memory["toy.entries"]
    # approach and settle both run toy_goto with $goal; home runs with target 0
    assert entries == [1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 0.0]
    assert [it["outcome"] for it in r.summary["iterations"]] == ["succeeded"] * 3


def test_foreach_failure_stops_or_continues():
    stop = load_mission(FULL, overrides=["world.params.tool_ok=false"])
    r = run_mission(stop, record=False)
    assert_outcome(r, "failed")
    assert [it["outcome"] for it in r.summary["iterations"]] == ["failed"]
    # continue: every item is tried; the loop's rule (default: all items) then fails the loop
    cont = load_mission(FULL, overrides=["world.params.tool_ok=false",
                                         "machine.states.operate.states.visit.foreach.on_failure=continue"])
    r = run_mission(cont, record=False)
    assert_outcome(r, "failed")
    assert [it["outcome"] for it in r.summary["iterations"]] == ["failed"] * 3
    assert r.summary["items"]["operate.visit"] == {"attempted": 3, "succeeded": 0, "failed": 3, "success_rate": 0.0,
                                                   "required": 3, "rule": "all"}
    assert "0 of 3 items succeeded" in r.summary["reason"]


# -- asynchronous action -----------------------------------------------------------------------


def test_action_starts_on_entry_and_its_event_ends_the_state():
    m = load_mission(FULL)
    r = run_mission(m, record=False)
    settle = [k for k in r.summary["states_visited"] if k.endswith("settle")]
    assert len(settle) == 3
    # the toy tool takes 0.5 s: each settle lasts exactly that long
    assert time_in(r, "operate.visit.settle") == pytest.approx(1.5)


def test_action_is_cancelled_when_its_state_is_left_early():
    m = load_mission(FULL)
    script = Script(metrics=lambda s: {"pos_error": 0.0}, events=[(1.5, "target_lost"), (2.0, "target_found")],
                    actions={"tool": (5.0, "tool_done")})
    worlds = []
    r = drive(m, script, max_time=4.0, on_world=worlds.append)
    world = worlds[0]
    # settle is entered at 0.5 + 0.2 s (dwell), the tool started, then cancelled by target_lost at 1.5 s
    assert [name for _, name, _ in world.started][:1] == ["tool"]
    assert world.cancelled and world.cancelled[0] == (pytest.approx(1.5), "tool")
    assert r.outcome == "timeout"  # the slow tool never finishes within 4 s


# -- outcomes and timeout ------------------------------------------------------------------------------


@pytest.mark.parametrize("outcome", ["succeeded", "failed", "aborted"])
def test_final_outcomes(outcome):
    m = mission(f"""
machine:
  initial: a
  states:
    a: {{transitions: [{{to: z, after: 0.1 s}}]}}
    z: {{final: {outcome}}}
""")
    r = drive(m, Script())
    assert r.outcome == outcome


def test_timeout_outcome_and_safe_stop():
    m = mission("""
machine:
  initial: a
  states:
    a:
      task: {name: toy_goto, params: {target: 100.0}}
      bind: {gains: fast}
      transitions: [{to: z, when: "pos_error < 1 cm"}]
    z: {final: succeeded}
""")
    r = run_mission(m, record=False, max_time=2.0)
    assert r.outcome == "timeout"
    assert r.summary["sim_time_s"] == pytest.approx(2.0)


# -- blend -------------------------------------------------------------------------------------


def test_blend_weight_is_the_papers_h():
    assert blend_weight(0.0, 1.0) == 0.0
    assert blend_weight(1.0, 1.0) == 1.0
    assert blend_weight(0.5, 1.0) == pytest.approx(0.5)
    ts = np.linspace(0, 1, 101)
    hs = np.array([blend_weight(t, 1.0) for t in ts])
    assert np.all(np.diff(hs) >= 0)
    assert hs[25] == pytest.approx(0.5 * (1 - math.cos(math.pi * 0.25)))


def test_blend_mixes_outgoing_into_incoming_command():
    text = """
machine:
  initial: a
  states:
    a:
      task: {name: toy_goto, params: {target: 10.0}}
      bind: {gains: slow}
      transitions: [{to: b, after: 1 s, BLEND}]
    b:
      task: {name: toy_goto, params: {target: -10.0}}
      bind: {gains: slow}
      transitions: [{to: z, after: 1 s}]
    z: {final: succeeded}
"""
    def commands(blend: str) -> np.ndarray:
        m = mission(text.replace(", BLEND", blend))
        log: list[float] = []
        world_cls = m.world_cls

        class Spy(world_cls):  # type: ignore[misc, valid-type]
            def apply(self, command):  # type: ignore[no-untyped-def]
                log.append(float(command["v"][0]))
                super().apply(command)

        robot = m.build_robot()
        run_mission(m, world=Spy(robot, m.world_params(0), 0), record=False)
        return np.array(log)

    hard = commands("")
    soft = commands(", blend: 0.5 s")
    k = 21  # first tick of `b`: the switch fires at t = 1.0 s after `a`'s command of that tick
    assert hard[k] < 0 < hard[k - 1]  # without blend the command flips at once
    jumps_hard = np.abs(np.diff(hard[k - 1:k + 12])).max()
    jumps_soft = np.abs(np.diff(soft[k - 1:k + 12])).max()
    assert jumps_soft < 0.4 * jumps_hard
    h = blend_weight(0.05, 0.5)  # τ = one tick after the switch
    assert soft[k] == pytest.approx(h * hard[k] + (1 - h) * hard[k - 1], rel=0.05)
    assert soft[k + 9] == pytest.approx(hard[k + 9], rel=0.05)  # τ = 0.5 s: fully incoming


# -- profiles --------------------------------------------------------------------------------------


def test_profiles_inherit_and_override():
    m = load_mission(FULL)
    approach = m.states["operate.visit.approach"]
    settle = m.states["operate.visit.settle"]
    assert approach.profiles["gains"].kp == 4.0  # own bind
    assert settle.profiles["gains"].kp == 1.0  # inherited from `operate`


# -- determinism ---------------------------------------------------------------------------------


def test_same_seed_same_trace(tmp_path):
    m = load_mission(FULL, overrides=["world.params.noise=0.001"])
    a = run_mission(m, seed=7, out_dir=tmp_path / "a")
    b = run_mission(m, seed=7, out_dir=tmp_path / "b")
    c = run_mission(m, seed=8, out_dir=tmp_path / "c")
    ta = (tmp_path / "a" / "trace.csv").read_bytes()
    assert ta == (tmp_path / "b" / "trace.csv").read_bytes()
    assert ta != (tmp_path / "c" / "trace.csv").read_bytes()
    assert a.summary["states_visited"] == b.summary["states_visited"]
    del c
