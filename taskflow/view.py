"""The web view of a run: what the page (``taskflow/web/``) asks the control endpoint for, as JSON.

The same page serves a live run (``taskflow run --view``: the routes are added to the run's control app,
:mod:`taskflow.control_http`) and a finished one (``taskflow view RUN_DIR``: the same app without a run
loop behind it).  Either way the page reads the run *record* (:mod:`taskflow.records`) — never the run
loop — so serving it costs the loop nothing per tick: the routes read ``trace.csv`` and
``transitions.jsonl`` as the recorder flushes them (every ``flush_every`` ticks, and when the run pauses).

``GET /``                   the page;  ``GET /web/FILE`` its script and style (shipped in the package)
``GET /view/machine``       the compiled state tree with each state's transitions (:func:`machine_json`), the
                            metric units, the trace columns of the robot's ground-truth pose and of
                            other bodies' positions (:data:`BODIES`), and the points the mission's
                            parameters name (waypoints, keyframes, the room)
``GET /view/trace?since=N`` trace rows ``N …`` (at most :data:`MAX_ROWS`): ``{columns, rows, next, done}``,
                            a row as ``[t, state, events, numbers…]`` (``null`` for NaN)
``GET /view/transitions?since=N``  ``transitions.jsonl`` objects ``N …``: ``{records, next}``
``GET /view/summary``       ``summary.json`` (written at the start as ``aborted``, replaced at the end)
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .guards import Guard, Node
from .model import (CompiledMission, DoneTransition, EventTransition, GuardTransition, StateNode,
                    TimeoutTransition, Transition)

WEB_DIR = Path(__file__).resolve().parent / "web"
MAX_ROWS = 4000  # trace rows per answer: a long run arrives in a few requests
XY_KEYS = (("x", "y", "yaw"), ("base_x", "base_y", "base_yaw"))  # robot pose columns (gt.*), first match wins
BODIES = (("obj", "robot"), ("part", "world"))
"""Other bodies' ground-truth position columns (``gt.NAME_x``, ``gt.NAME_y``) and their frame, as the shipped
worlds document them: ``viki_ground``'s object in the robot frame, ``screw_conveyor``'s part in the world."""


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


def _point(v: Any) -> tuple[float, float] | None:
    if isinstance(v, dict):
        v = v.get("pose", v.get("xy", v.get("position")))
    if isinstance(v, (list, tuple)) and len(v) >= 2 and all(isinstance(a, (int, float)) for a in v[:2]):
        return float(v[0]), float(v[1])
    return None


def markers(resolved: dict[str, Any]) -> list[dict[str, Any]]:
    """Points to draw on the top view, where the mission states them simply in the world frame: every list
    of two or more ``[x, y, …]`` (or ``{pose: [x, y, …]}``) among the world's parameters and the
    mission's ``parameters`` (waypoints, keyframes), and a ``room`` ``{x0, x1, y0, y1}``.  Points given in
    the robot's frame (a single ``goal``) are not guessed at."""
    out: list[dict[str, Any]] = []
    world = resolved.get("world")
    sources = [("world", world.get("params") or {} if isinstance(world, dict) else {}),
               ("parameters", resolved.get("parameters") or {})]
    seen: set[tuple[tuple[float, float], ...]] = set()
    for where, params in sources:
        if not isinstance(params, dict):
            continue
        for key, value in params.items():
            if key == "room" and isinstance(value, dict) and {"x0", "x1", "y0", "y1"} <= set(value):
                out.append({"name": key, "kind": "box", "from": where,
                            "box": [float(value[k]) for k in ("x0", "x1", "y0", "y1")]})
            elif isinstance(value, list) and len(value) >= 2:
                pts = [_point(v) for v in value]
                if all(p is not None for p in pts):
                    key_pts = tuple(pts)  # type: ignore[arg-type]
                    if key_pts not in seen:  # a YAML anchor shared by world and parameters: once
                        seen.add(key_pts)
                        out.append({"name": key, "kind": "points", "from": where, "points": [list(p) for p in key_pts]})
    return out


def machine_json(mission: CompiledMission, resolved: dict[str, Any], gt_names: list[str]) -> dict[str, Any]:
    """``GET /view/machine``: the state tree, the metric units, the ground-truth pose columns of the robot
    (``xy``: ``[x, y, yaw]``, yaw ``""`` when not recorded; null without a position), other bodies
    (:data:`BODIES`: ``{name, x, y, frame}``) and the markers of the top view."""
    pose = next(([f"gt.{a}" for a in k] for k in XY_KEYS if all(f"gt.{a}" in gt_names for a in k[:2])), None)
    if pose is not None and pose[2] not in gt_names:
        pose[2] = ""
    bodies = [{"name": name, "x": f"gt.{name}_x", "y": f"gt.{name}_y", "frame": frame} for name, frame in BODIES
              if f"gt.{name}_x" in gt_names and f"gt.{name}_y" in gt_names and (frame == "world" or pose and pose[2])]
    return {"mission": mission.name, "rate_hz": mission.spec.rate_hz, "root": state_json(mission, mission.root),
            "metric_units": dict(sorted(mission.metric_units.items())),
            "xy": pose, "bodies": bodies, "markers": markers(resolved)}


# -- the record, read as it is written ------------------------------------------------------------------


def _number(text: str) -> float | None:
    try:
        x = float(text)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


class RecordReader:
    """Reads a run directory's ``trace.csv`` and ``transitions.jsonl`` incrementally: each call reads only
    the complete lines written since the last one (the recorder may be half-way through a line).  Used
    from the server's one event-loop thread."""

    def __init__(self, run_dir: Path) -> None:
        self.dir = Path(run_dir)
        self.columns: list[str] = []
        self.rows: list[list[Any]] = []
        self.records: list[dict[str, Any]] = []
        self._offsets = {"trace.csv": 0, "transitions.jsonl": 0}

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

    def trace(self, since: int) -> dict[str, Any]:
        self.refresh()
        rows = self.rows[since:since + MAX_ROWS]
        return {"columns": self.columns, "rows": rows, "next": since + len(rows),
                "done": since + len(rows) >= len(self.rows)}

    def transitions(self, since: int) -> dict[str, Any]:
        self.refresh()
        return {"records": self.records[since:], "next": len(self.records)}

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
    """What the page of one run is served from: its mission (compiled), its resolved document and its record."""

    def __init__(self, mission: CompiledMission, run_dir: Path, live: bool) -> None:
        self.mission = mission
        self.reader = RecordReader(run_dir)
        self.live = live
        self._machine: dict[str, Any] | None = None

    def machine(self) -> dict[str, Any]:
        """:func:`machine_json`, computed once the trace's header is on disk (a live run writes it with its
        first block of rows; until then the ground-truth columns are unknown: ``columns_known`` false)."""
        if self._machine is None or not self._machine["columns_known"]:
            resolved = self.mission.raw
            try:
                import yaml

                resolved = yaml.safe_load((self.reader.dir / "mission.yaml").read_text()) or resolved
            except (OSError, ValueError):
                pass
            self._machine = {**machine_json(self.mission, resolved, self.reader.gt_names()),
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
