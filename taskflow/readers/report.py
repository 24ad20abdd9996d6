"""The terminal summary of a run, from its record (:class:`~taskflow.readers.recorded.RecordedRun`).

What it prints, in order: the outcome and its reason; times; ``foreach`` item counts (and attempts, with ``retry``); the operator's
actions (pause, hold, resume, inject, preempt: who, when, in which state), whatever the outcome; each declared
property's verdict (``summary.json``'s ``properties``) with its first violation's atom values; for a run that
did not succeed, the chain of transitions that led to the final state, each with its cause (the guard
with the metric values it fired on, the event, the timeout, the sub-machine's outcome); then every metric
with its unit in two groups, each saying how many it holds (``-``: dimensionless; ``(no unit)``: a
count, a ratio or a label whose name declares none):

* **ground truth and world summary** — what the world measured at the end of the run
  (:meth:`~taskflow.api.World.summary_metrics`); these are the final values;
* **task and sensor metrics** — each metric tasks and the world's observations publish every tick
  (what guards read): its last value in the trace, labelled with the state that published it
  and when: a task's belief at that moment, not a final value (the stopped car's last ``speed`` is
  from before the stop).

Units of task and world-observation metrics are the declared ones; a world summary metric's unit is
read from its name's suffix (:data:`taskflow.units.SUFFIX_UNITS`: ``final_error_m`` is in m, ``gt_speed_mps`` in m/s).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from taskflow.execution.records import OperatorRecord, PropertyRecord, TransitionRecord
from taskflow.readers.recorded import RecordedRun
from taskflow.units import suffix_unit

CHAIN_SHOWN = 12
"""Longest transition chain printed whole; a longer one prints its last entries and says how many it left out."""


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (int, float)):
        return "nan" if isinstance(v, float) and math.isnan(v) else f"{v:.6g}"
    if isinstance(v, (list, dict)):
        return f"({type(v).__name__} of {len(v)} entries, see summary.json)"
    return str(v)


def _unit(unit: str | None) -> str:
    return "(no unit)" if unit is None else "-" if unit == "" else unit


def describe_transition(rec: TransitionRecord, units: dict[str, str]) -> str:
    """One line: when, from → to, and what caused it with the values it fired on."""
    head = f"t = {rec.t:8.2f} s  {rec.source} → {rec.target}"
    where = f" (declared on {rec.state})" if rec.state and rec.state != rec.source else ""
    if rec.cause == "start":
        return f"t = {rec.t:8.2f} s  start in {rec.target}"
    if rec.cause == "guard":
        why = f"guard '{rec.label}'"
    elif rec.cause == "event":
        why = f"event '{rec.event}'" + (f" with condition '{rec.label}'" if rec.metrics else "")
    elif rec.cause == "timeout":
        why = f"timeout '{rec.label}'"
    elif rec.cause == "done":
        why = f"sub-machine {rec.state} finished '{rec.outcome}'"
        where = ""
    elif rec.cause == "operator":
        why = f"pre-empted by {rec.who} (operator)"
    elif rec.cause == "retry":
        why = f"retry of item {rec.item} in {rec.state}, attempt {rec.attempt} (the last ended '{rec.outcome}')"
        where = ""
    else:
        why = f"{rec.cause} (item {rec.item}, previous item {rec.outcome})"
    values = ""
    if rec.metrics:
        values = " with " + ", ".join(f"{k} = {_value(v)} {units.get(k, '')}".rstrip() for k, v in rec.metrics.items())
    return f"{head}: {why}{where}{values}"


def describe_operator(rec: OperatorRecord) -> str:
    """One line: when, which operator action with its argument, who asked for it, the state active then, and
    why the run refused it, if it did."""
    to = rec.args.get("to")
    arg = {"preempt": f" --to {to}" if to else " (abort)", "inject": f" {rec.args.get('event', '')}"}.get(rec.action, "")
    refused = f" — refused: {rec.refused}" if rec.refused else ""
    return f"t = {rec.t:8.2f} s  {rec.action}{arg} by {rec.who} (tick {rec.tick}, in {rec.state or '-'}){refused}"


def describe_property(name: str, verdict: dict[str, Any], rec: PropertyRecord | None) -> str:
    """One line: the property, its verdict, and for a violation when, in which state, with its atoms' values."""
    head = f"{name} ({verdict.get('pattern', '')}): {verdict.get('verdict', '')}"
    if rec is None:
        return head + (f" — {verdict['reason']}" if verdict.get("reason") else "")
    values = ", ".join(f"{k} = {_value(v) if v is not None else 'none'}" for k, v in rec.atoms.items())
    return f"{head} at t = {rec.t:.2f} s in {rec.state or '-'}" + (f": {values}" if values else "") + \
        (f" — {rec.reason}" if rec.reason else "")


