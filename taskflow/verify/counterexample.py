"""Counterexamples a person can read and the engine can replay.

A :class:`Counterexample` is a path of the model (:mod:`taskflow.verify.model`) from the configuration after
the start, with the cause of every step, and a sentence for what happens at its end ("no final state can be
reached from here", "waits in ``searching`` forever").  :meth:`Counterexample.render` prints it like the
"how it got there" chain of a run's report; :meth:`Counterexample.script` turns it into a
:class:`~taskflow.execution.scripted.Script` for the scripted backend — metric values that make each step's guard true
(and the guards checked before it false) while its state is active, its events at their times — so that
``taskflow.execution.scripted.drive`` runs the real engine along it and records the run the replay page shows
(``taskflow verify MISSION --replay DIR``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from taskflow.execution.records import EVENT, START_CAUSE
from taskflow.execution.scripted import Script, ScriptState
from taskflow.execution.summary import RunResult
from taskflow.mission.guards import DATA_PREFIX
from taskflow.mission.model import EventTransition, GuardTransition, TimeoutTransition, Transition
from taskflow.verify.model import MAX_TIME, TICK, Model, Step, entered_by

__all__ = ["Counterexample", "Replay", "satisfying_metrics"]


@dataclass
class Counterexample:
    """A path of ``model`` from its initial configuration: ``[(from, step), …]``, then ``ending`` in words."""

    model: Model
    path: list[tuple[int, Step]]
    ending: str = ""
    highlight: list[str] = field(default_factory=list)  # the states the ending names (drawn on `taskflow graph`)

    @property
    def end(self) -> int:
        return self.path[-1][1].target if self.path else self.model.initial

    def times(self) -> list[float]:
        """The model time (s) at which each step of :attr:`path` is taken."""
        q, t, out = self.model.quantum, 0.0, []
        for _, step in self.path:
            out.append(t)
            if step.cause == TICK:
                t += q
        return out

    def states_visited(self) -> list[str]:
        """The leaves the run enters, in order, as a run's ``summary.json`` lists them (``states_visited``)."""
        m = self.model
        out: list[str] = []
        records = list(m.start_records) + [r for _, step in self.path for r in step.records]
        for _cause, to in records:
            node = m.mission.states[to]
            out += [leaf.path for leaf in node.entry_leaves()] if node.parallel else [to]
        return out

    def transitions(self) -> list[Transition]:
        m = self.model
        return [m.mission.transitions[s.transition] for _, s in self.path if s.transition is not None]

    def render(self, indent: str = "  ") -> str:
        """The path as lines: time, the step's cause and transition, the configuration it leads to; runs of
        ticks folded into one line."""
        m = self.model
        lines = [f"{indent}t = 0 s: start in {m.configs[m.initial].describe()}"]
        times = self.times()
        k = 0
        while k < len(self.path):
            src, step = self.path[k]
            if step.cause == TICK:
                j = k
                while j < len(self.path) and self.path[j][1].cause == TICK:
                    j += 1
                n = j - k
                lines.append(f"{indent}  … {n * m.quantum:g} s pass (every guard false, no event)")
                k = j
                continue
            lines.append(f"{indent}t = {times[k]:g} s: {describe_step(m, step)} → {m.configs[step.target].describe()}")
            k += 1
        if self.ending:
            lines.append(f"{indent}then: {self.ending}")
        return "\n".join(lines)

    def as_dict(self) -> dict[str, Any]:
        m = self.model
        return {"steps": [{"t": t, "cause": s.cause, "label": s.label, "transition": s.transition, "event": s.event,
                           "from": m.configs[a].describe(), "to": m.configs[s.target].describe()}
                          for t, (a, s) in zip(self.times(), self.path)],
                "ending": self.ending, "highlight": self.highlight}

    # -- driving the engine along it ------------------------------------------------------------------------
    def schedule(self) -> tuple[list[tuple[float, float, dict[str, float]]], list[tuple[float, str]], float]:
        """When the engine takes each step: metric windows ``(from, to, values)`` for the guard steps, the events
        with their times, and the time of the last step.  An environment step comes one control period after
        the step before it (and not before the tick the model has reached); a timeout fires its ``after`` after
        its clock state was entered, as in the engine."""
        m = self.model
        dt = 1.0 / float(m.mission.spec.rate_hz)
        q = m.quantum
        windows: list[tuple[float, float, dict[str, float]]] = []
        events: list[tuple[float, str]] = []
        entered_at = {p: 0.0 for p in entered_by(m, -1, Step(START_CAUSE, m.initial))}
        t, ticks = 0.0, 0
        for src, step in self.path:
            if step.cause == TICK:
                ticks += 1
                continue
            if step.cause == MAX_TIME or step.transition is None:
                break
            tr = m.mission.transitions[step.transition]
            if isinstance(tr, TimeoutTransition):
                t = max(t, entered_at.get(tr.since.path, 0.0) + tr.after)
            else:
                t = _on_grid(max(t + dt, ticks * q), dt)
                earlier = _checked_before(m, src, tr)
                if isinstance(tr, GuardTransition):
                    windows.append((t - dt / 2, t + tr.dwell + dt / 2, satisfying_metrics(tr, earlier)))
                    t = _on_grid(t + tr.dwell, dt)
                elif isinstance(tr, EventTransition):
                    if tr.guard is not None:
                        windows.append((t - dt / 2, t + dt / 2, satisfying_metrics(tr, earlier)))
                    events.append((t, tr.event))
            for p in entered_by(m, src, step):
                entered_at[p] = t
        return windows, events, t

    def script(self) -> Script:
        """A :class:`Script` that drives the engine along this path (:meth:`schedule`): while a guard step is due,
        metric values that make its guard true and the guards checked before it false; its events at their
        times; the world's actions never end by themselves (their end events are among the path's events)."""
        windows, events, _ = self.schedule()

        def metrics(s: ScriptState) -> Mapping[str, float]:
            for a, b, values in windows:
                if a <= s.t < b:
                    return values
            return {}

        return Script(metrics=metrics, events=events,
                      actions={name: (math.inf, evs[0] if evs else "") for name, evs in
                               self.model.mission.world_cls.actions.items()})

    def replay(self, out_dir: str | Path | None = None) -> Replay:
        """Drive the real engine (the scripted backend) along the path, recording into ``out_dir`` when given
        (``taskflow view OUT_DIR`` shows it), and compare the records it writes with the path's."""
        from taskflow.execution.scripted import drive

        m = self.model
        _, _, t_end = self.schedule()
        result = drive(m.mission, self.script(), max_time=t_end + m.quantum + 1.0, out_dir=out_dir)
        assert result.executor is not None  # drive returns the run's executor
        got = [(r.cause, r.target) for r in result.executor.transitions_fired]
        want = list(m.start_records) + [r for _, st in self.path for r in st.records]
        return Replay(result, want, got)


