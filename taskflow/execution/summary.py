"""What a run returns and writes to ``summary.json``: the outcome, the summary built from the mission, the
seed and the simulation only (:func:`build_summary`), and the :class:`RunResult` of
:func:`taskflow.execution.runtime.run_mission`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from taskflow.execution.executor import Executor
from taskflow.execution.provenance import versions
from taskflow.execution.records import IterationRecord
from taskflow.mission.data import clean_floats
from taskflow.mission.model import CompiledMission

OUTCOMES = ("succeeded", "failed", "aborted", "timeout")


@dataclass
class RunResult:
    """What one run returns (:func:`~taskflow.execution.runtime.run_mission`, and :func:`taskflow.testing.drive` / ``run_on_world``).

    Everything a test asserts on is in ``summary``, the same dict the run writes to ``summary.json``
    (record or not); the other fields are the outcome again, where the record went, the machine itself
    and wall-clock figures. ``summary`` holds:

    - ``mission``, ``file`` (the mission file's resolved path), ``seed``;
    - ``outcome`` (as below), ``reason`` (why, in words), ``final_state`` (the active leaf at the end,
      parallel leaves joined with ``|``);
    - ``states_visited`` (every leaf entered, in order), ``time_in_state_s`` (leaf → simulated seconds
      spent in it), ``sim_time_s`` (simulated time when the outcome was reached), ``ticks``,
      ``transitions`` (how many fired), ``stopped_at_s`` (simulated time after the safe stop);
    - ``iterations`` (one dict per ``foreach`` item: ``state``, ``index``, ``item``, ``outcome``,
      ``t_start``, ``t_end``, ``ground_truth`` when it ended; with ``retry`` declared, ``attempts`` and
      ``retried``, the final state of each earlier attempt — the item counts on its last) and ``items``
      (foreach state → ``attempted``, ``succeeded``, ``failed``, ``success_rate``, ``required``, ``rule``;
      with ``retry``, ``retry``, ``attempts`` over all items, ``retried``, the items run again, and
      ``recovered``, those of them that succeeded);
    - ``metrics`` (the last value of every metric published on the last tick, then the world's
      ``summary_metrics()``: ground truth such as ``gt_x_m``, ``final_error_m``), ``outputs`` (the final
      mission data the mission declares as outputs), ``versions`` (the packages the run used);
    - ``properties``, only when the mission declares some: name → ``pattern``, ``verdict`` (``held``,
      ``violated``, ``not_decided``), ``t`` (the first violation, None) and ``reason``
      (:mod:`taskflow.execution.monitors`).
    """

    #: ``"succeeded"``, ``"failed"``, ``"timeout"`` (``max_time`` reached) or ``"aborted"`` (an error,
    #: Ctrl-C, SIGTERM, an operator's abort); the same as ``summary["outcome"]``
    outcome: str
    #: the run's summary, as written to ``summary.json`` (see above)
    summary: dict[str, Any]
    #: the run directory with trace.csv, transitions.jsonl, summary.json, mission.yaml, timing.json;
    #: None when nothing was recorded (``drive`` and ``run_on_world`` record only with ``out_dir``)
    run_dir: Path | None
    #: the machine after the run: ``state``, ``path``, ``memory`` (mission data), ``transitions_fired``,
    #: ``iterations``; None when the run could not start (its world could not be built)
    executor: Executor | None
    #: wall-clock figures (what timing.json holds: real-time factor, per-tick and per-part costs); never
    #: part of the summary, and empty when the run could not start
    timing: dict[str, Any]

    @property
    def succeeded(self) -> bool:
        """Whether ``outcome`` is ``"succeeded"``."""
        return self.outcome == "succeeded"


def recorded_file(file: str) -> str:
    """The mission file as a run records it: its resolved absolute path, the same from any working
    directory (so a seed reproduces ``summary.json`` byte for byte wherever it is run from); a mission
    loaded from text keeps its placeholder name (``<string>``)."""
    return file if file.startswith("<") else str(Path(file).resolve())


def build_summary(mission: CompiledMission, seed: int, ex: Executor, sim_time: float,
                  metrics: dict[str, Any], ticks: int) -> dict[str, Any]:
    """What a run did, from the mission, the seed and the simulation only (no wall-clock figure).  A run an
    operator acted on also has ``preempted`` (each pre-emption: ``t``, ``who``, ``to``, ``from``) and
    ``held_s`` (sim seconds under hold), when there were any."""
    out = {
        "mission": mission.name,
        "file": recorded_file(mission.file),
        "seed": seed,
        "outcome": ex.outcome,
        "reason": ex.reason,
        "final_state": ex.state,
        "states_visited": list(ex.path),
        "sim_time_s": round(sim_time, 9),
        "ticks": ticks,
        "time_in_state_s": {k: round(v, 9) for k, v in ex.time_in_state.items()},
        "iterations": [_iteration(r) for r in ex.iterations],
        "items": {path: count.as_dict() for path, count in ex.item_counts.items()},
        "transitions": len(ex.transitions_fired),
        "metrics": metrics,
        "outputs": mission.data.outputs(ex.memory),
        "versions": versions(),
    }
    if ex.preemptions:
        out["preempted"] = [p.as_dict() for p in ex.preemptions]
    if ex.held_s > 0.0:
        out["held_s"] = round(ex.held_s, 9)
    summary: dict[str, Any] = clean_floats(out)
    return summary


def _iteration(r: IterationRecord) -> dict[str, Any]:
    """One ``foreach`` item of ``summary.json``'s ``iterations`` (its attempts where the loop declares ``retry``)."""
    out: dict[str, Any] = {"state": r.state, "index": r.index, "item": r.item, "outcome": r.outcome,
                           "t_start": r.t_start, "t_end": r.t_end, "ground_truth": r.ground_truth}
    if r.attempts is not None:
        out.update(attempts=r.attempts, retried=list(r.retried))
    return out
