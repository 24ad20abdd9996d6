"""Property-based tests of the loader and the executor (hypothesis).

1. Random *valid* nested machines (depth <= 3, 1-4 children per composite, after/on/when
   transitions over the toy metrics and events, foreach, history, actions, final states with random
   outcomes) are driven by :func:`taskflow.testing.drive` with a random :class:`Script` (metrics a
   seeded function of the tick, events at random ticks).  Every run keeps the executor's invariants:
   one active leaf at each transition record; each fired transition is a declared one whose source
   is an ancestor-or-self of the leaf it leaves and whose target contains the leaf it enters; its
   trigger really held (guards re-checked by an independent Python oracle, over the whole `for:`
   dwell; `after` timers; events) and no transition checked before it (outer first) was due; the
   run ends with a proper outcome in a final state (or at max_time), and the `transitions` machine
   agrees with the executor about the active state.
   Two executor bugs found this way are pinned by deterministic strict-xfail tests below.
2. Random machines with *parallel regions, blends and history composites* (self-transitions,
   transitions from inside a composite to it, `resume: false` entries, region finals and
   `outcome_map`) run on the scripted backend with a constant command per leaf, side by side with
   :class:`_Oracle`, a small separate implementation of the documented semantics that reads only the
   generated document: both agree on every tick's active leaves, entry clocks, history, command
   (each region's parts and blends) and outcome, and on the transitions fired.  It found the engine
   bug pinned by tests/machine/test_crossing.py::test_a_region_moves_on_while_the_last_region_has_finished.
2b. The machines of 1 with a random *operator script* (pause, hold, resume, pre-empt, abort, inject) against
   an independent tick-by-tick oracle (`_OperatedOracle`, at the end of the file): every tick's active
   leaf, every transition, the entry and operating clocks (hold does not count toward `after`/`for`),
   history, the outcome (a pre-emption past a loop's rule cannot succeed), `preempted` and `held_s`.
3. Random *mutations* of a valid mission (keys deleted or renamed, values replaced, junk text
   inserted) never make :func:`load_mission_text` raise anything but :class:`MissionError`.
"""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st

from taskflow.api import Observation, StepResult, Task, TaskContext
from taskflow.errors import MissionError
from taskflow.execution.executor import CAUSES
from taskflow.execution.runtime import run_mission
from taskflow.execution.summary import OUTCOMES
from taskflow.mission.loader import load_mission_text
from taskflow.mission.model import (
    CompiledMission,
    DoneTransition,
    EventTransition,
    GuardTransition,
    StateNode,
    TimeoutTransition,
)
from taskflow.mission.yamlsrc import MissionLoader
from taskflow.testing import Script, ScriptedWorld, drive

TOY = Path(__file__).parents[1] / "machine" / "missions" / "toy_full.yaml"
RATE_HZ = 20
MAX_TIME = 12.0
EVENTS = ["target_lost", "target_found", "arrived", "tool_done", "tool_failed"]
TOL = 0.04  # the `tol` parameter (4 cm)
# every guard the generator uses, with an independent Python oracle over base-unit metrics
GUARDS: dict[str, Any] = {
    "pos_error < 5 cm": lambda m: m["pos_error"] < 0.05,
    "pos_error >= 0.15 m": lambda m: m["pos_error"] >= 0.15,
    "feature_error > 20 px": lambda m: m["feature_error"] > 20,
    "abs(yaw_error) < 3 deg": lambda m: abs(m["yaw_error"]) < math.radians(3),
    "yaw_error <= -0.1 rad": lambda m: m["yaw_error"] <= -0.1,
    "visible < 50 %": lambda m: m["visible"] < 0.5,
    "visible == 1": lambda m: m["visible"] == 1,
    "pos_error < $tol": lambda m: m["pos_error"] < TOL,
    "not (feature_error > 10 px) or visible != 1": lambda m: not m["feature_error"] > 10 or m["visible"] != 1,
    "(pos_error < 8 cm and abs(yaw_error) < 0.1 rad) or feature_error < 2 px":
        lambda m: (m["pos_error"] < 0.08 and abs(m["yaw_error"]) < 0.1) or m["feature_error"] < 2,
}


# -- generating valid machines ------------------------------------------------------------------------


class _Gen:
    """Builds one machine from hypothesis draws; every state gets a globally unique name."""

    def __init__(self, draw: Any) -> None:
        self.draw = draw
        self.k = 0
        self.items = 0
        self.paths: list[str] = []  # every state path, for random extra transitions
        self.pending: list[dict[str, Any]] = []  # transitions whose target is chosen at the end

    def name(self, prefix: str) -> str:
        self.k += 1
        return f"{prefix}{self.k}"

    def trigger(self, slow: bool = False) -> dict[str, Any]:
        """A random trigger; ``slow`` ones (on composites, into root finals) give inner states time."""
        if slow:
            if self.draw(st.booleans()):
                return {"after": f"{self.draw(st.integers(1, 5))} s"}
            return {"on": self.draw(st.sampled_from(EVENTS))}
        kind = self.draw(st.sampled_from(["after", "on", "when", "when"]))
        if kind == "after":
            return {"after": f"{self.draw(st.integers(1, 40)) * 50} ms"}
        if kind == "on":
            return {"on": self.draw(st.sampled_from(EVENTS))}
        tr: dict[str, Any] = {"when": self.draw(st.sampled_from(sorted(GUARDS)))}
        if self.draw(st.booleans()):
            tr["for"] = f"{self.draw(st.integers(1, 10)) * 0.05:.2f} s"
        return tr

    def transition(self, to: str, slow: bool = False) -> dict[str, Any]:
        tr = {"to": to, **self.trigger(slow)}
        if self.draw(st.integers(0, 5)) == 0:
            tr["resume"] = False
        if self.draw(st.integers(0, 5)) == 0:
            tr["blend"] = "0.2 s"
        return tr

    def extra(self, state: dict[str, Any], slow: bool) -> None:
        """0-2 transitions to any state of the machine (chosen once all states exist)."""
        for _ in range(self.draw(st.integers(0, 2))):
            tr = self.transition("?", slow)
            state.setdefault("transitions", []).append(tr)
            self.pending.append(tr)

    def children(self, path: str, depth: int, in_foreach: list[str]) -> tuple[dict[str, Any], str]:
        """The ``states`` mapping of a machine/composite at ``path`` and its initial state."""
        n_work = self.draw(st.integers(1, 3))
        n_final = self.draw(st.integers(1, 4 - n_work if n_work < 3 else 1))  # 2-4 children
        work = [self.name("s") for _ in range(n_work)]
        finals = [self.name("f") for _ in range(n_final)]
        full = lambda nm: f"{path}.{nm}" if path else nm
        states: dict[str, Any] = {}
        order = work + finals
        for i, nm in enumerate(work):
            self.paths.append(full(nm))
            composite = depth < 3 and self.draw(st.integers(0, depth)) == 0
            st_: dict[str, Any] = {}
            if composite:
                # its `done` transition leads to the next sibling (filled in by `machines`)
                st_ = self.composite(full(nm), depth + 1, in_foreach)
            else:
                if in_foreach and self.draw(st.booleans()):
                    st_["task"] = {"name": "toy_goto", "params": {"target": "$" + in_foreach[-1]}}
                if self.draw(st.integers(0, 4)) == 0:
                    st_["action"] = {"name": "tool"}
                # chain to the next sibling: every state is reachable, every leaf has a way out
                into_root_final = depth == 1 and i + 1 >= len(work)
                st_["transitions"] = [self.transition(full(order[i + 1]), slow=into_root_final)]
            self.extra(st_, slow=composite and self.draw(st.booleans()))
            states[nm] = st_
        # finals beyond the first are reached from a random working sibling
        for nm in finals[1:]:
            src = self.draw(st.sampled_from(work))
            states[src]["transitions"].append(self.transition(full(nm), slow=depth == 1 or "states" in states[src]))
        for nm in finals:
            self.paths.append(full(nm))
            states[nm] = {"final": self.draw(st.sampled_from([True, "succeeded", "failed", "aborted"]))}
        return states, work[0]

    def composite(self, path: str, depth: int, in_foreach: list[str]) -> dict[str, Any]:
        st_: dict[str, Any] = {}
        if self.draw(st.booleans()):
            self.items += 1
            item = f"item{self.items}"
            st_["foreach"] = {"in": "goals", "as": item,
                              "on_failure": self.draw(st.sampled_from(["stop", "continue"]))}
            if st_["foreach"]["on_failure"] == "continue":
                st_["foreach"]["require"] = self.draw(st.sampled_from(["all", 1, "50 %"]))
            in_foreach = [*in_foreach, item]
        if self.draw(st.booleans()):
            st_["history"] = True
        states, initial = self.children(path, depth, in_foreach)
        st_["initial"] = initial
        st_["states"] = states
        # a way to finish, to the next sibling via the chain target: `done: true`, or one `done` per outcome
        # (the loader refuses a composite that can finish with an outcome no `done` handles)
        if self.draw(st.booleans()):
            st_["transitions"] = [{"to": "?done", "done": True}]
        else:
            outcomes = self.draw(st.permutations(["succeeded", "failed", "aborted"]))
            st_["transitions"] = [{"to": "?done", "done": o} for o in outcomes]
        return st_


