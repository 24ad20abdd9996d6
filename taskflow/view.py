"""The web view of a run: what the page (``taskflow/web/``) asks the control endpoint for, as JSON.

The same page serves a live run (``taskflow run --view``: the routes are added to the run's control app,
:mod:`taskflow.control_http`) and a finished one (``taskflow view RUN_DIR``: the same app without a run
loop behind it).  Either way the page reads the run *record* (:mod:`taskflow.records`) — never the run
loop — so serving it costs the loop nothing per tick: the routes read ``trace.csv`` and
``transitions.jsonl`` as the recorder flushes them (every ``flush_every`` ticks, and when the run pauses).

``GET /``                   the page;  ``GET /web/FILE`` its script and style (shipped in the package)
``GET /view/machine``       the compiled state tree with each state's transitions (:func:`machine_json`), the
                            metric units, and the top view of the mission's declared scene
                            (:mod:`taskflow.scene`, as :mod:`taskflow.plots` draws it): the trace columns
                            of the declared ground-truth poses, the markers, and per state the control
                            point its guards measure
``GET /view/trace?since=N`` trace rows ``N …`` (at most :data:`MAX_ROWS`): ``{columns, rows, next, done}``,
                            a row as ``[t, state, events, numbers…]`` (``null`` for NaN)
``GET /view/transitions?since=N``  ``transitions.jsonl`` objects ``N …``: ``{records, next}``
``GET /view/summary``       ``summary.json`` (written at the start as ``aborted``, replaced at the end)
``GET /view/frames?since=N``  ``frames.jsonl`` objects ``N …`` (the camera frames recorded in rendered modes,
                            :mod:`taskflow.frames`): ``{records, next}``
``GET /view/frame?sensor=S&t=T``  the PNG of camera entry ``S`` captured nearest sim time ``T`` (without
                            ``t``: its latest), its capture time in the header ``X-Frame-Stamp`` (s) and
                            its tick's in ``X-Frame-T``; 404 with ``{error}`` when there is none
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .frames import INDEX as FRAMES_INDEX, FrameRecord, nearest
from .guards import Guard, Node
from .markers import Marker
from .model import (CompiledMission, DoneTransition, EventTransition, GuardTransition, StateNode,
                    TimeoutTransition, Transition)
from .scene import Scene, mission_scene

WEB_DIR = Path(__file__).resolve().parent / "web"
MAX_ROWS = 4000  # trace rows per answer: a long run arrives in a few requests


class ViewError(ValueError):
    """A run directory the view cannot show: the message says why."""


# -- the machine ---------------------------------------------------------------------------------------


def guard_json(node: Node) -> dict[str, Any]:
    """A parsed guard as the page evaluates it: ``{op: and|or|not, args}`` or ``{metric, abs, cmp, value}``
    (``value`` in the metric's base unit, as the trace holds it; comparisons are :mod:`taskflow.guards`')."""
    if node.cmp is not None:
        c = node.cmp
        return {"metric": c.metric, "abs": c.absolute, "cmp": c.op, "value": c.value, "param": c.param}
    return {"op": node.kind, "args": [guard_json(k) for k in node.children]}


def _guard(guard: Guard | None) -> dict[str, Any] | None:
    return None if guard is None else {"text": guard.text, "tree": guard_json(guard.tree),
                                       "metrics": sorted(guard.metrics)}


def transition_json(tr: Transition) -> dict[str, Any]:
    """One compiled transition: where it leads, its kind and what the page needs to show its progress."""
    out: dict[str, Any] = {"index": tr.index, "source": tr.source.path, "target": tr.target.path,
                           "label": tr.label}
    if isinstance(tr, GuardTransition):
        out.update(kind="guard", guard=_guard(tr.guard), dwell=tr.dwell)
    elif isinstance(tr, TimeoutTransition):
        out.update(kind="timeout", after=tr.after, since=tr.since.path, since_first=tr.since_first)
    elif isinstance(tr, EventTransition):
        out.update(kind="event", event=tr.event, guard=_guard(tr.guard))
    elif isinstance(tr, DoneTransition):
        out.update(kind="done", outcome=tr.outcome)
    return out


def state_json(mission: CompiledMission, node: StateNode) -> dict[str, Any]:
    """A state and its sub-states: ``kind`` is leaf, final, composite or parallel; ``region`` marks a
    parallel state's child."""
    kind = "parallel" if node.parallel else "composite" if node.children else "final" if node.final else "leaf"
    out: dict[str, Any] = {"name": node.name or mission.name, "path": node.path, "kind": kind,
                           "initial": node.initial, "region": node.owns is not None,
                           "transitions": [transition_json(t) for t in node.transitions],
                           "children": [state_json(mission, c) for c in node.children.values()]}
    if node.final:
        out["outcome"] = node.final
    if node.task_cls is not None and node.is_leaf:
        out["task"] = getattr(node.task_cls, "name", node.task_cls.__name__)
    if node.action is not None:
        out["action"] = node.action[0]
    if node.loop is not None:
        out["loop"] = f"foreach {node.loop.item} in {node.loop.items}"
    if node.history:
        out["history"] = True
    if node.path:
        out["description"] = mission.description_of(node)
    return out


