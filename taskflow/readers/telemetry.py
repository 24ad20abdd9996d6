"""Telemetry export of a run record to MCAP, the container Foxglove and the ROS 2 tools open.

Written with the ``mcap`` library's own writer, every message JSON-encoded against a JSON schema (Foxglove
decodes these without plugins).  Log and publish times are the simulation clock in nanoseconds, so an
export depends only on the record (and two runs with one seed export the same messages).

Topics:

* ``/tf`` — ``foxglove.FrameTransform``: ``world → BODY`` for every planar pose the world declares
  (:attr:`taskflow.api.World.poses`; the robot first), every tick;
* ``/pose/BODY`` — ``foxglove.PoseInFrame`` of the same poses in frame ``world``;
* ``/control_point`` — ``foxglove.PoseInFrame``: the point the active state's guards measure (the car's
  point ``d`` ahead of the rear axle), as :meth:`~taskflow.readers.recorded.RecordedRun.control_track` gives it;
* ``/metrics``, ``/commands``, ``/ground_truth`` — one flat JSON object per tick (``taskflow.Metrics`` …):
  ``state`` (the active leaf), then one number per metric / command component / ground-truth column
  (null where it has no value); each property's schema ``description`` gives its unit;
* ``/transitions`` — ``taskflow.Transition``: one message per change of the active leaf in
  ``transitions.jsonl``, the same fields (``t``, ``from``, ``to``, ``cause``, ``label``, ``metrics``, ``attempt``,
  ``who`` of a pre-emption …);
* ``/operator`` — ``taskflow.OperatorAction``: one message per operator action of ``transitions.jsonl``
  (:class:`~taskflow.execution.records.OperatorRecord`: ``t``, ``tick``, ``action``, ``who``, ``state``, ``args``),
  logged at the tick it took effect;
* ``/scene`` — ``foxglove.SceneUpdate`` at t = 0: the markers of :mod:`taskflow.readers.scene` (goals, waypoints,
  keyframes as spheres; obstacles and walls as line loops);
* ``/camera/SENSOR`` — ``foxglove.CompressedImage``: the camera frames the run recorded (rendered modes,
  :mod:`taskflow.execution.frames`), the PNG base64-encoded in ``data`` as Foxglove's JSON encoding of bytes has it,
  stamped and logged at the image's capture time, ``frame_id`` its camera frame.
"""

from __future__ import annotations

import base64
import json
import math
from pathlib import Path
from typing import IO, Any

from taskflow.execution.frames import FrameRecord, read_frame
from taskflow.mission.data import clean_floats
from taskflow.readers.recorded import RecordedRun, RunDirError, load_run

FORMATS = ("mcap",)
"""Export formats ``taskflow export --format`` and ``taskflow run --record`` accept."""

_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
FRAME_TRANSFORM_SCHEMA = {
    "title": "foxglove.FrameTransform", "type": "object",
    "properties": {"timestamp": _TIME, "parent_frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
                   "translation": _VEC3, "rotation": _QUAT}}
POSE_IN_FRAME_SCHEMA = {
    "title": "foxglove.PoseInFrame", "type": "object",
    "properties": {"timestamp": _TIME, "frame_id": {"type": "string"},
                   "pose": {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}}}
_COLOR = {"type": "object", "properties": {k: {"type": "number"} for k in "rgba"}}
_POSE = {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}
SCENE_UPDATE_SCHEMA = {
    "title": "foxglove.SceneUpdate", "type": "object",
    "properties": {"deletions": {"type": "array", "items": {"type": "object"}}, "entities": {"type": "array", "items": {
        "type": "object", "properties": {
            "timestamp": _TIME, "frame_id": {"type": "string"}, "id": {"type": "string"},
            "frame_locked": {"type": "boolean"},
            "metadata": {"type": "array", "items": {"type": "object", "properties": {
                "key": {"type": "string"}, "value": {"type": "string"}}}},
            "spheres": {"type": "array", "items": {"type": "object", "properties": {
                "pose": _POSE, "size": _VEC3, "color": _COLOR}}},
            "lines": {"type": "array", "items": {"type": "object", "properties": {
                "type": {"type": "integer"}, "pose": _POSE, "thickness": {"type": "number"},
                "scale_invariant": {"type": "boolean"}, "points": {"type": "array", "items": _VEC3},
                "color": _COLOR}}}}}}}}
COMPRESSED_IMAGE_SCHEMA = {
    "title": "foxglove.CompressedImage", "type": "object",
    "properties": {"timestamp": _TIME, "frame_id": {"type": "string"},
                   "data": {"type": "string", "contentEncoding": "base64"}, "format": {"type": "string"}}}
