"""Property-based tests of the engine (hypothesis): parallel regions, blends and history against an oracle.

Random machines with *parallel regions, blends and history composites* (self-transitions,
transitions from inside a composite to it, `resume: false` entries, region finals and
`outcome_map`) run on the scripted backend with a constant command per leaf, side by side with
:class:`_Oracle` (properties_region_oracle.py), a small separate implementation of the documented semantics that reads only the
generated document: both agree on every tick's active leaves, entry clocks, history, command
(each region's parts and blends) and outcome, and on the transitions fired.  It found the engine
bug pinned by tests/machine/test_crossing.py::test_a_region_moves_on_while_the_last_region_has_finished.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st
from properties_machines import GUARDS, RATE_HZ, TOL, _metrics_at, _script_events_at, scripts
from properties_region_oracle import _Oracle

from taskflow.api import Observation, StepResult, Task, TaskContext
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, ScriptedWorld

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