def _on_grid(t: float, dt: float) -> float:
    """``t`` rounded up to the control period's grid."""
    return math.ceil(t / dt - 1e-6) * dt


@dataclass
class Replay:
    """The engine driven along a counterexample: its run, the records the path writes and those the run wrote."""

    result: RunResult
    expected: list[tuple[str, str]]
    got: list[tuple[str, str]]

    @property
    def followed(self) -> bool:
        return self.got[:len(self.expected)] == self.expected

    def describe(self) -> str:
        if self.followed:
            return f"the engine followed the counterexample ({len(self.expected)} records); outcome {self.result.outcome}"
        k = next(i for i, (a, b) in enumerate(itertools.zip_longest(self.expected, self.got)) if a != b)
        return (f"the engine left the counterexample at record {k + 1}: expected {self.expected[k] if k < len(self.expected) else None}, "
                f"got {self.got[k] if k < len(self.got) else None}")


def describe_step(model: Model, step: Step) -> str:
    """The cause of a step in words: ``guard `when: …` (declared on S)``, ``event e``, ``timeout `after: 3 s```."""
    if step.cause == MAX_TIME:
        return f"the max time ends the run ({step.label})"
    if step.transition is None:
        return step.cause
    tr = model.mission.transitions[step.transition]
    where = f" on {tr.source.path}"
    cascade = [c for c, _ in step.records[1:]]
    then = f" (then {', '.join(cascade)})" if cascade else ""
    if step.cause == EVENT:
        return f"event {step.event!r} `{tr.label}`{where}{then}"
    return f"{step.cause} `{tr.label}`{where}{then}"


def _checked_before(model: Model, src: int, tr: Transition) -> list[GuardTransition]:
    """The guard transitions the engine checks before ``tr`` in the tables of the configuration ``src`` (their
    guards must be false for ``tr`` to be the one that fires)."""
    out: list[GuardTransition] = []
    states = model.mission.states
    for leaf in model.configs[src].leaves:
        table = [t for a in states[leaf].ancestors() for t in a.transitions]
        if tr not in table:
            continue
        out += [t for t in table[:table.index(tr)] if isinstance(t, GuardTransition)]
    return out


def satisfying_metrics(target: GuardTransition | EventTransition, false: list[GuardTransition]) -> dict[str, float]:
    """Metric values under which ``target``'s guard holds and the guard of every transition of ``false`` does not —
    by trying, for each metric involved, no value at all (a comparison on a metric without a value is false) and
    points just around each threshold it is compared with, on the transitions' own compiled predicates.  ``data.``
    atoms are the run's mission data, not metrics: they are left out (the predicates see no data).  An empty dict
    when no candidate works (the step is then left to the run)."""
    guards = [g for g in [target.guard, *(t.guard for t in false)] if g is not None]
    candidates: dict[str, set[float | None]] = {}
    for g in guards:
        for c in g.comparisons():
            if c.metric.startswith(DATA_PREFIX):
                continue
            opts = candidates.setdefault(c.metric, {None})
            if c.value is not None:
                v = float(c.value)
                step = max(abs(v) * 1e-3, 1e-6)
                opts.update({v - step, v, v + step, -v - step, -v + step})
    names = sorted(candidates)
    choices = [sorted(candidates[n], key=lambda x: (x is not None, x or 0.0)) for n in names]
    holds, fails = target.predicate, [t.predicate for t in false]
    for combo in itertools.islice(itertools.product(*choices), 20_000):
        values = {k: v for k, v in zip(names, combo) if v is not None}
        if holds is not None and not holds(values, {}):
            continue
        if any(f(values, {}) for f in fails):
            continue
        return values
    return {}