def marker_json(m: Marker) -> dict[str, Any]:
    """One declared scene marker (:class:`~taskflow.markers.Marker`): ``kind`` its role, ``label``,
    ``points`` ``[[x, y], …]`` in the world frame (m), ``closed`` (a polygon), ``yaw`` (rad) and ``radius``
    (m), null when not given."""
    return {"kind": m.role, "label": m.label, "points": [list(p) for p in m.points], "closed": m.closed,
            "yaw": m.yaw, "radius": m.radius}


def _pose_columns(keys: tuple[str, str, str | None], gt_names: list[str]) -> list[str] | None:
    """The trace columns ``[gt.x, gt.y, gt.yaw]`` of a declared pose (yaw ``""`` when not recorded), None
    when its position is not in the trace."""
    x, y, yaw = (f"gt.{k}" if k else "" for k in keys)
    if x not in gt_names or y not in gt_names:
        return None
    return [x, y, yaw if yaw in gt_names else ""]


def machine_json(mission: CompiledMission, scene: Scene, gt_names: list[str]) -> dict[str, Any]:
    """``GET /view/machine``: the state tree, the metric units and the top view as the figures draw it
    (:mod:`taskflow.plots`), from the mission's declared ``scene`` (:func:`taskflow.scene.mission_scene`):
    ``xy`` the trace columns of the robot's ground-truth pose (:attr:`taskflow.api.World.poses`' first
    entry: ``[x, y, yaw]``, yaw ``""`` when not recorded; null without a position), ``bodies`` the other
    declared poses recorded (``{name, x, y}``, world frame), ``markers`` (:func:`marker_json`) and
    ``control_points``: leaf state path → ``{offset: [ahead, left], label}``, the point of the robot its
    guards measure (:class:`~taskflow.markers.ControlPoint`; a state not listed measures the pose itself;
    a row of parallel leaves ``a|b`` takes the first leaf's that declares one, as
    :meth:`taskflow.scene.Scene.control_point`)."""
    recorded = {name: _pose_columns(keys, gt_names) for name, keys in scene.poses.items()}
    pose = next(iter(recorded.values()), None)
    bodies = [{"name": name, "x": c[0], "y": c[1]} for name, c in list(recorded.items())[1:] if c is not None]
    return {"mission": mission.name, "rate_hz": mission.spec.rate_hz, "root": state_json(mission, mission.root),
            "metric_units": dict(sorted(mission.metric_units.items())),
            "xy": pose, "bodies": bodies, "markers": [marker_json(m) for m in scene.markers],
            "control_points": {state: {"offset": list(cp.offset), "label": cp.label}
                               for state, cp in sorted(scene.control_points.items())}}


# -- the record, read as it is written ------------------------------------------------------------------


def _number(text: str) -> float | None:
    try:
        x = float(text)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


