"""Statechart semantics where features cross: blends in parallel regions, history with self-transitions
and operator re-entry, and guards reading a sibling region's metrics — through the real loader, engine and
executor (toy world and tasks, or the scripted backend)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from taskflow.api import Observation, StepResult, Task, TaskContext
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission_text
from taskflow.shaping import activation
from taskflow.testing import Script, ScriptedWorld, drive

HEAD = """
mission: cross
robot: ROBOT
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
"""


def mission(machine: str, robot: str = "toy_point"):  # type: ignore[no-untyped-def]
    profiles = "profiles: {gains: {g: {kp: 1.0}}}\n" if "gains: g" in machine else ""
    return load_mission_text(HEAD.replace("ROBOT", robot) + profiles + machine, "cross.yaml")


# -- 1. blends per region -------------------------------------------------------------------------

class _Const(Task):
    """Commands ``v = w = value``, whatever it observes: toy_goto's ``target``; toy_watch (no parameters)
    10 when entered at the start, 20 later."""

    def __init__(self, ctx: TaskContext) -> None:
        super().__init__(ctx)
        target = getattr(ctx.params, "target", None)
        self.value = float(target) if target is not None else 10.0 if ctx.t == 0.0 else 20.0

    def step(self, obs: Observation) -> StepResult:
        return StepResult({"v": np.array([self.value]), "w": np.array([self.value])},
                          {"pos_error": 1.0, "feature_error": 0.0, "yaw_error": 0.0})


def _goto(target: float) -> str:
    return f"{{name: toy_goto, params: {{target: {target}}}}}"


BLENDS = f"""
machine:
  initial: both
  states:
    both:
      regions:
        a:
          owns: [v]
          initial: a1
          states:
            a1: {{task: {_goto(1.0)}, bind: {{gains: g}}, transitions: [{{to: a2, after: 1 s, blend: 1 s}}]}}
            a2: {{task: {_goto(3.0)}, bind: {{gains: g}}, transitions: [{{to: a_end, after: 9 s}}]}}
            a_end: {{final: true}}
        b:
          owns: [w]
          initial: b1
          states:
            b1: {{task: toy_watch, transitions: [{{to: b2, after: 1.5 s, blend: 1 s}}]}}
            b2: {{task: toy_watch, transitions: [{{to: b_end, after: 9 s}}]}}
            b_end: {{final: true}}
      transitions: [{{to: fin, done: true}}]
    fin: {{final: true}}
"""


def test_two_regions_blending_at_overlapping_times_each_follow_their_own_blend():
    m = mission(BLENDS, robot="toy_pair")
    world = ScriptedWorld(m.build_robot(), Script(), m)
    r = run_mission(m, world=world, task_factory=lambda cls, ctx: _Const(ctx), record=False, max_time=3.0,
                    safe_stop_s=0.0)
    assert [(round(rec.t, 3), rec.target) for rec in r.executor.transitions_fired[1:]] == [
        (1.0, "both.a.a2"), (1.5, "both.b.b2")]
    applied = world.applied[:60]  # one command per tick of 50 ms, from t = 0
    assert len(applied) == 60
    for k, cmd in enumerate(applied):
        t = k / 20
        h_a, h_b = activation(t - 1.0, 1.0), activation(t - 1.5, 1.0)
        v = 1.0 if t < 1.0 else h_a * 3.0 + (1.0 - h_a) * 1.0
        w = 10.0 if t < 1.5 else h_b * 20.0 + (1.0 - h_b) * 10.0
        assert float(cmd["v"][0]) == pytest.approx(v, abs=1e-12), f"v at t={t}"
        assert float(cmd["w"][0]) == pytest.approx(w, abs=1e-12), f"w at t={t}"


# -- 2. history: exit first, then resolve it ---------------------------------------------------------

HISTORY = """
machine:
  initial: h
  states:
    h:
      history: true
      initial: a
      transitions:
        - {to: h, on: target_lost}
        - {to: away, on: target_found}
        - {to: end, done: true}
      states:
        a: {transitions: [{to: b, after: 1 s}]}
        b: {transitions: [{to: c, after: 1 s}]}
        c: {transitions: [{to: fin, after: 10 s}]}
        fin: {final: true}
    away: {transitions: [{to: h, after: 0.5 s, resume: false}]}
    end: {final: true}