@st.composite
def machines(draw: Any) -> dict[str, Any]:
    g = _Gen(draw)
    states, initial = g.children("", 1, [])
    # a composite's `done` goes to its next sibling
    def fix(states: dict[str, Any], path: str) -> None:
        names = list(states)
        for i, (nm, s) in enumerate(states.items()):
            for t in s.get("transitions", []):
                if t["to"] == "?done":
                    t["to"] = f"{path}.{names[i + 1]}" if path else names[i + 1]
            fix(s.get("states", {}), f"{path}.{nm}" if path else nm)
    fix(states, "")
    for tr in g.pending:
        tr["to"] = draw(st.sampled_from(g.paths))
    n_goals = draw(st.integers(1, 3))
    return {
        "mission": "prop",
        "robot": "toy_point",
        "world": {"name": "toy_line", "params": {"start": 0.0}},
        "rate_hz": RATE_HZ,
        "max_time": f"{MAX_TIME} s",
        "parameters": {"goals": [float(i + 1) for i in range(n_goals)], "tol": f"{TOL * 100:g} cm"},
        "profiles": {"gains": {"g": {"kp": 1.0}}},
        "machine": {"initial": initial, "task": {"name": "toy_goto", "params": {"target": 0.5}},
                    "bind": {"gains": "g"}, "states": states},
    }


@st.composite
def scripts(draw: Any) -> Script:
    seed = draw(st.integers(0, 2**31 - 1))
    events = draw(st.lists(st.tuples(st.integers(0, int(MAX_TIME * RATE_HZ)).map(lambda k: k / RATE_HZ),
                                     st.sampled_from(EVENTS)), max_size=20))
    tool = (draw(st.sampled_from([0.05, 0.3, 1.0])), draw(st.sampled_from(["tool_done", "tool_failed"])))

    def metrics(s: Any) -> dict[str, float]:  # a function of the tick only, so the checker can replay it
        rng = random.Random(seed * 1_000_003 + round(s.t * RATE_HZ))
        return {"pos_error": rng.uniform(0.0, 0.2), "feature_error": rng.uniform(0.0, 40.0),
                "yaw_error": rng.uniform(-0.2, 0.2), "visible": float(rng.random() < 0.7)}

    return Script(metrics=metrics, events=events, actions={"tool": tool})


# -- invariants ----------------------------------------------------------------------------------------

def _is_under(node: StateNode, ancestor: StateNode) -> bool:
    return ancestor in node.ancestors()


def _metrics_at(script: Script, tick: int) -> dict[str, float]:
    return dict(script.metrics(type("S", (), {"t": tick / RATE_HZ})()))  # type: ignore[arg-type]


def _script_events_at(script: Script, tick: int) -> set[str]:
    """Script events the executor sees at ``tick`` (those due in (t - dt, t]; at t = 0, those due
    at 0 or earlier: test_event_at_time_zero_is_seen)."""
    lo, hi = (tick - 1) / RATE_HZ, tick / RATE_HZ
    return {name for when, name in script.events if lo + 1e-9 < when <= hi + 1e-9}


def _domain_of(tr: Any) -> Any:
    """UML external-transition domain: the common ancestor of source and target, or its parent when
    one contains the other (written here independently of `Transition.domain` in taskflow/mission/model.py)."""
    src, dst = tr.source.ancestors(), tr.target.ancestors()
    common = [a for a, b in zip(src, dst) if a is b][-1]
    if common is tr.source or common is tr.target:
        return common.parent if common.parent is not None else common
    return common


def _loop_outcome(m: CompiledMission, iterations: list[dict[str, Any]], node: StateNode, t: float) -> str:
    """What a foreach loop that finished at ``t`` must finish with, from its iteration records alone: with
    ``on_failure: stop`` the first failed item's outcome; with ``continue`` its ``require`` rule over the
    items of that run (``all``, a count, or a share rounded up)."""
    mine = [it for it in iterations if it["state"] == node.path and it["t_end"] <= t + 1e-9]
    run: list[dict[str, Any]] = []
    for it in mine:  # the run that ended at t: from its last index-0 iteration on
        run = [it] if it["index"] == 0 else run + [it]
    fe = m.spec.machine
    for a in node.ancestors()[1:]:
        fe = fe.states[a.name]
    rule, n = fe.foreach.require, len(m.spec.parameters[fe.foreach.in_])
    if fe.foreach.on_failure == "stop":
        bad = [it["outcome"] for it in run if it["outcome"] != "succeeded"]
        return bad[0] if bad else "succeeded"
    need = n if rule == "all" else rule if isinstance(rule, int) else math.ceil(float(rule.rstrip(" %")) * n / 100)
    return "succeeded" if sum(it["outcome"] == "succeeded" for it in run) >= need else "failed"