class RecordReader:
    """Reads a run directory's ``trace.csv``, ``transitions.jsonl`` and ``frames.jsonl`` incrementally: each call reads only
    the complete lines written since the last one (the recorder may be half-way through a line).  Used
    from the server's one event-loop thread."""

    def __init__(self, run_dir: Path) -> None:
        self.dir = Path(run_dir)
        self.columns: list[str] = []
        self.rows: list[list[Any]] = []
        self.records: list[dict[str, Any]] = []
        self.frames: list[FrameRecord] = []
        self._offsets = {"trace.csv": 0, "transitions.jsonl": 0, FRAMES_INDEX: 0}

    def _new_lines(self, name: str) -> list[str]:
        try:
            with open(self.dir / name, "rb") as f:
                f.seek(self._offsets[name])
                data = f.read()
        except FileNotFoundError:
            return []
        end = data.rfind(b"\n") + 1
        self._offsets[name] += end
        return data[:end].decode().splitlines()

    def refresh(self) -> None:
        lines = self._new_lines("trace.csv")
        if lines and not self.columns:
            self.columns = lines.pop(0).split(",")
        for line in lines:
            cells = line.split(",")
            self.rows.append([float(cells[0]), cells[1], cells[2], *map(_number, cells[3:])])
        for line in self._new_lines("transitions.jsonl"):
            if line.strip():
                self.records.append(json.loads(line))
        for line in self._new_lines(FRAMES_INDEX):
            if line.strip():
                self.frames.append(FrameRecord(**json.loads(line)))

    def trace(self, since: int) -> dict[str, Any]:
        self.refresh()
        rows = self.rows[since:since + MAX_ROWS]
        return {"columns": self.columns, "rows": rows, "next": since + len(rows),
                "done": since + len(rows) >= len(self.rows)}

    def transitions(self, since: int) -> dict[str, Any]:
        self.refresh()
        return {"records": self.records[since:], "next": len(self.records)}

    def frame_records(self, since: int) -> dict[str, Any]:
        self.refresh()
        return {"records": [f.as_dict() for f in self.frames[since:]], "next": len(self.frames)}

    def frame(self, sensor: str, t: float | None) -> tuple[FrameRecord, bytes] | None:
        """The frame of ``sensor`` nearest sim time ``t`` (its latest when None) and its file's bytes."""
        self.refresh()
        rec = nearest(self.frames, sensor, t)
        if rec is None:
            return None
        try:
            return rec, (self.dir / rec.file).read_bytes()
        except OSError:
            return None

    def summary(self) -> dict[str, Any]:
        try:
            return dict(json.loads((self.dir / "summary.json").read_text()))
        except (OSError, ValueError):
            return {}

    def gt_names(self) -> list[str]:
        """The trace's ground-truth columns (``gt.NAME``); empty until its header is on disk."""
        self.refresh()
        return [c for c in self.columns if c.startswith("gt.")]


class RunView:
    """What the page of one run is served from: its mission (compiled) and its record."""

    def __init__(self, mission: CompiledMission, run_dir: Path, live: bool) -> None:
        self.mission = mission
        self.reader = RecordReader(run_dir)
        self.live = live
        self._machine: dict[str, Any] | None = None

    def machine(self) -> dict[str, Any]:
        """:func:`machine_json`, computed once the trace's header is on disk (a live run writes it with its
        first block of rows; until then the ground-truth columns are unknown: ``columns_known`` false).
        The scene is the mission's with the world parameters drawn for the run's seed (its summary's)."""
        if self._machine is None or not self._machine["columns_known"]:
            seed = int(self.reader.summary().get("seed", self.mission.spec.seed))
            scene = mission_scene(self.mission, self.mission.world_params(seed))
            self._machine = {**machine_json(self.mission, scene, self.reader.gt_names()),
                             "columns_known": bool(self.reader.columns)}
        return {**self._machine, "live": self.live}

    def replay_state(self) -> dict[str, Any]:
        """``GET /state`` of a replay: the run's end as its summary tells it (nothing runs)."""
        s = self.reader.summary()
        return {"mission": self.mission.name, "state": s.get("final_state", ""), "t": s.get("sim_time_s", 0.0),
                "tick": s.get("ticks", 0), "paused": False, "held": False, "outcome": s.get("outcome"),
                "reason": s.get("reason", ""), "running": False, "replay": True}


def open_run(run_dir: str | Path) -> RunView:
    """The view of a finished run directory: its mission is compiled from the record's ``mission.yaml``
    (else from the file the summary names).  Raises :class:`ViewError` saying what is missing."""
    from .errors import MissionError
    from .loader import load_mission

    d = Path(run_dir)
    if not d.is_dir():
        raise ViewError(f"{d}: no such folder")
    if not (d / "trace.csv").is_file():
        what = ("a batch folder: view one of its trial-NNNNN folders (taskflow batch --keep-runs)"
                if (d / "batch.json").is_file() else "not a run folder (it has no trace.csv)")
        raise ViewError(f"{d}: {what}")
    tried: list[str] = []
    candidates = [d / "mission.yaml"]
    file = RecordReader(d).summary().get("file")
    if file:
        candidates.append(Path(file))
    for path in candidates:
        if not path.is_file():
            continue
        try:
            return RunView(load_mission(path), d, live=False)
        except MissionError as exc:
            tried.append(f"{path}: {exc.problems[0] if exc.problems else exc}")
    raise ViewError(f"{d}: the run's mission does not load ({'; '.join(tried) or 'no mission.yaml'})")