"""


def _fired(r: Any) -> list[tuple[float, str, str, bool]]:
    return [(round(rec.t, 3), rec.target, rec.cause, rec.resumed) for rec in r.executor.transitions_fired]


def test_a_history_self_transition_after_a_fresh_entry_resumes_the_leaf_it_leaves():
    # h is left in b (history b), entered afresh at a (resume: false), then its self-transition fires in a:
    # the exit records a, and the re-entry resumes a — not b, the history of the earlier exit
    r = drive(mission(HISTORY), Script(events=[(1.5, "target_found"), (2.5, "target_lost")]), max_time=4.0)
    assert _fired(r)[1:] == [(1.0, "h.b", "timeout", False), (1.5, "away", "event", False),
                             (2.0, "h.a", "timeout", False), (2.5, "h.a", "event", True),
                             (3.5, "h.b", "timeout", False)]  # h.a re-entered at 2.5: its `after 1 s` restarts
    assert r.executor.history["h"] == "h.a"


def test_a_history_self_transition_on_the_first_entry_resumes_the_active_leaf():
    r = drive(mission(HISTORY), Script(events=[(1.5, "target_lost")]), max_time=2.0)
    assert _fired(r)[1:] == [(1.0, "h.b", "timeout", False), (1.5, "h.b", "event", True)]
    assert r.executor.entered_at(r.executor.mission.states["h.b"]) == 1.5


def test_an_operator_preempt_into_the_active_history_state_resumes_where_it_is():
    from taskflow.execution.control import OperatorAction

    r = drive(mission(HISTORY), Script(events=[(1.5, "target_found")]), max_time=4.0,
              operator=[OperatorAction(t=2.5, action="preempt", args={"to": "h"})])
    assert [(t, tgt, res) for t, tgt, _, res in _fired(r)][1:] == [
        (1.0, "h.b", False), (1.5, "away", False), (2.0, "h.a", False), (2.5, "h.a", True), (3.5, "h.b", False)]
    assert r.executor.transitions_fired[4].cause == "operator"


def test_a_done_transition_into_its_own_history_state_starts_it_afresh():
    # the history as the exit leaves it is the final leaf: resuming it would finish h again, forever
    text = HISTORY.replace("- {to: end, done: true}", "- {to: h, done: true}").replace(
        "c: {transitions: [{to: fin, after: 10 s}]}", "c: {transitions: [{to: fin, after: 0.5 s}]}").replace(
        "        - {to: away, on: target_found}\n",
        "        - {to: away, on: target_found}\n        - {to: end, after: 3 s}\n")
    r = drive(mission(text), Script(), max_time=4.0)
    assert _fired(r)[1:5] == [(1.0, "h.b", "timeout", False), (2.0, "h.c", "timeout", False),
                              (2.5, "h.fin", "timeout", False), (2.5, "h.a", "done", False)]


# -- 3. a guard in one region reads what a sibling region's task publishes --------------------------

SIBLING = """
machine:
  initial: both
  states:
    both:
      regions:
        a:
          owns: [v]
          initial: go
          states:
            go:
              task: {name: toy_goto, params: {target: 1.0}}
              bind: {gains: g}
              transitions: [{to: a_end, when: "x_abs > 0.5 m"}]   # x_abs: toy_watch's, in region b
            a_end: {final: succeeded}
        b:
          initial: look
          states:
            look:
              task: toy_watch
              transitions: [{to: b_end, after: LOOK_FOR}]
            b_end: {final: succeeded}
      transitions: [{to: done, done: succeeded}]
    done: {final: succeeded}
"""


def test_a_guard_fires_on_a_sibling_regions_metric_on_the_scripted_backend():
    m = mission(SIBLING.replace("LOOK_FOR", "10 s"))
    script = Script(metrics=lambda s: {"x_abs": 0.25 * s.t} if "both.b.look" in s.state else {})
    r = drive(m, script, max_time=5.0)
    first = r.executor.transitions_fired[1]
    assert (round(first.t, 3), first.source, first.target, first.cause) == (2.05, "both.a.go", "both.a.a_end", "guard")
    assert first.metrics == {"x_abs": pytest.approx(0.5125)}


def test_a_guard_reads_the_sibling_tasks_metric_of_the_same_tick_on_the_toy_loop():
    # the real loop: every region's task steps before any guard is checked, so region a's guard reads the
    # x_abs that toy_watch computed from this tick's observation
    m = mission(SIBLING.replace("LOOK_FOR", "10 s"))
    r = run_mission(m, record=False, max_time=5.0)
    first = r.executor.transitions_fired[1]
    assert first.target == "both.a.a_end"
    x_at = 1.0 - np.exp(-first.t)  # toy_goto's P law from 0 towards 1 m with kp = 1 (world integrates exactly)
    assert first.metrics["x_abs"] > 0.5 and x_at == pytest.approx(first.metrics["x_abs"], abs=0.01)
    assert first.t == pytest.approx(np.log(2.0), abs=0.06)


def test_a_sibling_metric_not_published_on_a_tick_compares_false():
    # region b leaves toy_watch at 0.3 s (x ≈ 0.26 m): x_abs is published by no active task afterwards,
    # so region a's guard never holds although the robot passes 0.5 m
    m = mission(SIBLING.replace("LOOK_FOR", "0.3 s"))
    r = run_mission(m, record=False, max_time=3.0)
    assert r.outcome == "timeout" and r.executor.state == "both.a.go|both.b.b_end"
    assert r.executor.world.ground_truth()["x"] > 0.9


# -- found by the oracle (tests/execution/test_properties_regions.py): a region moves while the last region is final ---------

def test_a_region_moves_on_while_the_last_region_has_finished():
    # `transitions` 0.9.3's own final-state check took region b's final state for the parallel state's and
    # raised AttributeError ('scoped_enter'): the run aborted at 1 s
    m = mission("""
machine:
  initial: both
  states:
    both:
      regions:
        a:
          initial: a1
          states:
            a1: {transitions: [{to: a2, after: 1 s}]}
            a2: {transitions: [{to: a_end, after: 1 s}]}
            a_end: {final: true}
        b:
          initial: b1
          states:
            b1: {transitions: [{to: b_end, after: 0.5 s}]}
            b_end: {final: true}
      transitions: [{to: fin, done: true}]
    fin: {final: true}
""")
    r = drive(m, Script(), max_time=5.0)
    assert r.outcome == "succeeded", r.summary["reason"]
    assert _fired(r)[1:] == [(0.5, "both.b.b_end", "timeout", False), (1.0, "both.a.a2", "timeout", False),
                             (2.0, "both.a.a_end", "timeout", False), (2.0, "fin", "done", False)]
