"""What a run leaves on disk, written as the run goes.

``RUN_DIR/``
  ``mission.yaml``        the mission as resolved (overrides applied, world parameters drawn)
  ``seed``                the seed, alone on a line
  ``transitions.jsonl``   one JSON object per change of the active leaf: ``t``, ``from``, ``to``, ``cause``
                          (start, guard, timeout, event, done, next_item, retry), ``state`` and ``label`` (the
                          declaring state and the transition as written), and as they apply ``index``,
                          ``metrics`` (the guard's metric values when it fired), ``event``, ``outcome``,
                          ``item``, ``attempt``, ``resumed``, ``who`` — :class:`TransitionRecord`; and one object per
                          operator action (``taskflow ctl``, an operator script): ``cause: operator``,
                          ``action``, ``who``, ``args``, ``t``, ``tick``, ``state`` (and ``refused``, why, when the
                          run could not take it) — :class:`OperatorRecord`; and one object per declared
                          property a tick first violated: ``cause: property``, ``property``, ``pattern``,
                          ``verdict`` (violated), ``t``, ``state``, ``atoms`` (each atom's value then),
                          ``reason`` — :class:`PropertyRecord` (:mod:`taskflow.execution.monitors`)
  ``trace.csv``           one row per control tick: ``t``, ``state``, ``events``, metric columns
                          ``m.NAME``, command columns ``cmd.KEY[.i]``, ground truth ``gt.NAME``
                          (``pandas.read_csv`` / ``numpy.genfromtxt(names=True)`` read it; ``nan``
                          where a metric has no value that tick)
  ``summary.json``        outcome, final state, states visited, times, foreach items, final metrics, and
                          the versions of the packages that shape the result; after operator actions,
                          ``preempted`` (``t``, ``who``, ``to``, ``from`` each) and ``held_s``; with declared
                          properties, ``properties`` (name → ``pattern``, ``verdict``, ``t``, ``reason``)
  ``timing.json``         wall-clock figures only: real-time factor, per-tick loop time and the parts tasks
                          and worlds time (perception, control …) as n / mean / p50 / p95 / max in ms
  ``frames/``, ``frames.jsonl``  in rendered modes, the camera images the world observed, as PNG at a declared
                          rate on simulation time, and their index (:mod:`taskflow.execution.frames`)

Everything but ``timing.json`` depends only on the mission and the seed: two runs with one seed write
the same bytes.

Read back (:mod:`taskflow.readers.run_files`), every reader parses a ``transitions.jsonl`` line with
``record_from_dict`` (the one parse: an :class:`OperatorRecord`, a :class:`PropertyRecord` or a
:class:`TransitionRecord`), a trace row
with ``parse_trace_row`` (``read_trace``), through :mod:`taskflow.execution.record_io` (a record is untrusted
input).

Rows are buffered and flushed every ``flush_every`` ticks; ``summary.json`` exists from the start
(outcome ``aborted``, reason ``run did not finish``) and is replaced when the run ends, so a crash or
Ctrl-C still leaves a readable record.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from taskflow.mission.data import clean_floats

START_CAUSE, GUARD, TIMEOUT, EVENT, DONE, NEXT_ITEM = "start", "guard", "timeout", "event", "done", "next_item"
RETRY, OPERATOR = "retry", "operator"
CAUSES = (START_CAUSE, GUARD, TIMEOUT, EVENT, DONE, NEXT_ITEM, RETRY, OPERATOR)
PROPERTY = "property"
"""The ``cause`` of a :class:`PropertyRecord` (no state change: not one of :data:`CAUSES`)."""


@dataclass
class TransitionRecord:
    """One change of the active leaf, with what caused it as fields (``transitions.jsonl`` holds them).

    ``cause`` is one of :data:`CAUSES`: ``start``; ``guard`` (a ``when`` held: ``metrics`` has the values
    of its metrics that tick), ``timeout`` (an ``after`` ran out), ``event`` (``event``; with a condition,
    ``metrics`` too), ``done`` (the sub-machine of ``state`` finished with ``outcome``) or ``next_item``
    (the loop ``state`` moved to item ``item`` after an item that ended ``outcome``) or ``retry`` (the loop
    ``state`` runs item ``item`` again, its attempt ``attempt`` — 2 the first retry — after the final state
    ``from`` ended the previous attempt ``outcome``: ``foreach: {retry: …}``; ``from`` is that final state
    alone, even beside parallel regions) or ``operator`` (``who``
    pre-empted the run to ``target``: ``taskflow ctl preempt --to``, :mod:`taskflow.execution.control`).  ``state`` and
    ``label`` name the declaring state and the transition as written; ``index`` is the transition's index
    in the mission; ``resumed`` says a history state was resumed where it was left."""

    t: float
    source: str  # the leaf left ("__start__" for the first record)
    target: str  # the leaf entered
    cause: str
    state: str = ""
    label: str = ""
    index: int | None = None
    metrics: dict[str, float] | None = None
    event: str | None = None
    outcome: str | None = None
    item: int | None = None
    attempt: int | None = None  # the attempt a ``retry`` starts (2: the first retry)
    resumed: bool = False
    who: str | None = None  # the operator who pre-empted (cause ``operator``)

    def as_dict(self) -> dict[str, Any]:
        """The JSON object of ``transitions.jsonl``: the fields that apply to this cause."""
        out: dict[str, Any] = {"t": round(self.t, 9), "from": self.source, "to": self.target, "cause": self.cause,
                               "state": self.state, "label": self.label}
        for key in ("index", "metrics", "event", "outcome", "item", "attempt", "who"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        if self.resumed:
            out["resumed"] = True
        return out


@dataclass
class OperatorRecord:
    """One operator action as it took effect (``transitions.jsonl``, ``cause: operator``, no ``from``/``to``):
    ``action`` (pause, hold, resume, preempt, inject) with its ``args`` (``to`` of a pre-emption, ``event``
    of an injection), ``who`` asked for it, and the sim time ``t`` and index ``tick`` of the control tick at
    whose start it was applied, with the ``state`` active then; ``refused``, when the run could not take it
    (a pre-emption whose target reads mission data not written yet), says why — the action then changed
    nothing.  A list of these is an operator script (:func:`taskflow.execution.control.script_from_records`):
    replayed, it gives the same run."""

    t: float
    tick: int
    action: str
    who: str
    state: str
    args: dict[str, str]
    refused: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out = {"t": round(self.t, 9), "tick": self.tick, "cause": OPERATOR, "action": self.action, "who": self.who,
               "state": self.state, "args": dict(self.args)}
        if self.refused is not None:
            out["refused"] = self.refused
        return out


@dataclass
class PropertyRecord:
    """A declared property's first violation (``transitions.jsonl``, ``cause: property``, no ``from``/``to``):
    the ``property`` and its ``pattern``, the sim time ``t`` of the tick that violated it, the configuration
    ``state`` that tick ran in, the value of each of its ``atoms`` then (a state, event or outcome atom true or
    false; a metric its number, None when not published) and, for a response or precedence, the ``reason``."""

    t: float
    property: str
    pattern: str
    state: str
    atoms: dict[str, Any]
    reason: str = ""
    verdict: str = "violated"

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"t": round(self.t, 9), "cause": PROPERTY, "property": self.property,
                               "pattern": self.pattern, "verdict": self.verdict, "state": self.state,
                               "atoms": dict(self.atoms)}
        if self.reason:
            out["reason"] = self.reason
        return out


@dataclass
class ItemCount:
    """A foreach loop's items over a whole run: attempted, succeeded (each item counted on its last attempt),
    its success rule, and — for a loop that declares ``retry`` — every attempt and the items run again."""

    required: int  # per run of the loop
    rule: str  # as written: "all", "3", "75 %"
    attempted: int = 0
    succeeded: int = 0
    retry: int = 0  # further attempts the loop allows an item (0: no ``retry``, nothing below is written)
    attempts: int = 0  # attempts over all items (an item's retries included)
    retried: int = 0  # items that took more than one attempt
    recovered: int = 0  # ... and of those, the ones that succeeded

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "attempted": self.attempted, "succeeded": self.succeeded, "failed": self.attempted - self.succeeded,
            "success_rate": self.succeeded / self.attempted if self.attempted else None,
            "required": self.required, "rule": self.rule}
        if self.retry:
            out.update(retry=self.retry, attempts=self.attempts, retried=self.retried, recovered=self.recovered)
        return out


@dataclass
class IterationRecord:
    state: str
    index: int
    item: Any
    outcome: str
    t_start: float
    t_end: float
    ground_truth: dict[str, float]
    attempts: int | None = None  # with ``retry`` declared: the attempts the item took (it counts on the last)
    retried: tuple[str, ...] = ()  # ... and the final state each earlier attempt ended in



def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, float) and math.isnan(o):
        return None
    return str(o)


def write_json(path: Path, data: Any) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=_json_default, allow_nan=False) + "\n")
    os.replace(tmp, path)


class RunRecorder:
    """Writes one run directory."""

    def __init__(self, out_dir: Path, metric_names: Iterable[str], command_layout: dict[str, int],
                 gt_names: Iterable[str], flush_every: int = 50) -> None:
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.metric_names = list(metric_names)
        self.command_layout = dict(command_layout)
        self.gt_names = list(gt_names)
        self.flush_every = flush_every
        self._rows: list[str] = []  # the rows formatted at their tick, written every ``flush_every``
        self._nans = [math.nan] * len(self.metric_names)  # the value of a metric not published that tick
        self._gt_nans = [math.nan] * len(self.gt_names)
        self._cmd = [(k, n, [math.nan] * n) for k, n in self.command_layout.items()]
        cmd_cols = [f"cmd.{k}" if n == 1 else f"cmd.{k}.{i}" for k, n in self.command_layout.items() for i in range(n)]
        self.columns = ["t", "state", "events", *[f"m.{m}" for m in self.metric_names], *cmd_cols,
                        *[f"gt.{g}" for g in self.gt_names]]
        self._trace = open(self.dir / "trace.csv", "w", buffering=1 << 16)  # noqa: SIM115 - open for the run
        self._trace.write(",".join(self.columns) + "\n")
        self._transitions = open(self.dir / "transitions.jsonl", "w")  # noqa: SIM115 - open for the run
        self.ticks = 0

    # -- start ---------------------------------------------------------------------------------
    def write_mission(self, resolved: dict[str, Any], seed: int) -> None:
        (self.dir / "mission.yaml").write_text(yaml.safe_dump(clean_floats(resolved), sort_keys=False))
        (self.dir / "seed").write_text(f"{seed}\n")

    # -- as the run goes ---------------------------------------------------------------------
    def transition(self, record: dict[str, Any]) -> None:
        self._transitions.write(json.dumps(clean_floats(record)) + "\n")

    def tick(self, t: float, state: str, events: Iterable[str], metrics: dict[str, float],
             command: dict[str, Any], gt: dict[str, float]) -> None:
        # the row is formatted now: a task or world may reuse (and later change) the dicts and arrays it returned
        vals = list(map(metrics.get, self.metric_names, self._nans))
        for k, n, missing in self._cmd:
            v = command.get(k)
            if v is None:
                vals += missing
            elif type(v) is np.ndarray and v.ndim == 1:  # the usual command: np.ravel's copy is not needed
                vals += v[:n].tolist()
            elif type(v) is float and n == 1:
                vals.append(v)
            else:
                vals += np.ravel(v)[:n].tolist()
        if self.gt_names:
            vals += map(gt.get, self.gt_names, self._gt_nans)
        ev = "|".join(sorted(events)) if events else ""
        self._rows.append(f"{t!r},{state},{ev}," + ",".join(map(repr, map(float, vals))))
        self.ticks += 1
        if len(self._rows) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        if not self._rows:
            self._transitions.flush()
            return
        self._rows.append("")  # the last row's newline
        self._trace.write("\n".join(self._rows))
        self._trace.flush()
        self._transitions.flush()
        self._rows.clear()

    # -- end -------------------------------------------------------------------------------------
    def summary(self, data: dict[str, Any]) -> None:
        self.flush()
        write_json(self.dir / "summary.json", clean_floats(data))

    def timing(self, data: dict[str, Any]) -> None:
        write_json(self.dir / "timing.json", clean_floats(data))

    def close(self) -> None:
        self.flush()
        self._trace.close()
        self._transitions.close()


def _stats_ms(seconds: list[float]) -> dict[str, float]:
    a = 1e3 * np.asarray(seconds, dtype=float)
    return {"n": int(a.size), "mean": float(a.mean()), "p50": float(np.percentile(a, 50)),
            "p95": float(np.percentile(a, 95)), "max": float(a.max())}


class TimingRecord:
    """Wall-clock time of one run: the control loop per tick, and the named parts tasks and worlds report
    (``StepResult.timings`` / ``Observation.timings``, in seconds).  Kept apart from the trace and the
    summary, which must not depend on the machine's speed."""

    def __init__(self) -> None:
        self.parts: dict[str, list[float]] = {}
        self.ticks: list[float] = []
        self._last: float | None = None

    def add(self, source: str, timings: dict[str, float]) -> None:
        for name, seconds in timings.items():
            self.parts.setdefault(f"{source}.{name}", []).append(seconds)

    def tick(self, now: float) -> None:
        """Mark the end of a tick at wall time ``now`` (``time.perf_counter()``)."""
        if self._last is not None:
            self.ticks.append(now - self._last)
        self._last = now

    def summary(self, sim_time: float, wall: float, ticks: int) -> dict[str, Any]:
        return {
            "sim_time_s": sim_time, "wall_time_s": wall, "ticks": ticks,
            "real_time_factor": sim_time / wall if wall > 0 else None,
            "tick_ms": _stats_ms(self.ticks) if self.ticks else None,
            "parts_ms": {k: _stats_ms(v) for k, v in sorted(self.parts.items()) if v},
        }