TRANSITION_SCHEMA = {
    "title": "taskflow.Transition", "type": "object",
    "properties": {"t": {"type": "number", "description": "s"}, "from": {"type": "string"}, "to": {"type": "string"},
                   "cause": {"type": "string"}, "state": {"type": "string"}, "label": {"type": "string"},
                   "index": {"type": "integer"}, "metrics": {"type": "object"}, "event": {"type": "string"},
                   "outcome": {"type": "string"}, "item": {"type": "integer"}, "attempt": {"type": "integer"},
                   "resumed": {"type": "boolean"},
                   "who": {"type": "string"}}}
OPERATOR_SCHEMA = {
    "title": "taskflow.OperatorAction", "type": "object",
    "properties": {"t": {"type": "number", "description": "s"}, "tick": {"type": "integer"},
                   "cause": {"type": "string"}, "action": {"type": "string"}, "who": {"type": "string"},
                   "state": {"type": "string"}, "args": {"type": "object"}}}

_ROLE_COLOUR = {"goal": (0.86, 0.08, 0.24), "waypoint": (0.86, 0.08, 0.24), "keyframe": (1.0, 0.55, 0.0),
                "object": (0.1, 0.1, 0.1), "start": (0.4, 0.4, 0.4), "obstacle": (0.18, 0.55, 0.34),
                "boundary": (0.0, 0.0, 0.0)}


def _stamp(t: float) -> dict[str, int]:
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _quat(yaw: float) -> dict[str, float]:
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}


def _flat_schema(title: str, columns: dict[str, str]) -> dict[str, Any]:
    """A flat object: ``state`` and one nullable number per column, its unit as the description."""
    props: dict[str, Any] = {"state": {"type": "string"}}
    for name, unit in columns.items():
        props[name] = {"type": ["number", "null"], "description": unit or "dimensionless"}
    return {"title": title, "type": "object", "properties": props}


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


class _Mcap:
    """The ``mcap`` writer with one JSON-schema channel per topic."""

    def __init__(self, stream: IO[bytes], run: RecordedRun) -> None:
        from mcap.writer import Writer

        self.w = Writer(stream)
        self.w.start(profile="", library="taskflow")
        self.channels: dict[str, int] = {}
        self.w.add_metadata("taskflow.run", {
            "mission": run.mission.name, "seed": str(run.seed), "outcome": str(run.summary.get("outcome")),
            "final_state": str(run.summary.get("final_state")), "file": str(run.summary.get("file", ""))})

    def channel(self, topic: str, schema: dict[str, Any]) -> None:
        sid = self.w.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
        self.channels[topic] = self.w.register_channel(topic, "json", sid)

    def write(self, topic: str, t: float, msg: dict[str, Any]) -> None:
        ns = int(round(t * 1e9))
        self.w.add_message(self.channels[topic], log_time=ns, publish_time=ns,
                           data=json.dumps(msg, allow_nan=False).encode())

    def finish(self) -> None:
        self.w.finish()  # type: ignore[no-untyped-call]  # mcap's Writer.finish has no annotations


def _scene_update(run: RecordedRun) -> dict[str, Any]:
    entities = []
    for i, m in enumerate(run.scene.markers):
        r, g, b = _ROLE_COLOUR[m.role]
        colour = {"r": r, "g": g, "b": b, "a": 0.8}
        ent: dict[str, Any] = {"timestamp": _stamp(0.0), "frame_id": "world", "id": f"{m.role}-{i}",
                               "frame_locked": True, "metadata": [{"key": "label", "value": m.label}],
                               "spheres": [], "lines": []}
        identity = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": _quat(0.0)}
        if len(m.points) == 1:
            (x, y), = m.points
            d = 2 * m.radius if m.radius else 0.08
            ent["spheres"].append({"pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": _quat(m.yaw or 0.0)},
                                   "size": {"x": d, "y": d, "z": d}, "color": colour})
        else:
            ent["lines"].append({"type": 2 if m.closed else 0, "pose": identity, "thickness": 0.02,
                                 "scale_invariant": False, "color": colour,
                                 "points": [{"x": x, "y": y, "z": 0.0} for x, y in m.points]})
        entities.append(ent)
    return {"deletions": [], "entities": entities}