def check_run(m: CompiledMission, result: Any, script: Script) -> None:
    ex = result.executor
    recs = ex.transitions_fired
    leaves = {p for p, n in m.states.items() if n.is_leaf}
    assert recs and recs[0].cause == "start" and recs[0].source == "__start__"
    entered: dict[str, float] = {}  # state path -> time it was last entered
    previous = "__start__"
    for rec in recs:
        # exactly one active leaf: each record leaves the leaf the previous one entered
        assert rec.source == previous, f"{rec}: active leaf was {previous!r}"
        assert rec.target in leaves, f"{rec}: {rec.target!r} is not a leaf of the machine"
        previous = rec.target
        tick = round(rec.t * RATE_HZ)
        assert rec.t == pytest.approx(tick / RATE_HZ, abs=1e-9)
        domain: Any = m.root  # the state whose descendants this record exits and enters
        assert rec.cause in CAUSES, rec
        if rec.cause != "start":
            src_leaf = m.states[rec.source]
            src, label = rec.state, rec.label
        if rec.cause == "start":
            assert rec is recs[0]
        elif rec.cause == "next_item":
            parent = m.states[src]
            assert parent.loop and _is_under(src_leaf, parent) and src_leaf.final, rec
            assert rec.target == parent.initial_leaf().path and not rec.resumed, rec
            assert rec.outcome == src_leaf.final and rec.item is not None and rec.item >= 1, rec
            domain = parent
        elif rec.cause == "done":
            node = m.states[src]
            assert src_leaf.final and src_leaf.parent is node, rec
            done = [t for t in node.transitions if isinstance(t, DoneTransition) and t.label == label]
            assert done and done[0].index == rec.index and done[0].handles(rec.outcome), rec
            domain = _domain_of(done[0])
            if node.loop:
                assert rec.outcome == _loop_outcome(m, result.summary["iterations"], node, rec.t), rec
            else:
                assert rec.outcome == src_leaf.final, rec
        else:
            assert not src_leaf.final, f"{rec}: left a final state"
            # the executor's table: outermost state first, each state's transitions in order
            table = [t for a in src_leaf.ancestors() for t in a.transitions if not isinstance(t, DoneTransition)]
            pos = next((i for i, t in enumerate(table) if (t.source.path, t.label) == (src, label)), None)
            assert pos is not None, f"{rec}: no declared transition {src!r}: {label!r} on the active path"
            tr = table[pos]
            assert tr.index == rec.index, rec
            assert _is_under(src_leaf, tr.source), f"{rec}: {src!r} is not an ancestor of {rec.source!r}"
            assert _is_under(m.states[rec.target], tr.target), f"{rec}: target outside {tr.target.path!r}"
            domain = _domain_of(tr)
            metrics, events = _metrics_at(script, tick), _script_events_at(script, tick)
            # the transition that fired holds ...
            if isinstance(tr, GuardTransition):
                assert rec.cause == "guard", rec
                guard = GUARDS[label.split(" for ")[0]]
                assert rec.metrics == {k: metrics.get(k) for k in sorted(tr.guard.metrics)}, rec
                first = tick - round(tr.dwell * RATE_HZ)
                assert first >= round(entered[tr.source.path] * RATE_HZ), f"{rec}: dwell longer than the stay"
                for k in range(first, tick + 1):
                    assert guard(_metrics_at(script, k)), f"{rec}: guard false at t={k / RATE_HZ}"
            elif isinstance(tr, TimeoutTransition):
                assert rec.cause == "timeout", rec
                assert rec.t - entered[tr.source.path] >= tr.after - 1e-9, f"{rec}: fired early"
            else:
                assert isinstance(tr, EventTransition) and rec.cause == "event" and rec.event == tr.event, rec
                assert tr.event in events or tr.event in ("tool_done", "tool_failed"), f"{rec}: {tr.event} not emitted"
            # ... and none checked before it did (outer first, then in order)
            for t in table[:pos]:
                if isinstance(t, GuardTransition) and t.dwell == 0:
                    assert not GUARDS[t.label](metrics), f"{rec}: earlier {t.source.path}: {t.label!r} held"
                elif isinstance(t, EventTransition):
                    assert t.event not in events, f"{rec}: earlier {t.source.path}: on {t.event} was due"
        # entry times: every state below the transition's domain on the target side is (re-)entered;
        # the machine library's own least common ancestor of the two leaves may be deeper (a transition
        # into its own source re-enters it: test_composite_self_transition_restarts_its_timer)
        before = set() if rec.source == "__start__" else {a.path for a in m.states[rec.source].ancestors()}
        for a in m.states[rec.target].ancestors()[1:]:
            if a.path not in before or _is_under(a, domain) and a is not domain:
                entered[a.path] = rec.t
    assert result.outcome in OUTCOMES
    assert result.outcome != "aborted" or "final state" in result.summary["reason"] \
        or "finished aborted" in result.summary["reason"], result.summary["reason"]  # no exception
    assert ex.leaf is not None and ex.leaf.path == previous == result.summary["final_state"]
    assert ex.engine.mission_model.state == ex.leaf.path  # the leaf is the `transitions` machine's state
    for a in ex.leaf.ancestors()[1:]:  # its entry clocks (which `after` reads) are the oracle's
        assert ex.entered_at(a) == pytest.approx(entered[a.path]), a.path
    if result.outcome != "timeout":
        assert ex.leaf.final, f"ended {result.outcome} in non-final {ex.leaf.path!r}"
    else:
        assert result.summary["sim_time_s"] == pytest.approx(MAX_TIME)
    assert result.summary["states_visited"] == [r.target for r in recs]
    assert sum(result.summary["time_in_state_s"].values()) == pytest.approx(result.summary["sim_time_s"], abs=1e-6)


