"""The web view of a run: what the page (``taskflow/operate/web/``) asks the control endpoint for, as JSON.

The same page serves a live run (``taskflow run --view``: the routes are added to the run's control app,
:mod:`taskflow.operate.control_http`) and a finished one (``taskflow view RUN_DIR``: the same app without a run
loop behind it).  Either way the page reads the run *record* (:mod:`taskflow.execution.records`) — never the run
loop — so serving it costs the loop nothing per tick: the routes read ``trace.csv`` and
``transitions.jsonl`` as the recorder flushes them (every ``flush_every`` ticks, and when the run pauses).

``GET /``                   the page;  ``GET /web/FILE`` its script and style (shipped in the package)
``GET /view/machine``       the compiled state tree with each state's transitions (:func:`machine_json`), the
                            metric units, and the top view of the mission's declared scene
                            (:mod:`taskflow.readers.scene`, as :mod:`taskflow.readers.plots` draws it): the trace columns
                            of the declared ground-truth poses, the markers, and per state the control
                            point its guards measure
``GET /view/trace?since=N`` trace rows ``N …`` (at most :data:`MAX_ROWS`): ``{columns, rows, next, done}``,
                            a row as ``[t, state, events, numbers…]`` (``null`` for NaN)
``GET /view/transitions?since=N``  ``transitions.jsonl`` objects ``N …``: ``{records, next}``
``GET /view/summary``       ``summary.json`` (written at the start as ``aborted``, replaced at the end)
``GET /view/frames?since=N``  ``frames.jsonl`` objects ``N …`` (the camera frames recorded in rendered modes,
                            :mod:`taskflow.execution.frames`): ``{records, next}``
``GET /view/frame?sensor=S&t=T``  the PNG of camera entry ``S`` captured nearest sim time ``T`` (without
                            ``t``: its latest), its capture time in the header ``X-Frame-Stamp`` (s) and
                            its tick's in ``X-Frame-T``; 404 with ``{error}`` when there is none

The record is untrusted input (it may be a colleague's run or a CI artifact): every route reads files
only inside the run directory, bounded (:mod:`taskflow.execution.record_io`), and answers a malformed or hostile
record — a frame whose ``file`` leads outside the folder or is a link out of it, a line too long, a field
of the wrong type — with 422 and ``{error}``, one line naming the file and line, serving nothing of it.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

from taskflow.execution.frames import INDEX as FRAMES_INDEX
from taskflow.execution.frames import FrameRecord, frames_from, nearest, read_frame
from taskflow.execution.record_io import RunDirError, check_summary, lines, read_json
from taskflow.execution.records import OperatorRecord, PropertyRecord, TransitionRecord
from taskflow.markers import Marker
from taskflow.mission import model
from taskflow.mission.guards import Guard, Node
from taskflow.mission.model import CompiledMission, StateNode, Transition
from taskflow.readers.run_files import check_trace_header, parse_trace_row, read_transitions
from taskflow.readers.scene import Scene, mission_scene

WEB_DIR = Path(__file__).resolve().parent / "web"
MAX_ROWS = 4000  # trace rows per answer: a long run arrives in a few requests


class ViewError(ValueError):
    """A run directory the view cannot show: the message says why."""


# -- the machine ---------------------------------------------------------------------------------------


def guard_json(node: Node) -> dict[str, Any]:
    """A parsed guard as the page evaluates it: ``{op: and|or|not, args}`` or ``{metric, abs, cmp, value}``
    (``value`` in the metric's base unit, as the trace holds it; comparisons are :mod:`taskflow.mission.guards`')."""
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
    if isinstance(tr, model.GuardTransition):
        out.update(kind="guard", guard=_guard(tr.guard), dwell=tr.dwell)
    elif isinstance(tr, model.TimeoutTransition):
        out.update(kind="timeout", after=tr.after, since=tr.since.path, since_first=tr.since_first)
    elif isinstance(tr, model.EventTransition):
        out.update(kind="event", event=tr.event, guard=_guard(tr.guard))
    elif isinstance(tr, model.DoneTransition):
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
    (:mod:`taskflow.readers.plots`), from the mission's declared ``scene`` (:func:`taskflow.readers.scene.mission_scene`):
    ``xy`` the trace columns of the robot's ground-truth pose (:attr:`taskflow.api.World.poses`' first
    entry: ``[x, y, yaw]``, yaw ``""`` when not recorded; null without a position), ``bodies`` the other
    declared poses recorded (``{name, x, y}``, world frame), ``markers`` (:func:`marker_json`) and
    ``control_points``: leaf state path → ``{offset: [ahead, left], label}``, the point of the robot its
    guards measure (:class:`~taskflow.markers.ControlPoint`; a state not listed measures the pose itself;
    a row of parallel leaves ``a|b`` takes the first leaf's that declares one, as
    :meth:`taskflow.readers.scene.Scene.control_point`); ``properties`` the declared properties (``{name, pattern,
    description, text}``, in order: :mod:`taskflow.mission.properties`), whose verdicts the page shows."""
    recorded = {name: _pose_columns(keys, gt_names) for name, keys in scene.poses.items()}
    pose = next(iter(recorded.values()), None)
    bodies = [{"name": name, "x": c[0], "y": c[1]} for name, c in list(recorded.items())[1:] if c is not None]
    return {"mission": mission.name, "rate_hz": mission.spec.rate_hz, "root": state_json(mission, mission.root),
            "metric_units": dict(sorted(mission.metric_units.items())),
            "xy": pose, "bodies": bodies, "markers": [marker_json(m) for m in scene.markers],
            "control_points": {state: {"offset": list(cp.offset), "label": cp.label}
                               for state, cp in sorted(scene.control_points.items())},
            "properties": [{"name": p.name, "pattern": p.pattern, "description": p.description,
                            "text": "; ".join(f"{role}: {g.text}" for role, g in p.exprs.items())
                            + (f"; within: {p.within:g} s" if p.within is not None else "")}
                           for p in mission.properties]}