def _last_values(run: RecordedRun) -> list[tuple[str, float, str, float]]:
    """(metric, last finite value, state that published it, t) for every metric in the trace."""
    t, states = run.trace["t"], run.trace["state"]
    out = []
    for name in run.metric_columns():
        col = run.trace[f"m.{name}"]
        i = int(np.flatnonzero(np.isfinite(col))[-1])
        out.append((name, float(col[i]), str(states[i]), float(t[i])))
    return out


def format_report(run: RecordedRun, timing: dict[str, Any] | None = None) -> str:
    """The summary printed after ``taskflow run`` (module docstring)."""
    s = run.summary
    lines = [f"outcome: {s.get('outcome', '')} ({s.get('reason', '')})"]
    wall = f"   wall: {timing.get('wall_time_s', 0):.2f} s   RTF: {timing.get('real_time_factor') or 0:.1f}x" if timing else ""
    lines.append(f"final state: {s.get('final_state', '')}   sim time: {s.get('sim_time_s') or 0.0:.2f} s{wall}   "
                 f"ticks: {s.get('ticks', 0)}")
    for loop, c in s.get("items", {}).items():
        tries = f"; {c['attempts']} attempts, {c['retried']} items retried" if "attempts" in c else ""
        lines.append(f"  items of {loop}: {c['succeeded']}/{c['attempted']} succeeded (rule: {c.get('rule', '')}, "
                     f"{c.get('required', 0)} required{tries})")
    if run.operator:
        lines.append(f"operator actions ({len(run.operator)}):")
        lines += [f"  {describe_operator(r)}" for r in run.operator]
    verdicts = s.get("properties")
    if isinstance(verdicts, dict) and verdicts:
        first = {r.property: r for r in run.properties}
        lines.append(f"properties ({len(verdicts)}):")
        lines += [f"  {describe_property(k, v, first.get(k))}" for k, v in verdicts.items() if isinstance(v, dict)]
    units = run.metric_units
    if s.get("outcome") != "succeeded" and run.transitions:
        chain = run.transitions
        lines.append(f"how it got there ({len(chain)} transition{'s' if len(chain) != 1 else ''}):")
        if len(chain) > CHAIN_SHOWN:
            lines.append(f"  … {len(chain) - CHAIN_SHOWN + 1} earlier transitions (transitions.jsonl has them all)")
            chain = chain[-(CHAIN_SHOWN - 1):]
        lines += [f"  {describe_transition(r, units)}" for r in chain]
        if s.get("reason") and run.transitions[-1].target != s.get("final_state"):
            lines.append(f"  then: {s['reason']}")

    task_names = set(units)
    world = {k: v for k, v in s.get("metrics", {}).items() if k not in task_names}
    lines.append(f"ground truth and world summary at the end ({len(world)} metrics):")
    width = max([len(k) for k in world] + [len(k) for k in units] + [8])
    for k, v in world.items():
        lines.append(f"  {k:{width}s}  {_value(v):>14s}  {_unit(suffix_unit(k))}")
    last = _last_values(run)
    lines.append(f"task and sensor metrics ({len(last)} metrics; last value each, with the state that published it — "
                 "not final values):")
    for name, v, state, t in last:
        lines.append(f"  {name:{width}s}  {v:>14.6g}  {_unit(units.get(name)):10s}  last in {state} at t = {t:.2f} s")
    return "\n".join(lines)
