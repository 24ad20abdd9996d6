"""Random operator scripts and the independent tick-by-tick oracle of an operated run
(`_OperatedOracle`), for tests/execution/test_properties_operated.py."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import strategies as st
from properties_machines import EVENTS, GUARDS, MAX_TIME, RATE_HZ, _domain_of, _is_under, _metrics_at, _script_events_at

from taskflow.mission.model import (
    CompiledMission,
    DoneTransition,
    EventTransition,
    GuardTransition,
    StateNode,
    TimeoutTransition,
)
from taskflow.testing import Script

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