def write_mcap(run: RecordedRun, out: str | Path) -> Path:
    """Write ``run`` as MCAP to ``out`` (module docstring); returns the path."""
    out = Path(out)
    tr = run.trace
    t, states = tr["t"], tr["state"]
    metrics = {m: run.metric_units.get(m, "") for m in run.metric_columns()}
    commands = {run.command_labels.get(c, (c[4:], ""))[0]: c for c in tr if c.startswith("cmd.")}
    gts = [c for c in tr if c.startswith("gt.")]
    bodies = {b: run.pose_track(b) for b in run.scene.poses}
    tracks = {b: v for b, v in bodies.items() if v is not None}
    cx, cy = run.control_track()
    frames = run.frames
    with open(out, "wb") as f:
        mc = _Mcap(f, run)
        mc.channel("/tf", FRAME_TRANSFORM_SCHEMA)
        for b in tracks:
            mc.channel(f"/pose/{b}", POSE_IN_FRAME_SCHEMA)
        if tracks:
            mc.channel("/control_point", POSE_IN_FRAME_SCHEMA)
        mc.channel("/metrics", _flat_schema("taskflow.Metrics", metrics))
        mc.channel("/commands", _flat_schema("taskflow.Commands",
                                             {k: run.command_labels.get(c, ("", ""))[1] for k, c in commands.items()}))
        mc.channel("/ground_truth", _flat_schema("taskflow.GroundTruth", {c[3:]: "" for c in gts}))
        mc.channel("/transitions", TRANSITION_SCHEMA)
        mc.channel("/operator", OPERATOR_SCHEMA)
        mc.channel("/scene", SCENE_UPDATE_SCHEMA)
        for sensor in dict.fromkeys(fr.sensor for fr in frames):
            mc.channel(f"/camera/{sensor}", COMPRESSED_IMAGE_SCHEMA)
        mc.write("/scene", 0.0, _scene_update(run))
        pending = list(run.transitions)
        operator = list(run.operator)
        images = list(frames)
        for i in range(t.size):
            ti = float(t[i])
            while operator and operator[0].t <= ti + 1e-9:
                mc.write("/operator", operator[0].t, operator.pop(0).as_dict())
            while pending and pending[0].t <= ti + 1e-9:
                mc.write("/transitions", pending[0].t, clean_floats(pending.pop(0).as_dict()))
            while images and images[0].t <= ti + 1e-9:
                _write_image(mc, run, images.pop(0))
            stamp = _stamp(ti)
            for b, (x, y, yaw) in tracks.items():
                if not (math.isfinite(x[i]) and math.isfinite(y[i])):
                    continue
                q = _quat(float(yaw[i]) if yaw is not None and math.isfinite(yaw[i]) else 0.0)
                mc.write("/tf", ti, {"timestamp": stamp, "parent_frame_id": "world", "child_frame_id": b,
                                     "translation": {"x": float(x[i]), "y": float(y[i]), "z": 0.0}, "rotation": q})
                mc.write(f"/pose/{b}", ti, {"timestamp": stamp, "frame_id": "world", "pose": {
                    "position": {"x": float(x[i]), "y": float(y[i]), "z": 0.0}, "orientation": q}})
                if b == next(iter(tracks)) and math.isfinite(cx[i]):
                    mc.write("/control_point", ti, {"timestamp": stamp, "frame_id": "world", "pose": {
                        "position": {"x": float(cx[i]), "y": float(cy[i]), "z": 0.0}, "orientation": q}})
            state = str(states[i])
            mc.write("/metrics", ti, {"state": state, **{m: _num(tr[f"m.{m}"][i]) for m in metrics}})
            mc.write("/commands", ti, {"state": state, **{k: _num(tr[c][i]) for k, c in commands.items()}})
            mc.write("/ground_truth", ti, {"state": state, **{c[3:]: _num(tr[c][i]) for c in gts}})
        for op in operator:
            mc.write("/operator", op.t, op.as_dict())
        for rec in pending:
            mc.write("/transitions", rec.t, clean_floats(rec.as_dict()))
        for fr in images:
            _write_image(mc, run, fr)
        mc.finish()
    return out


def _write_image(mc: _Mcap, run: RecordedRun, fr: FrameRecord) -> None:
    """One recorded frame as ``foxglove.CompressedImage`` on ``/camera/SENSOR`` at its capture time."""
    data = read_frame(run.dir, fr)
    mc.write(f"/camera/{fr.sensor}", fr.stamp, {"timestamp": _stamp(fr.stamp), "frame_id": fr.frame,
                                               "data": base64.b64encode(data).decode("ascii"),
                                               "format": Path(fr.file).suffix[1:]})


def export_run(run_dir: str | Path, fmt: str = "mcap", out: str | Path | None = None) -> Path:
    """Export the run directory ``run_dir`` in ``fmt`` (default file: ``RUN_DIR/telemetry.mcap``)."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} — valid: {', '.join(FORMATS)}")
    run = load_run(run_dir)
    path = Path(out) if out is not None else run.dir / f"telemetry.{fmt}"
    try:
        return write_mcap(run, path)
    except RunDirError:  # a recorded frame refused half-way (record_io): no partial export stays
        path.unlink(missing_ok=True)
        raise


__all__ = ["FORMATS", "export_run", "write_mcap"]
