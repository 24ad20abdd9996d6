"""A finished run directory read back: its trace, transitions, summary, and the mission it ran.

Figures (:mod:`taskflow.readers.plots`), the terminal summary (:mod:`taskflow.readers.report`) and telemetry exports
(:mod:`taskflow.readers.telemetry`) all start from :func:`load_run`.  The mission is recompiled from the run's own
``mission.yaml`` (world parameters as drawn for its seed), so units, guards, command components and the
scene come from the declarations of the code that reads the record, checked as at load time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from taskflow.errors import MissionError
from taskflow.execution.frames import FrameRecord, read_frames
from taskflow.execution.record_io import MAX_FRAME_BYTES, RunDirError, check_summary, inside, read_bytes, read_json
from taskflow.execution.records import OperatorRecord, PropertyRecord, TransitionRecord
from taskflow.mission.guards import Comparison
from taskflow.mission.model import CompiledMission, EventTransition, GuardTransition
from taskflow.readers.run_files import read_trace, read_transitions
from taskflow.readers.scene import Scene, mission_scene

__all__ = ["RecordedRun", "RunDirError", "Threshold", "load_run"]


@dataclass(frozen=True)
class Threshold:
    """One comparison of a guard: ``metric op value`` (value in the metric's base unit), declared by the
    transition ``source → target`` (state paths) written ``label``."""

    metric: str
    op: str
    value: float
    absolute: bool
    source: str
    target: str
    label: str


@dataclass
class RecordedRun:
    """Everything one run directory holds, plus what its mission declares.

    ``trace`` maps column → array (:func:`~taskflow.readers.run_files.read_trace`); ``transitions`` are the records of
    ``transitions.jsonl`` in order that change the active leaf (the operator's pre-emptions included),
    ``operator`` its operator actions (pause, hold, resume, preempt, inject: :class:`OperatorRecord`) in
    order; ``properties`` the first violation of each declared property (:class:`PropertyRecord`); ``frames`` the camera frames ``frames.jsonl`` indexes (:mod:`taskflow.execution.frames`, each file
    inside the run directory); ``summary`` is ``summary.json``; ``mission`` the recompiled mission,
    ``scene`` its markers and control points; ``metric_units`` metric → base unit; ``command_labels``
    trace column ``cmd.KEY[.i]`` → (component name, unit)."""

    dir: Path
    trace: dict[str, np.ndarray]
    transitions: list[TransitionRecord]
    summary: dict[str, Any]
    mission: CompiledMission
    world_params: BaseModel
    scene: Scene
    metric_units: dict[str, str] = field(default_factory=dict)
    command_labels: dict[str, tuple[str, str]] = field(default_factory=dict)
    operator: list[OperatorRecord] = field(default_factory=list)
    frames: list[FrameRecord] = field(default_factory=list)
    properties: list[PropertyRecord] = field(default_factory=list)

    @property
    def seed(self) -> int:
        seed = self.summary.get("seed")
        return int(self.mission.spec.seed if seed is None else seed)

    def thresholds(self) -> list[Threshold]:
        """Every metric comparison of every ``when`` guard or event condition, with its bound value."""
        out: list[Threshold] = []
        for tr in self.mission.transitions:
            guard = tr.guard if isinstance(tr, (GuardTransition, EventTransition)) else None
            if guard is None:
                continue
            for c in guard.comparisons():
                if c.value is not None and _bound(c):
                    out.append(Threshold(c.metric, c.op, float(c.value), c.absolute,
                                         tr.source.path, tr.target.path, tr.label))
        return out

    def metric_columns(self) -> list[str]:
        """The metric names with at least one value in the trace, in trace order."""
        return [c[2:] for c in self.trace if c.startswith("m.") and np.isfinite(self.trace[c]).any()]

    def pose_track(self, body: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """Ground-truth x, y (and yaw, None when the world gives none) of ``body`` over the trace."""
        keys = self.scene.poses.get(body)
        if keys is None or f"gt.{keys[0]}" not in self.trace or f"gt.{keys[1]}" not in self.trace:
            return None
        yaw = self.trace.get(f"gt.{keys[2]}") if keys[2] is not None else None
        return self.trace[f"gt.{keys[0]}"], self.trace[f"gt.{keys[1]}"], yaw

    def control_track(self) -> tuple[np.ndarray, np.ndarray]:
        """x, y of the point each tick's state measures: its control point (:meth:`Scene.control_point`)
        where the state declares one, the robot's reported pose elsewhere; NaN where the trace has no pose."""
        track = self.pose_track(next(iter(self.scene.poses), ""))
        n = self.trace["t"].size
        if track is None:
            return np.full(n, np.nan), np.full(n, np.nan)
        x, y, yaw = track
        cx, cy = x.copy(), y.copy()
        if yaw is not None:
            states = self.trace["state"]
            for state in dict.fromkeys(states.tolist()):
                cp = self.scene.control_point(state)
                if cp is not None:
                    m = states == state
                    cx[m], cy[m] = cp.of(x[m], y[m], yaw[m])
        return cx, cy


def _bound(c: Comparison) -> bool:
    return c.value is not None and math.isfinite(float(c.value))


def _command_labels(mission: CompiledMission) -> dict[str, tuple[str, str]]:
    robot = mission.robot_cls
    out: dict[str, tuple[str, str]] = {}
    for key, n in robot.command_keys.items():
        declared = robot.command_units.get(key, ())
        for i in range(n):
            col = f"cmd.{key}" if n == 1 else f"cmd.{key}.{i}"
            name, unit = declared[i] if i < len(declared) else (str(i), "?")
            out[col] = (key if n == 1 else f"{key}.{name}", unit)
    return out


def _uses(node: Any, path: tuple[Any, ...]) -> tuple[Any, ...] | None:
    """The key path of the first ``use:`` in the machine ``node``, None when it has none."""
    if isinstance(node, dict):
        if "use" in node and "states" in path:
            return (*path, "use")
        items: Any = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        return None
    for key, child in items:
        found = _uses(child, (*path, key))
        if found is not None:
            return found
    return None


EXTERNAL_PARAMS = ("_dir", "_file", "_path")
"""Endings of the world parameters that name a file or folder outside the record (``quad_room``'s
``keyframe_dir``): the world reads them when it runs, a reader never needs them, so a record's mission
is compiled with them null — a reader opens nothing a record names outside itself."""


def _without_external_files(data: Any) -> None:
    world = data.get("world") if isinstance(data, dict) else None
    params = world.get("params") if isinstance(world, dict) else None
    if isinstance(params, dict):
        for key in params:
            if isinstance(key, str) and key.endswith(EXTERNAL_PARAMS):
                params[key] = None


def _load_mission(run_dir: Path) -> CompiledMission:
    """The run's own ``mission.yaml`` compiled: a plain file inside ``run_dir`` (:func:`inside`), in
    which every sub-mission is already expanded — a ``use:`` would read a file outside the record, so it
    is refused (:class:`RunDirError` ``FILE:LINE:COL``), as is a mission this code cannot compile; world
    parameters naming files (:data:`EXTERNAL_PARAMS`) are read as null."""
    from taskflow.mission.loader import compile_mission
    from taskflow.mission.yamlsrc import load_yaml_file

    path = inside(run_dir, "mission.yaml")
    read_bytes(run_dir, "mission.yaml", MAX_FRAME_BYTES)  # there, a plain file, not too large
    try:
        data, smap, _ = load_yaml_file(path)
        use = _uses(data.get("machine") if isinstance(data, dict) else None, ("machine",))
        if use is not None:
            where = smap.problem(use, "a run record's mission has its sub-missions expanded: this `use:` would "
                                 "read a file outside the record", "a mission.yaml written by taskflow run")
            raise RunDirError(str(where))
        _without_external_files(data)
        return compile_mission(data, smap, None)
    except MissionError as exc:
        first = str(exc.problems[0]) if exc.problems else str(exc)
        raise RunDirError(f"{run_dir}: its mission.yaml no longer loads ({first}) — the record was written by "
                          "a mission this code cannot compile") from None


def load_run(run_dir: str | Path) -> RecordedRun:
    """Read ``run_dir``; :class:`RunDirError` (one line) when it is not a run record, or a malformed or
    hostile one: every file is read inside ``run_dir`` and bounded (:mod:`taskflow.execution.record_io`)."""
    d = Path(run_dir)
    if not (d / "trace.csv").is_file():
        what = ("no such folder" if not d.exists() else
                "a batch folder: use one of its trial-NNNNN folders (taskflow batch --keep-runs)"
                if (d / "batch.json").is_file() else "not a run folder (it has no trace.csv)")
        raise RunDirError(f"{d}: {what}")
    summary = check_summary(read_json(d, "summary.json"), d / "summary.json")
    records = [rec for rec, _, _ in read_transitions(d, complete_only=True)]  # a line cut short by a crash: left out
    trace = read_trace(d)
    mission = _load_mission(d)
    seed = summary.get("seed")
    world_params = mission.world_params(mission.spec.seed if seed is None else seed)
    scene = mission_scene(mission, world_params)
    return RecordedRun(d, trace, [r for r in records if isinstance(r, TransitionRecord)], summary, mission,
                       world_params, scene, dict(mission.metric_units), _command_labels(mission),
                       [r for r in records if isinstance(r, OperatorRecord)], read_frames(d),
                       [r for r in records if isinstance(r, PropertyRecord)])