# -- the record, read as it is written ------------------------------------------------------------------


def _json_number(x: Any) -> Any:
    return None if isinstance(x, float) and not math.isfinite(x) else x


class RecordReader:
    """Reads a run directory's ``trace.csv``, ``transitions.jsonl`` and ``frames.jsonl`` incrementally: each call reads only
    the complete lines written since the last one (the recorder may be half-way through a line).  Used
    from the server's one event-loop thread.

    The record is untrusted input (:mod:`taskflow.execution.record_io`): files are read inside the run directory
    only, a line at most :data:`~taskflow.execution.record_io.MAX_LINE_BYTES` long, and every line is parsed by
    the readers' one parse (:func:`taskflow.readers.run_files.parse_trace_row`,
    :func:`taskflow.readers.run_files.record_from_dict`, :func:`taskflow.execution.frames.frame_from_dict`); a malformed or
    hostile one is a :class:`~taskflow.execution.record_io.RunDirError` naming its file and line (the routes answer
    it with 422), and is read again, not skipped, on the next call."""

    def __init__(self, run_dir: Path) -> None:
        self.dir = Path(run_dir)
        self.columns: list[str] = []
        self.rows: list[list[Any]] = []
        self.records: list[TransitionRecord | OperatorRecord | PropertyRecord] = []
        self.frames: list[FrameRecord] = []
        self._offsets = {"trace.csv": 0, "transitions.jsonl": 0, FRAMES_INDEX: 0}
        self._lines = {"trace.csv": 1, "transitions.jsonl": 1, FRAMES_INDEX: 1}

    def present(self, name: str) -> bool:
        """Whether ``name`` is in the run directory (a link counts: reading it decides)."""
        path = self.dir / name
        return path.exists() or path.is_symlink()  # a dangling link is read, and refused, by record_io

    def _trace_lines(self) -> None:
        name = "trace.csv"
        if not self.present(name):
            return
        where = self.dir / name
        for n, text, end in lines(self.dir, name, offset=self._offsets[name], first_line=self._lines[name],
                                  complete_only=True):
            if text:
                cells = next(csv.reader([text]))
                if not self.columns:
                    self.columns = check_trace_header(cells, f"{where}:{n}")
                else:
                    self.rows.append([_json_number(x) for x in parse_trace_row(self.columns, cells, f"{where}:{n}")])
            self._offsets[name], self._lines[name] = end, n + 1

    def refresh(self) -> None:
        self._trace_lines()
        name = "transitions.jsonl"
        if self.present(name):
            for rec, n, end in read_transitions(self.dir, offset=self._offsets[name], first_line=self._lines[name],
                                                complete_only=True):
                self.records.append(rec)
                self._offsets[name], self._lines[name] = end, n + 1
        if self.present(FRAMES_INDEX):
            for frame, n, end in frames_from(self.dir, offset=self._offsets[FRAMES_INDEX],
                                             first_line=self._lines[FRAMES_INDEX]):
                self.frames.append(frame)
                self._offsets[FRAMES_INDEX], self._lines[FRAMES_INDEX] = end, n + 1

    def trace(self, since: int) -> dict[str, Any]:
        self.refresh()
        rows = self.rows[since:since + MAX_ROWS]
        return {"columns": self.columns, "rows": rows, "next": since + len(rows),
                "done": since + len(rows) >= len(self.rows)}

    def transitions(self, since: int) -> dict[str, Any]:
        """``transitions.jsonl`` records ``since …`` as their objects (state changes and operator actions)."""
        self.refresh()
        return {"records": [r.as_dict() for r in self.records[since:]], "next": len(self.records)}

    def frame_records(self, since: int) -> dict[str, Any]:
        self.refresh()
        return {"records": [f.as_dict() for f in self.frames[since:]], "next": len(self.frames)}

    def frame(self, sensor: str, t: float | None) -> tuple[FrameRecord, bytes] | None:
        """The frame of ``sensor`` nearest sim time ``t`` (its latest when None) and its file's bytes; None
        when the sensor has none; a file outside the run directory or too large is a
        :class:`~taskflow.execution.record_io.RunDirError` (:func:`taskflow.execution.frames.read_frame`)."""
        self.refresh()
        rec = nearest(self.frames, sensor, t)
        if rec is None:
            return None
        return rec, read_frame(self.dir, rec)

    def summary(self) -> dict[str, Any]:
        """``summary.json`` (empty until it is on disk), its fields checked
        (:func:`~taskflow.execution.record_io.check_summary`)."""
        if not self.present("summary.json"):
            return {}
        return check_summary(read_json(self.dir, "summary.json"), self.dir / "summary.json")

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
            seed = self.reader.summary().get("seed")
            seed = self.mission.spec.seed if seed is None else seed
            scene = mission_scene(self.mission, self.mission.world_params(seed))
            self._machine = {**machine_json(self.mission, scene, self.reader.gt_names()),
                             "columns_known": bool(self.reader.columns)}
        return {**self._machine, "live": self.live}

    def replay_state(self) -> dict[str, Any]:
        """``GET /state`` of a replay: the run's end as its summary tells it (nothing runs); a summary
        that has turned unreadable gives no outcome and its error as the reason."""
        try:
            s = self.reader.summary()
        except RunDirError as exc:
            s = {"reason": str(exc)}
        return {"mission": self.mission.name, "state": s.get("final_state", ""), "t": s.get("sim_time_s", 0.0),
                "tick": s.get("ticks", 0), "paused": False, "held": False, "outcome": s.get("outcome"),
                "reason": s.get("reason", ""), "running": False, "replay": True}


def open_run(run_dir: str | Path) -> RunView:
    """The view of a finished run directory: its mission is compiled from the record's own
    ``mission.yaml`` (never from a file elsewhere, as the summary's ``file``: the record is untrusted
    input), and the record is read once whole.  Raises :class:`ViewError` (one line) saying what is
    missing or what is wrong, with the file and line."""
    from taskflow.readers.recorded import _load_mission

    d = Path(run_dir)
    if not d.is_dir():
        raise ViewError(f"{d}: no such folder")
    if not (d / "trace.csv").is_file():
        raise ViewError(f"{d}: not a run folder (it has no trace.csv)")
    try:
        view = RunView(_load_mission(d), d, live=False)
        for name in ("summary.json", "transitions.jsonl"):
            if not view.reader.present(name):
                raise RunDirError(f"{d / name}: missing — a run record has it")
        view.reader.refresh()  # the whole record read once: a malformed or hostile one is refused here
        view.reader.summary()
    except RunDirError as exc:
        raise ViewError(str(exc)) from None
    return view