@settings(max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(doc=machines(), script=scripts())
def test_random_valid_machines_keep_invariants(doc: dict[str, Any], script: Script) -> None:
    text = yaml.safe_dump(doc, sort_keys=False)
    note(text)
    m = load_mission_text(text, "generated.yaml")  # generated to be valid: a MissionError is a finding
    result = drive(m, script, max_time=MAX_TIME)
    note(str([(r.t, r.source, r.target, r.cause, r.state, r.label) for r in result.executor.transitions_fired]))
    check_run(m, result, script)
    causes = [r.cause for r in result.executor.transitions_fired]
    event(f"outcome {result.outcome}")
    event(f"depth {max(n.depth for n in m.states.values())}")
    event(f"transitions fired {min(len(causes) // 10 * 10, 50)}+")
    for cause in ("next_item", "done"):
        if cause in causes:
            event(f"fired a {cause} transition")
    if any(r.resumed for r in result.executor.transitions_fired):
        event("resumed a history state")


# -- executor bugs the exploration above ran into (deterministic, strict xfail) ------------------------

_LOCAL = """
mission: local
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 5 s
profiles: {gains: {g: {kp: 1.0}}}
machine:
  task: {name: toy_goto, params: {target: 1.0}}
  bind: {gains: g}
  initial: s
  states:
    s:
      initial: a
      transitions:
%s
      states:
        a:
          transitions:
            - {to: b, after: 10 s}
        b:
          transitions:
            - {to: a, after: 10 s}
    done: {final: true}
"""


def test_composite_self_transition_restarts_its_timer() -> None:
    m = load_mission_text(_LOCAL % "        - {to: s, after: 1 s}\n        - {to: done, on: arrived}", "local.yaml")
    r = drive(m, Script(), max_time=5)
    times = [round(rec.t, 2) for rec in r.executor.transitions_fired if (rec.state, rec.label) == ("s", "after 1 s")]
    assert times == [1.0, 2.0, 3.0, 4.0]


def test_dwell_restarts_after_a_break_in_a_tick_where_an_outer_transition_fires() -> None:
    m = load_mission_text(_LOCAL % ("        - {to: s.b, on: target_lost}\n"
                                    "        - {to: done, when: \"pos_error < 5 cm\", for: 1 s}"), "local.yaml")
    script = Script(metrics=lambda s: {"pos_error": 1.0 if abs(s.t - 0.5) < 1e-6 else 0.0},  # break at t = 0.5 s
                    events=[(0.5, "target_lost")])
    r = drive(m, script, max_time=5)
    fired = [rec.t for rec in r.executor.transitions_fired if rec.target == "done"]
    assert fired and fired[0] >= 1.55 - 1e-9, fired  # the guard holds again from 0.55 s


def test_event_at_time_zero_is_seen() -> None:
    m = load_mission_text(_LOCAL.replace("max_time: 5 s", "max_time: 1 s") % "        - {to: done, on: target_lost}",
                          "local.yaml")
    r = drive(m, Script(events=[(0.0, "target_lost")]), max_time=1)
    assert r.outcome == "succeeded"


# -- parallel regions, blends per region, history with self-transitions: engine against an oracle ------
#
# Random machines of top-level leaves, history composites and parallel states (two regions, each of
# leaves and history composites; region `a` owns `v` or both parts, region `b` the other part or none),
# with self-transitions on history composites, transitions from inside a composite to it, `resume:
# false` entries and `blend:` on transitions.  Every leaf runs a task commanding a constant of its own
# (`_LeafConst`), so the command shows each region's blends.  The engine runs on the scripted backend; the
# oracle below is a small, separate implementation of the documented semantics (docs/missions.md: order
# of evaluation, history, blend, parallel regions) that reads only the generated document — it never
# calls the executor or the compiler.  Both must agree on every tick's active leaves, entry clocks,
# history, command and outcome, and on the transitions fired.

REGION_EVENTS = ["target_lost", "target_found", "arrived"]
REGION_MAX_TIME = 6.0
BLENDS_S = ["0.3 s", "0.6 s", "1 s"]


class _RegionGen:
    """Builds one machine with parallel regions and history composites from hypothesis draws."""

    def __init__(self, draw: Any) -> None:
        self.draw = draw
        self.k = 0
        self.pending: list[tuple[dict[str, Any], list[str]]] = []  # (transition, the targets it may take)

    def name(self, prefix: str) -> str:
        self.k += 1
        return f"{prefix}{self.k}"

    def trigger(self, slow: bool = False) -> dict[str, Any]:
        kind = self.draw(st.sampled_from(["after", "on", "when"] if not slow else ["after", "on"]))
        if kind == "after":
            return {"after": f"{self.draw(st.integers(6, 40) if slow else st.integers(1, 24)) * 50} ms"}
        if kind == "on":
            return {"on": self.draw(st.sampled_from(REGION_EVENTS))}
        return {"when": self.draw(st.sampled_from(sorted(GUARDS)))}

    def transition(self, to: str, slow: bool = False, resume: bool = True) -> dict[str, Any]:
        tr: dict[str, Any] = {"to": to, **self.trigger(slow)}
        if resume and self.draw(st.integers(0, 3)) == 0:
            tr["resume"] = False
        if self.draw(st.booleans()):
            tr["blend"] = self.draw(st.sampled_from(BLENDS_S))
        return tr

    def leaf(self, in_b: bool) -> dict[str, Any]:
        task: Any = "toy_watch" if in_b else {"name": "toy_goto", "params": {"target": 0.5}}
        out: dict[str, Any] = {"task": task}
        if not in_b:
            out["bind"] = {"gains": "g"}
        return out

    def history(self, path: str, in_b: bool, scope: list[str]) -> dict[str, Any]:
        """A composite with history: 2-3 chained leaves and a final; maybe its own self-transition and a
        transition from a leaf inside it to it."""
        leaves = [self.name("h") for _ in range(self.draw(st.integers(2, 3)))]
        fin = self.name("hf")
        states: dict[str, Any] = {}
        order = leaves + [fin]
        for i, nm in enumerate(leaves):
            s = self.leaf(in_b)
            s["transitions"] = [self.transition(f"{path}.{order[i + 1]}")]
            if self.draw(st.integers(0, 2)) == 0:  # to the composite itself, from inside
                s["transitions"].append(self.transition(path))
            states[nm] = s
        states[fin] = {"final": self.draw(st.sampled_from([True, "succeeded", "failed"]))}
        out: dict[str, Any] = {"history": True, "initial": leaves[0], "states": states, "transitions": []}
        if self.draw(st.integers(0, 3)) > 0:
            out["transitions"].append(self.transition(path, slow=True))  # the self-transition
        self.extra(out, scope, slow=True)
        return out

    def extra(self, state: dict[str, Any], scope: list[str], slow: bool = False) -> None:
        for _ in range(self.draw(st.integers(0, 1))):
            tr = self.transition("?", slow)
            state.setdefault("transitions", []).append(tr)
            self.pending.append((tr, scope))

    def sequence(self, prefix: str, kinds: list[str], in_b: bool, top: bool,
                 scope: list[str]) -> tuple[dict[str, Any], str]:
        """States of the machine (``top``) or of a region: one working state per kind, then finals."""
        full = lambda nm: f"{prefix}.{nm}" if prefix else nm
        work = [self.name("s") for _ in kinds]
        finals = [self.name("f") for _ in range(self.draw(st.integers(1, 2)))]
        order = work + finals
        scope += [full(nm) for nm in order]
        states: dict[str, Any] = {}
        for i, (nm, kind) in enumerate(zip(work, kinds)):
            nxt = full(order[i + 1])
            if kind == "parallel":
                s = self.parallel(full(nm))
                s["transitions"] = [{"to": nxt, "done": True}]
                self.extra(s, scope, slow=True)
            elif kind == "history":
                s = self.history(full(nm), in_b, scope)
                s["transitions"].append({"to": nxt, "done": True})
            else:
                s = self.leaf(in_b)
                s["transitions"] = [self.transition(nxt, slow=top and i + 1 == len(work))]
                self.extra(s, scope)
            states[nm] = s
        for nm in finals[1:]:
            src = states[self.draw(st.sampled_from(work))]
            src["transitions"].insert(0, self.transition(full(nm), slow=True))
        for nm in finals:
            states[nm] = {"final": self.draw(st.sampled_from([True, "succeeded", "failed", "aborted"] if top else
                                                              [True, "succeeded", "failed"]))}
        return states, work[0]

    def parallel(self, path: str) -> dict[str, Any]:
        a_owns = self.draw(st.sampled_from([["v"], ["v", "w"]]))
        regions: dict[str, Any] = {}
        for r, owns in (("a", a_owns), ("b", [] if a_owns == ["v", "w"] else self.draw(st.sampled_from([["w"], []])))):
            scope: list[str] = []
            kinds = self.draw(st.lists(st.sampled_from(["leaf", "leaf", "history"]), min_size=1, max_size=2))
            states, initial = self.sequence(f"{path}.{r}", kinds, in_b=r == "b", top=False, scope=scope)
            regions[r] = {"initial": initial, "states": states, **({"owns": owns} if owns else {})}
        out: dict[str, Any] = {"regions": regions}
        if self.draw(st.integers(0, 2)) == 0:
            out["outcome_map"] = {"succeeded": {"a": "succeeded"}}
        return out


@st.composite
def region_machines(draw: Any) -> dict[str, Any]:
    g = _RegionGen(draw)
    top: list[str] = []
    kinds = draw(st.lists(st.sampled_from(["parallel", "history", "leaf"]), min_size=2, max_size=3))
    if "parallel" not in kinds:
        kinds[draw(st.integers(0, len(kinds) - 1))] = "parallel"
    states, initial = g.sequence("", kinds, in_b=False, top=True, scope=top)
    for tr, scope in g.pending:  # a state of the same region or sequence, or any top-level state (seldom a final)
        targets = sorted(set(scope) | set(top))
        if draw(st.integers(0, 3)) > 0:
            targets = [p for p in targets if not p.rsplit(".", 1)[-1].startswith("f")] or targets
        tr["to"] = draw(st.sampled_from(targets))
    return {
        "mission": "prop_regions",
        "robot": "toy_pair",
        "world": {"name": "toy_line", "params": {"start": 0.0}},
        "rate_hz": RATE_HZ,
        "max_time": f"{REGION_MAX_TIME} s",
        "parameters": {"tol": f"{TOL * 100:g} cm"},
        "profiles": {"gains": {"g": {"kp": 1.0}}},
        "machine": {"initial": initial, "states": states},
    }


class _ONode:
    """The oracle's view of one state, read from the generated document."""

    def __init__(self, name: str, path: str, parent: _ONode | None, spec: dict[str, Any]) -> None:
        self.name, self.path, self.parent, self.spec = name, path, parent, spec
        self.depth = 0 if parent is None else parent.depth + 1
        self.final: str | None = None
        if "final" in spec:
            self.final = "succeeded" if spec["final"] is True else spec["final"]
        self.children: dict[str, _ONode] = {}
        self.parallel = "regions" in spec
        self.history = bool(spec.get("history"))
        self.owns: tuple[str, ...] | None = None  # a region's parts (None: not a region)
        self.initial: str | None = spec.get("initial")
        kids = spec.get("regions") or spec.get("states") or {}
        for nm, sub in kids.items():
            child = _ONode(nm, f"{path}.{nm}" if path else nm, self, sub)
            if self.parallel:
                child.owns = tuple(sub.get("owns", ()))
            self.children[nm] = child
        self.transitions: list[dict[str, Any]] = list(spec.get("transitions", []))

    def walk(self) -> list[_ONode]:
        return [self] + [d for c in self.children.values() for d in c.walk()]

    def chain(self) -> list[_ONode]:
        """Root first, down to this state."""
        return ([] if self.parent is None else self.parent.chain()) + [self]

    def inside(self, other: _ONode) -> bool:
        return self.path == other.path or other.parent is None or self.path.startswith(other.path + ".")


def _o_weight(tau: float, duration: float) -> float:
    """h(τ) = ½(1 − cos(π τ / T)), 0 before the switch, 1 after T (docs/missions.md, `blend`)."""
    if tau >= duration:
        return 1.0
    return 0.0 if tau <= 0.0 else 0.5 * (1.0 - math.cos(math.pi * tau / duration))


class _Oracle:
    """The semantics of docs/missions.md for the generated machines, written apart from the executor."""

    def __init__(self, doc: dict[str, Any]) -> None:
        self.root = _ONode("", "", None, doc["machine"])
        self.nodes = {n.path: n for n in self.root.walk() if n.parent is not None}
        self.order = {p: i for i, p in enumerate(self.nodes)}  # declaration order
        self.consts = {p: float(i + 1) for i, p in enumerate(sorted(p for p, n in self.nodes.items()
                                                                      if not n.children and n.final is None))}
        self.active: set[str] = set()  # active leaf paths
        self.entered: dict[str, float] = {}  # active state → sim time of its last entry
        self.history: dict[str, str] = {}
        self.finished: dict[str, dict[str, str]] = {}  # parallel state → region → outcome
        self.blends: dict[str | None, tuple[float, float, dict[str, float], tuple[str, ...] | None]] = {}
        self.last = {"v": 0.0, "w": 0.0}
        self.outcome: str | None = None
        self.fired: list[tuple[int, str, str, bool]] = []  # (tick, destination, cause, resumed)
        self.tick_no = 0
        self.seen: set[str] = set()  # which crossings the run exercised (hypothesis events)

    # -- structure
    def target(self, source: _ONode, to: str) -> _ONode:
        if "." in to:
            return self.nodes[to]
        scope: _ONode | None = source.parent
        while scope is not None:
            if to in scope.children:
                return scope.children[to]
            scope = scope.parent
        raise KeyError(to)

    def domain(self, source: _ONode, target: _ONode) -> _ONode:
        common = self.root
        for a, b in zip(source.chain(), target.chain()):
            if a is not b:
                break
            common = a
        if (common is source or common is target) and common.parent is not None:
            return common.parent
        return common

    def region_of(self, n: _ONode) -> _ONode | None:
        m: _ONode | None = n
        while m is not None and m.owns is None:
            m = m.parent
        return m

    def entry(self, n: _ONode) -> _ONode:
        while n.children and not n.parallel:
            n = n.children[n.initial]  # type: ignore[index]
        return n

    def leaves(self) -> list[str]:
        return sorted(self.active, key=self.order.__getitem__)

    def is_active(self, n: _ONode) -> bool:
        return any(self.nodes[leaf].inside(n) for leaf in self.active)

    def resume_point(self, n: _ONode) -> str:
        return next(leaf for leaf in self.leaves() if self.nodes[leaf].inside(n))

    # -- changing state
    def go(self, domain: _ONode, dest: _ONode, t: float, cause: str, resumed: bool) -> None:
        leaving = [leaf for leaf in self.leaves() if self.nodes[leaf].inside(domain) and leaf != domain.path]
        for leaf in leaving:  # each history state left records the leaf it is left in
            for a in self.nodes[leaf].chain()[domain.depth + 1:]:
                if a.history:
                    self.history[a.path] = self.resume_point(a)
        self.active.difference_update(leaving)
        for p in [p for p in self.entered if self.nodes[p].inside(domain) and p != domain.path]:
            del self.entered[p]
        for a in dest.chain()[domain.depth + 1:]:
            self.entered[a.path] = t
        entered = [dest]
        if dest.parallel:
            self.finished.pop(dest.path, None)
            entered = []
            for region in dest.children.values():
                self.entered[region.path] = t
                leaf = region
                while leaf.children:
                    leaf = leaf.children[leaf.initial]  # type: ignore[index]
                    self.entered[leaf.path] = t
                entered.append(leaf)
        for leaf in entered:
            self.active.add(leaf.path)
        self.fired.append((self.tick_no, dest.path, cause, resumed))
        if dest.final is not None:
            self.on_final(dest, t)

    def fire(self, source: _ONode, tr: dict[str, Any], t: float, cause: str) -> None:
        target = self.target(source, tr["to"])
        domain = self.domain(source, target)
        dest, resumed = self.entry(target), False
        if target.history and tr.get("resume", True):
            if target.depth > domain.depth and self.is_active(target):  # exit first, then resolve the history
                point = self.nodes[self.resume_point(target)]
                if point.final is None:
                    dest, resumed = point, True
                    self.seen.add("resumed an active history state")
            elif target.path in self.history:
                dest, resumed = self.nodes[self.history[target.path]], True
        if "blend" in tr and cause != "done":
            region = self.region_of(domain)
            if region is None:
                self.blends.clear()
            else:
                self.blends.pop(region.path, None)
            duration = float(tr["blend"].split()[0])
            self.blends[None if region is None else region.path] = (
                t, duration, dict(self.last), None if region is None else region.owns)
            if sum(key is not None for key in self.blends) >= 2:
                self.seen.add("two regions blending at once")
        self.go(domain, dest, t, cause, resumed)

    def on_final(self, leaf: _ONode, t: float) -> None:
        parent, outcome = leaf.parent, leaf.final
        assert parent is not None and outcome is not None
        if parent.owns is not None:  # a region finished
            parallel = parent.parent
            assert parallel is not None
            done = self.finished.setdefault(parallel.path, {})
            done[parent.name] = outcome
            result = None
            for out, need in parallel.spec.get("outcome_map", {}).items():
                if all(done.get(r) == o for r, o in need.items()):
                    result = out
                    break
            if result is None and outcome != "succeeded":
                result = outcome
            if result is None and len(done) == len(parallel.children):
                result = "succeeded"
            if result is not None:
                self.complete(parallel, result, t)
        elif parent.parent is None:
            self.outcome = outcome
        else:
            self.complete(parent, outcome, t)

    def complete(self, node: _ONode, outcome: str, t: float) -> None:
        for tr in node.transitions:
            if "done" in tr and (tr["done"] is True or tr["done"] == outcome):
                self.fire(node, tr, t, "done")
                return
        self.outcome = outcome

    # -- a tick
    def holds(self, source: _ONode, tr: dict[str, Any], t: float, metrics: dict[str, float], events: set[str]) -> bool:
        if "when" in tr:
            return bool(GUARDS[tr["when"]](metrics))
        if "on" in tr:
            return tr["on"] in events
        if "after" in tr:
            after = float(tr["after"].split()[0]) / 1000.0
            return t - self.entered[source.path] + 1e-9 >= after
        return False

    def command(self, t: float) -> dict[str, float]:
        leaves = self.leaves()
        if len(leaves) == 1 and self.region_of(self.nodes[leaves[0]]) is None:
            c = self.consts.get(leaves[0], 0.0)
            cmd = {"v": c, "w": c}
        else:
            cmd = {"v": 0.0, "w": 0.0}
            for leaf in leaves:
                region = self.region_of(self.nodes[leaf])
                assert region is not None and region.owns is not None
                for k in region.owns:
                    if leaf in self.consts:
                        cmd[k] = self.consts[leaf]
        for key, (t0, duration, old, parts) in list(self.blends.items()):
            h = _o_weight(t - t0, duration)
            if h >= 1.0:
                del self.blends[key]
                continue
            for k in cmd:
                if parts is None or k in parts:
                    cmd[k] = h * cmd[k] + (1.0 - h) * old[k]
        self.last = cmd
        return cmd

    def step(self, k: int, metrics: dict[str, float], events: set[str]) -> dict[str, float]:
        t = k * (1.0 / RATE_HZ)  # the scripted world's clock: ticks times the period
        self.tick_no = k
        cmd = self.command(t)
        seen: set[tuple[str, int]] = set()
        for leaf in self.leaves():
            if self.outcome is not None:
                break
            if leaf not in self.active:
                continue  # a transition this tick left it
            for a in self.nodes[leaf].chain()[1:]:
                fired = False
                for i, tr in enumerate(a.transitions):
                    if "done" in tr or (a.path, i) in seen:
                        continue
                    seen.add((a.path, i))
                    if self.holds(a, tr, t, metrics, events):
                        self.fire(a, tr, t, "guard" if "when" in tr else "event" if "on" in tr else "timeout")
                        fired = True
                        break
                if fired:
                    break
        return cmd

    def start(self) -> None:
        first = self.root.children[self.root.initial]  # type: ignore[index]
        self.go(self.root, self.entry(first), 0.0, "start", False)


class _LeafConst(Task):
    """Commands ``v = w =`` its leaf's constant (``_Oracle.consts``); publishes nothing (the script's metrics
    are the guards')."""

    def __init__(self, ctx: TaskContext, value: float) -> None:
        super().__init__(ctx)
        self.value = value

    def step(self, obs: Observation) -> StepResult:
        return StepResult({"v": np.array([self.value]), "w": np.array([self.value])})


def _engine_snapshot(ex: Any) -> dict[str, Any]:
    leaves = list(ex.engine.active_leaves())
    states = sorted({a.path for p in leaves for a in ex.mission.states[p].ancestors()[1:]})
    return {"leaves": leaves, "entered": {p: ex.entered_at(ex.mission.states[p]) for p in states},
            "history": dict(ex.history), "outcome": ex.outcome}


def _oracle_snapshot(o: _Oracle) -> dict[str, Any]:
    return {"leaves": o.leaves(), "entered": dict(sorted(o.entered.items())), "history": dict(o.history),
            "outcome": o.outcome}


def check_regions_run(doc: dict[str, Any], script: Script) -> tuple[list[tuple[int, str, str, bool]], set[str]]:
    """Run ``doc`` on the scripted backend and the oracle side by side; assert they agree tick by tick."""
    m = load_mission_text(yaml.safe_dump(doc, sort_keys=False), "generated_regions.yaml")
    oracle = _Oracle(doc)
    world = ScriptedWorld(m.build_robot(), script, m)
    ticks: list[tuple[dict[str, Any], dict[str, float]]] = []
    holder: dict[str, Any] = {}

    def factory(cls: type[Task], ctx: TaskContext) -> Task:
        return _LeafConst(ctx, oracle.consts[holder["ex"].path[-1]])  # the leaf being entered

    def attach(ex: Any) -> None:
        holder["ex"] = ex
        world.executor = ex
        tick = ex.tick

        def recorded(obs: Observation) -> Any:
            out = tick(obs)
            ticks.append((_engine_snapshot(ex), {k: float(v[0]) for k, v in out[0].items()}))
            return out
        ex.tick = recorded

    result = run_mission(m, world=world, task_factory=factory, on_start=attach, record=False, safe_stop_s=0.0)
    oracle.start()
    k = 0
    while oracle.outcome is None and k / RATE_HZ < REGION_MAX_TIME - 1e-9:
        assert k < len(ticks), (f"the engine stopped at tick {len(ticks)} ({result.outcome}: "
                                f"{result.summary['reason']}); the oracle goes on ({_oracle_snapshot(oracle)})")
        cmd = oracle.step(k, _metrics_at(script, k), _script_events_at(script, k))
        engine, engine_cmd = ticks[k]
        assert engine == _oracle_snapshot(oracle), f"tick {k} (t = {k / RATE_HZ:g} s)"
        assert engine_cmd == pytest.approx(cmd, abs=1e-9), f"command at tick {k} (t = {k / RATE_HZ:g} s)"
        k += 1
    assert len(ticks) == k, f"the oracle stopped at tick {k}, the engine ran {len(ticks)}"
    assert result.outcome == (oracle.outcome or "timeout"), result.summary["reason"]
    fired = [(round(r.t * RATE_HZ), r.target, r.cause, r.resumed) for r in result.executor.transitions_fired]
    assert fired == oracle.fired
    return fired, oracle.seen


@settings(max_examples=80, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(doc=region_machines(), script=scripts())
def test_random_region_and_history_machines_agree_with_the_oracle(doc: dict[str, Any], script: Script) -> None:
    note(yaml.safe_dump(doc, sort_keys=False))
    fired, seen = check_regions_run(doc, script)
    note(str(fired))
    event(f"transitions fired {min(len(fired) // 10 * 10, 40)}+")
    for what in sorted(seen):
        event(what)
    if any(res for _, _, _, res in fired):
        event("resumed a history state")
    if any("." in tgt and tgt.count(".") >= 2 for _, tgt, _, _ in fired):
        event("moved inside a region")


# -- mutations never escape as anything but MissionError --------------------------------------------

_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml when available: the loader is the slow part
BASE_TEXT = TOY.read_text()
TINY_TEXT = """\
mission: tiny
robot: toy_point
world: toy_line
rate_hz: 10
machine:
  initial: wait
  states:
    wait:
      transitions:
        - {to: done, after: 1 s}
        - {to: wait, on: target_lost}
    done: {final: true}
"""
BASE_DOCS = [yaml.load(t, Loader=MissionLoader) for t in (BASE_TEXT, TINY_TEXT)]

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(max_size=12), st.sampled_from(["$goals", "$goal", "$nope", "1 cm", "3 deg", "-1 s",
                                                           "toy_goto", "operate", "done", ".nan", "{}", "[]"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                      st.dictionaries(st.text(max_size=8), inner, max_size=3)),
                      max_leaves=8)


def _paths(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [path] if path else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, path + (i,))
    return out


def _mutate(doc: Any, data: Any) -> Any:
    import copy

    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        key = path[-1]
        op = data.draw(st.sampled_from(["delete", "rename", "replace", "replace"]))
        if op == "delete":
            del parent[key]
        elif op == "rename" and isinstance(parent, dict):
            new = data.draw(st.one_of(st.text(max_size=10), st.sampled_from(
                ["to", "when", "on", "done", "after", "for", "task", "states", "initial", "final", "history",
                 "foreach", "bind", "params", "name", "in", "as", "action", "transitions", "blend", "resume"])))
            parent[new] = parent.pop(key)
        else:
            parent[key] = data.draw(values)
    return doc


def _load_or_mission_error(text: str) -> None:
    try:
        load_mission_text(text, "mutant.yaml")
    except MissionError as exc:
        assert exc.problems
        for p in exc.problems:
            assert p.file == "mutant.yaml" and p.line >= 0 and p.col >= 0 and p.message
            str(p)


@settings(max_examples=120, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_document_mutations_give_only_mission_errors(data: Any) -> None:
    doc = _mutate(data.draw(st.sampled_from(BASE_DOCS)), data)
    text = yaml.dump(doc, Dumper=_Dumper, sort_keys=False, allow_unicode=True)
    note(text)
    _load_or_mission_error(text)


_printable = st.characters(codec="utf-8", exclude_categories=("Cs",))


@settings(max_examples=120, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_text_mutations_give_only_mission_errors(data: Any) -> None:
    text = data.draw(st.sampled_from([BASE_TEXT, TINY_TEXT]))
    for _ in range(data.draw(st.integers(1, 3))):
        pos = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["insert", "insert", "delete", "yaml"]))
        if op == "insert":
            text = text[:pos] + data.draw(st.text(_printable, min_size=1, max_size=8)) + text[pos:]
        elif op == "delete":
            text = text[:pos] + text[pos + data.draw(st.integers(1, 20)):]
        else:  # YAML punctuation is the likeliest to produce odd structures
            text = text[:pos] + data.draw(st.sampled_from(
                ["[", "]", "{", "}", ":", ": ", "- ", "&a ", "*a", "!!str ", "? ", "|", ">", "'", '"', "#", "\n  ",
                 "\t", "%", "@", "`", "---\n", "...\n", "!!binary ", "!!set ", "!!float "])) + text[pos:]
    note(text)
    _load_or_mission_error(text)


@settings(max_examples=60, deadline=None, database=None)
@given(ch=st.characters(categories=("Cc",), exclude_characters="\t\n\r"), pos=st.integers(0, len(BASE_TEXT)))
def test_control_characters_give_mission_errors(ch: str, pos: int) -> None:
    _load_or_mission_error(BASE_TEXT[:pos] + ch + BASE_TEXT[pos:])


# -- random operator scripts: an independent oracle of the whole run, tick by tick (issue 20) -----------
#
# The same random machines and scripts, now with a random operator script (pause, hold, resume, preempt to
# any state or abort, inject, at random ticks).  `_OperatedOracle` runs the machine itself from the
# machine's declarations, the script and the operator actions — written from docs/missions.md, not from
# taskflow/execution/ — and must agree with the engine on every tick's active leaf and its entry time, on
# every transition (tick, source, target, cause, resumed), the entry clocks and operating clocks at the end
# (time under hold does not count toward `after` and `for`), the history of every composite, the outcome
# (a pre-emption that leaves a loop before its rule held cannot end the run `succeeded`) and the summary's
# `preempted` and `held_s`.
#
# A transition or pre-emption into a `history` composite that is active at that moment resumes the leaf that
# exit leaves (UML: exit first, then resolve history; it used to resume an older record).

WHO = ("ann", "bo")


@st.composite
def operator_scripts(draw: Any, targets: list[str], busy: list[int], preferred: list[str]) -> list[dict[str, Any]]:
    """Operator actions at random ticks — half of them at a ``busy`` tick of the undisturbed run (a dwell
    under way, a timeout running, a loop active) — and pre-emptions half the time to a ``preferred``
    target (a root final that succeeds, a history composite)."""
    ops: list[dict[str, Any]] = []

    def tick() -> float:
        if busy and draw(st.booleans()):
            return draw(st.sampled_from(busy)) / RATE_HZ
        return draw(st.integers(0, int(MAX_TIME * RATE_HZ) - 1)) / RATE_HZ

    for _ in range(draw(st.integers(0, 6))):
        t = tick()
        who = draw(st.sampled_from(WHO))
        kind = draw(st.sampled_from(["hold", "hold", "resume", "preempt", "preempt", "preempt", "inject", "inject",
                                     "pause", "abort"]))
        if kind == "pause":  # without an endpoint a pause is ended by the script at its own sim time
            ops += [{"t": t, "action": "pause", "who": who},
                    {"t": t, "action": draw(st.sampled_from(["resume", "hold"])), "who": who}]
        elif kind == "preempt":
            pool = preferred if preferred and draw(st.booleans()) else targets
            ops.append({"t": t, "action": "preempt", "args": {"to": draw(st.sampled_from(pool))}, "who": who})
        elif kind == "abort":
            ops.append({"t": t, "action": "preempt", "who": who})
        elif kind == "inject":
            ops.append({"t": t, "action": "inject", "args": {"event": draw(st.sampled_from(EVENTS))}, "who": who})
        elif kind == "hold":  # mostly resumed later: a held run should also go on
            ops.append({"t": t, "action": "hold", "who": who})
            if draw(st.integers(0, 3)):
                back = min(t + draw(st.integers(1, 80)) / RATE_HZ, MAX_TIME - 1 / RATE_HZ)
                ops.append({"t": back, "action": "resume", "who": who})
        else:
            ops.append({"t": t, "action": kind, "who": who})
    return ops


def _busy_ticks(m: CompiledMission, script: Script, records: list[Any], end: float) -> list[int]:
    """Ticks of an undisturbed run where an operator action matters most: the active leaf has a dwell guard
    that held at this tick and the one before, or a timeout running, or a loop around it."""
    out: list[int] = []
    truth: dict[tuple[str, int], bool] = {}

    def holds(label: str, k: int) -> bool:
        if (label, k) not in truth:
            truth[label, k] = GUARDS[label](_metrics_at(script, k))
        return truth[label, k]

    for i, rec in enumerate(records):
        leaf = m.states[rec.target]
        first = round(rec.t * RATE_HZ)
        last = round((records[i + 1].t if i + 1 < len(records) else end) * RATE_HZ)
        table = [tr for a in leaf.ancestors() for tr in a.transitions if not isinstance(tr, DoneTransition)]
        for k in range(first, min(last, int(MAX_TIME * RATE_HZ))):
            if any(a.loop for a in leaf.ancestors()) or any(isinstance(tr, TimeoutTransition) for tr in table) or any(
                    isinstance(tr, GuardTransition) and tr.dwell > 0 and k > first
                    and holds(tr.label.split(" for ")[0], k - 1) and holds(tr.label.split(" for ")[0], k)
                    for tr in table):
                out.append(k)
    return out


def _required(m: CompiledMission, node: StateNode) -> int:
    """Items a foreach must see succeed, from the document (`require`: all, a count, a share rounded up)."""
    fe: Any = m.spec.machine
    for a in node.ancestors()[1:]:
        fe = fe.states[a.name]
    rule, n = fe.foreach.require, len(m.spec.parameters[fe.foreach.in_])
    if fe.foreach.on_failure == "stop" or rule == "all":
        return n
    return rule if isinstance(rule, int) else math.ceil(float(str(rule).rstrip(" %")) * n / 100)


class _OperatedOracle:
    """Runs a generated machine tick by tick, as docs/missions.md describes it, with operator actions."""

    def __init__(self, m: CompiledMission, script: Script, ops: list[dict[str, Any]]) -> None:
        self.m, self.script = m, script
        self.ops = sorted(ops, key=lambda a: a["t"])  # stable, as the channel applies them
        self.dt = 1.0 / RATE_HZ
        self.t = 0.0
        self.leaf: StateNode | None = None
        self.entered: dict[str, float] = {}  # state path → sim time of its last entry
        self.held_at: dict[str, float] = {}  # state path → time held before that entry
        self.held = 0.0
        self.dwell: dict[int, float] = {}  # transition index → operating time its condition began
        self.history: dict[str, str] = {}
        self.item: dict[str, int] = {}
        self.succeeded_items: dict[str, int] = {}
        self.pending: list[tuple[float, str]] = []  # the tool action's end event
        self.skipped: dict[str, str] = {}  # loop path → verdict of its rule when a pre-emption left it
        self.records: list[tuple[int, str, str, str, bool]] = []  # tick, from, to, cause, resumed
        self.seen: list[tuple[str, float]] = []  # per tick: active leaf and its entry time, as observed
        self.preempted: list[dict[str, Any]] = []
        self.outcome: str | None = None
        self.engine_records: list[Any] = []
        self.into_active_history = 0  # transitions into a history composite active at that moment

    # -- entering and leaving --------------------------------------------------------------------------
    def _path_down(self, leaf: StateNode, keep: int) -> list[StateNode]:
        return [a for a in leaf.ancestors()[1:] if a.depth > keep]

    def _go(self, dest: StateNode, cause: str, resumed: bool, keep: int) -> None:
        old = self.leaf
        if old is not None:
            for a in reversed(self._path_down(old, keep)):  # exits, innermost first
                if a.action is not None:
                    self.pending.clear()
                if a.history:
                    self.history[a.path] = old.path
        for a in self._path_down(dest, keep):  # entries, outermost first
            self.entered[a.path], self.held_at[a.path] = self.t, self.held
            for tr in a.transitions:
                self.dwell.pop(tr.index, None)
            if a.loop and not resumed:
                self.item[a.path], self.succeeded_items[a.path] = 0, 0
                self.skipped.pop(a.path, None)
            if a.action is not None:
                delay, event = self.script.actions["tool"]  # type: ignore[misc]
                self.pending.append((self.t + delay, event))
        self.leaf = dest
        self.records.append((round(self.t * RATE_HZ), old.path if old else "__start__", dest.path, cause, resumed))
        if dest.final:
            self._finished(dest)

    def _destination(self, target: StateNode, resume: bool) -> tuple[StateNode, bool]:
        """Where a transition into ``target`` leads.  UML order: the transition exits first, then resolves
        history — a history target that is active when it is exited resumes the leaf this exit leaves (its
        active leaf), or starts afresh when that leaf is final (the target has just finished)."""
        if target.children and target.history and resume and self.leaf is not None and _is_under(self.leaf, target):
            self.into_active_history += 1
            if self.leaf.final:
                return target.initial_leaf(), False
            return self.leaf, True
        last = self.history.get(target.path) if target.children and target.history and resume else None
        if last is not None:
            return self.m.states[last], True
        return target.initial_leaf(), False

    def _finished(self, leaf: StateNode) -> None:
        parent = leaf.parent
        outcome = leaf.final or "succeeded"
        assert parent is not None
        if parent.parent is None:
            self._end(outcome)
            return
        if parent.loop:
            n = len(self.m.spec.parameters[parent.loop.items])
            i = self.item[parent.path]
            if outcome == "succeeded":
                self.succeeded_items[parent.path] += 1
            if outcome == "succeeded" or parent.loop.on_failure == "continue":
                if i + 1 < n:
                    self.item[parent.path] = i + 1
                    self._go(parent.initial_leaf(), "next_item", False, parent.depth)
                    return
                outcome = "succeeded" if self.succeeded_items[parent.path] >= _required(self.m, parent) else "failed"
        self._complete(parent, outcome)

    def _complete(self, node: StateNode, outcome: str) -> None:
        self.skipped.pop(node.path, None)
        for tr in node.transitions:
            if isinstance(tr, DoneTransition) and (tr.outcome is None or tr.outcome == outcome):
                dest, resumed = self._destination(tr.target, tr.resume)
                self._go(dest, "done", resumed, _domain_of(tr).depth)
                return
        self._end(outcome)

    def _end(self, outcome: str) -> None:
        if outcome == "succeeded":
            outcome = next((v for v in self.skipped.values() if v != "succeeded"), outcome)
        self.outcome = outcome

    # -- one tick --------------------------------------------------------------------------------------
    def _observe(self, k: int) -> set[str]:
        """What the world's observation at tick ``k`` carries: the script's events and the tool's end."""
        events = _script_events_at(self.script, k)
        due = [e for e in self.pending if e[0] <= self.t + 1e-9]
        for e in due:
            self.pending.remove(e)
            events.add(e[1])
        assert self.leaf is not None
        self.seen.append((self.leaf.path, self.entered[self.leaf.path]))
        return events

    def _preempt(self, to: str | None, who: str) -> None:
        assert self.leaf is not None
        self.preempted.append({"t": round(self.t, 9), "who": who, "to": to, "from": self.leaf.path})
        if to is None:
            self.outcome = "aborted"
            return
        dest, resumed = self._destination(self.m.states[to], True)
        for a in self.leaf.ancestors()[1:]:
            if a.loop and not _is_under(dest, a):  # left for good: its rule, judged now
                self.skipped[a.path] = "succeeded" if self.succeeded_items[a.path] >= _required(self.m, a) else "failed"
        self._go(dest, "operator", resumed, 0)

    def _check(self, k: int, events: set[str]) -> None:
        assert self.leaf is not None
        metrics = _metrics_at(self.script, k)
        op = self.t - self.held
        table = [tr for a in self.leaf.ancestors() for tr in a.transitions if not isinstance(tr, DoneTransition)]
        for i, tr in enumerate(table):
            if isinstance(tr, GuardTransition):
                if GUARDS[tr.label.split(" for ")[0]](metrics):
                    if tr.dwell > 0:
                        since = self.dwell.setdefault(tr.index, op)
                        if op - since + 1e-9 < tr.dwell:
                            continue
                else:
                    self.dwell.pop(tr.index, None)
                    continue
            elif isinstance(tr, EventTransition):
                if tr.event not in events:
                    continue
            elif isinstance(tr, TimeoutTransition):
                src = tr.since.path
                if (self.t - self.entered[src]) - (self.held - self.held_at[src]) + 1e-9 < tr.after:
                    continue
            for later in table[i + 1:]:  # a dwell not evaluated this tick still sees its break
                if isinstance(later, GuardTransition) and later.dwell > 0 and later.index in self.dwell \
                        and not GUARDS[later.label.split(" for ")[0]](metrics):
                    del self.dwell[later.index]
            dest, resumed = self._destination(tr.target, tr.resume)
            cause = "guard" if isinstance(tr, GuardTransition) else "event" if isinstance(tr, EventTransition) else "timeout"
            self._go(dest, cause, resumed, _domain_of(tr).depth)
            return

    def run(self, engine_records: list[Any]) -> None:
        self.engine_records = engine_records
        first = self.m.root.children[self.m.root.initial]  # type: ignore[index]
        self._go(first.initial_leaf(), "start", False, 0)
        mode, nxt, k = "running", 0, 0
        while self.outcome is None:
            self.t = k / RATE_HZ
            events = self._observe(k)
            if self.t >= MAX_TIME - 1e-9:
                self.outcome = "timeout"
                break
            injected: set[str] = set()
            while nxt < len(self.ops) and self.ops[nxt]["t"] <= self.t + 1e-9 and self.outcome is None:
                a = self.ops[nxt]
                nxt += 1
                if a["action"] in ("pause", "hold", "resume"):
                    mode = {"pause": "paused", "hold": "held", "resume": "running"}[a["action"]]
                elif a["action"] == "inject":
                    injected.add(a["args"]["event"])
                else:
                    mode = "running"
                    self._preempt(a.get("args", {}).get("to"), a["who"])
            if self.outcome is not None:
                break
            assert mode != "paused", "the generated script ends every pause at its own time"
            if mode == "held":
                self.held += (k + 1) / RATE_HZ - self.t
                k += 1
                continue
            self._check(k, events | injected)
            k += 1


def check_operated_run(m: CompiledMission, result: Any, script: Script, ops: list[dict[str, Any]],
                       seen: list[tuple[str, float]]) -> _OperatedOracle:
    ex = result.executor
    oracle = _OperatedOracle(m, script, ops)
    oracle.run(ex.transitions_fired)
    got = [(round(r.t * RATE_HZ), r.source, r.target, r.cause, r.resumed) for r in ex.transitions_fired]
    for i, (want, have) in enumerate(zip(oracle.records, got)):
        assert want == have, f"record {i}: oracle {want}, engine {have}"
    assert len(got) == len(oracle.records), f"engine {got[len(oracle.records):]} / oracle {oracle.records[len(got):]}"
    # every tick's active leaf and its entry time, as the world observed them
    ticks = len(oracle.seen)
    assert [(s, pytest.approx(e)) for s, e in oracle.seen] == seen[:ticks]
    assert result.outcome == oracle.outcome, result.summary["reason"]
    assert result.summary["sim_time_s"] == pytest.approx(oracle.t)
    assert result.summary.get("preempted", []) == oracle.preempted
    assert result.summary.get("held_s", 0.0) == pytest.approx(oracle.held)
    assert ex.held_s == pytest.approx(oracle.held)
    assert ex.history == oracle.history
    leaf = m.states[result.summary["final_state"]]
    for a in leaf.ancestors()[1:]:  # entry clocks (sim time) and the operating clocks `after` reads
        assert ex.entered_at(a) == pytest.approx(oracle.entered[a.path]), a.path
        assert ex.operating_since(a, oracle.t) == pytest.approx(
            oracle.t - oracle.entered[a.path] - (oracle.held - oracle.held_at[a.path])), a.path
    if any(p["to"] is not None for p in oracle.preempted) and result.outcome in ("succeeded", "failed"):
        assert any(p["who"] in result.summary["reason"] for p in oracle.preempted), result.summary["reason"]
    return oracle


@settings(max_examples=250, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(doc=machines(), script=scripts(), data=st.data())
def test_random_operator_scripts_agree_with_an_independent_oracle(doc: dict[str, Any], script: Script, data: Any) -> None:
    text = yaml.safe_dump(doc, sort_keys=False)
    note(text)
    m = load_mission_text(text, "generated.yaml")
    base = drive(m, script, max_time=MAX_TIME)  # undisturbed: where operator actions would matter
    busy = _busy_ticks(m, script, base.executor.transitions_fired, base.summary["sim_time_s"])
    preferred = sorted(p for p, n in m.states.items() if n.history or (n.final == "succeeded" and n.depth == 1))
    ops = data.draw(operator_scripts(sorted(m.outside_regions), busy, preferred), label="operator script")
    seen: list[tuple[str, float]] = []
    metrics = script.metrics

    def watched(s: Any) -> dict[str, float]:  # the state each observation is taken in (before the tick)
        seen.append((s.state, s.t - s.time_in_state))
        return dict(metrics(s))

    watched_script = Script(metrics=watched, events=script.events, actions=script.actions)
    result = drive(m, watched_script, max_time=MAX_TIME, operator=ops)
    note(str([(r.t, r.source, r.target, r.cause, r.resumed) for r in result.executor.transitions_fired]))
    oracle = check_operated_run(m, result, script, ops, seen)
    event(f"outcome {result.outcome}")
    if oracle.into_active_history:
        event("a transition into an active history composite")
    actions = {a["action"] for a in ops}
    for a in sorted(actions):
        event(f"operator {a}")
    if result.summary.get("held_s", 0) > 0 and any(r.cause == "timeout" for r in result.executor.transitions_fired):
        event("a timeout fired after a hold")
    if any(r.cause == "operator" for r in result.executor.transitions_fired) and result.outcome == "failed":
        event("failed after a pre-emption")
