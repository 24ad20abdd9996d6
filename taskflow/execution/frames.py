"""Camera frames in the run record: what a rendered world's cameras showed, at a modest declared rate.

``RUN_DIR/``
  ``frames/SENSOR/TICK.png``  one PNG per recorded frame of the observation entry ``SENSOR`` (the key of
                              :attr:`Observation.sensors` that holds a :class:`taskflow.messages.Image`:
                              ``image`` for ``quad_room``, ``viki_ground`` and ``screw_conveyor`` in their
                              rendered perception modes), ``TICK`` the index
                              of the control tick that saw it (six digits)
  ``frames.jsonl``            one JSON object per frame written (:class:`FrameRecord`): ``t`` (the tick's
                              sim time), ``tick``, ``sensor``, ``stamp`` (the image's capture time),
                              ``frame`` (its camera frame), ``width``, ``height`` and ``file`` (relative to
                              the run directory)

Which ticks record a frame is decided by simulation time alone: frame ``n`` is due at ``n / hz`` s and
taken by the first tick at or after it, so two runs with one seed write the same files byte for byte
(PNG is lossless and OpenCV's encoder deterministic).  Only top-level :class:`Image` entries are recorded
(a tuple of keyframe images is the mission's input, not what the camera saw), and an image already
written (same stamp) is not written again when the camera runs slower than ``hz``.  A world that puts no
image in its observation writes nothing, so the rate can stay on by default (:data:`DEFAULT_HZ`).

A tick with no frame due costs one comparison.  Each frame is on disk, and its line in ``frames.jsonl``
flushed, before the run goes on: an interrupted or failed run keeps the frames written so far.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from taskflow.messages import Image

DEFAULT_HZ = 2.0
"""Frames per simulated second ``taskflow run`` records when the world observes images (``--frames``)."""
INDEX = "frames.jsonl"
FOLDER = "frames"
FORMAT = "png"


@dataclass(frozen=True)
class FrameRecord:
    """One recorded frame (a line of ``frames.jsonl``)."""

    t: float  # sim time of the control tick that saw it (s)
    tick: int
    sensor: str  # the observation key
    stamp: float  # the image's capture time (s)
    frame: str  # the camera's coordinate frame
    width: int
    height: int
    file: str  # relative to the run directory

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def images_in(sensors: Mapping[str, Any]) -> list[tuple[str, Image]]:
    """The observation's top-level camera images, ``(key, image)`` sorted by key."""
    return sorted((k, v) for k, v in sensors.items() if isinstance(v, Image))


def encode(image: Image) -> bytes:
    """``image`` as PNG bytes (RGB in, so swapped to OpenCV's BGR; grey as is)."""
    import cv2

    px: NDArray[Any] = np.ascontiguousarray(image.pixels)
    if px.ndim == 3:
        px = cv2.cvtColor(px, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(f".{FORMAT}", px)
    if not ok:
        raise ValueError(f"OpenCV could not encode a {px.shape} {px.dtype} image as {FORMAT}")
    return buf.tobytes()


class FrameRecorder:
    """Writes the frames of one run at ``hz`` frames per simulated second (module docstring)."""

    def __init__(self, run_dir: Path, hz: float) -> None:
        if not (math.isfinite(hz) and hz > 0):
            raise ValueError(f"frame rate {hz!r} — valid: a positive number of frames per simulated second")
        self.dir = Path(run_dir)
        self.hz = float(hz)
        self.count = 0
        self._due = 0.0  # sim time of the next frame
        self._last: dict[str, float] = {}  # sensor → stamp last written
        self._index: Any = None  # frames.jsonl, opened with the first frame

    def offer(self, t: float, tick: int, sensors: Mapping[str, Any]) -> None:
        """Called every control tick with its observation's sensors: records their images when one is due."""
        if t < self._due - 1e-9:
            return
        self._due = (math.floor(t * self.hz + 1e-9) + 1) / self.hz
        for name, image in images_in(sensors):
            if self._last.get(name) == image.stamp:
                continue
            self._write(t, tick, name, image)

    def _write(self, t: float, tick: int, name: str, image: Image) -> None:
        rel = f"{FOLDER}/{name}/{tick:06d}.{FORMAT}"
        path = self.dir / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(encode(image))
        width, height = image.size
        rec = FrameRecord(t=round(t, 9), tick=tick, sensor=name, stamp=round(float(image.stamp), 9),
                          frame=image.frame, width=width, height=height, file=rel)
        if self._index is None:
            self._index = open(self.dir / INDEX, "w")  # noqa: SIM115 - open for the whole run, closed by close()
        self._index.write(json.dumps(rec.as_dict()) + "\n")
        self._index.flush()
        self._last[name] = image.stamp
        self.count += 1

    def close(self) -> None:
        if self._index is not None:
            self._index.close()
            self._index = None


_FIELDS: dict[str, tuple[type, ...]] = {"t": (int, float), "tick": (int,), "sensor": (str,), "stamp": (int, float),
                                       "frame": (str,), "width": (int,), "height": (int,), "file": (str,)}


def frame_from_dict(d: Any, run_dir: Path) -> FrameRecord:
    """One line of ``frames.jsonl`` (parsed JSON) as its :class:`FrameRecord`; :class:`ValueError` when a
    field is missing or of another type, or ``file`` is not a file inside ``run_dir``
    (:func:`taskflow.execution.record_io.inside`)."""
    from taskflow.execution.record_io import RunDirError, inside

    if not isinstance(d, dict):
        raise ValueError(f"a JSON object was expected, got {type(d).__name__}")
    for key, types in _FIELDS.items():
        v = d.get(key)
        if key not in d or isinstance(v, bool) or not isinstance(v, types):
            raise ValueError(f"{key!r} is {type(v).__name__ if key in d else 'missing'} — "
                             f"{'a number' if float in types else types[0].__name__} was expected")
    extra = sorted(set(d) - set(_FIELDS))
    if extra:
        raise ValueError(f"unknown field {extra[0][:40]!r} — valid: {', '.join(_FIELDS)}")
    if not d["file"].endswith(f".{FORMAT}"):
        raise ValueError(f"file {d['file'][:60]!r} — a frame is a .{FORMAT} file (frames/SENSOR/TICK.{FORMAT})")
    try:
        inside(run_dir, d["file"])
    except RunDirError:
        raise ValueError(f"file {d['file'][:60]!r} leads outside the run directory — a frame is a file inside "
                         "it (frames/SENSOR/TICK.png)") from None
    return FrameRecord(**d)


def read_frames(run_dir: str | Path, *, offset: int = 0, first_line: int = 1) -> list[FrameRecord]:
    """The frames a run recorded, in the order written (empty when it recorded none).  Read as untrusted
    input (:mod:`taskflow.execution.record_io`): a line of another shape, or one whose ``file`` leads outside the
    run directory, is a :class:`~taskflow.execution.record_io.RunDirError` naming it; a last line cut short by a
    crash (no newline) is left out."""
    return [rec for rec, _, _ in frames_from(Path(run_dir), offset=offset, first_line=first_line)]


def frames_from(run_dir: Path, *, offset: int = 0, first_line: int = 1) -> list[tuple[FrameRecord, int, int]]:
    """:func:`read_frames` from byte ``offset``, each record with its line number and the offset after it."""
    from taskflow.execution.record_io import RunDirError, json_line, lines

    if not (run_dir / INDEX).exists() and not (run_dir / INDEX).is_symlink():
        return []
    where = run_dir / INDEX
    out = []
    for n, text, end in lines(run_dir, INDEX, offset=offset, first_line=first_line, complete_only=True):
        if not text.strip():
            continue
        try:
            out.append((frame_from_dict(json_line(f"{where}:{n}", text), run_dir), n, end))
        except RunDirError:
            raise
        except ValueError as exc:
            raise RunDirError(f"{where}:{n}: {exc}") from None
    return out


def read_frame(run_dir: Path, rec: FrameRecord) -> bytes:
    """The bytes of a recorded frame's file: inside ``run_dir``, at most
    :data:`~taskflow.execution.record_io.MAX_FRAME_BYTES` (:class:`~taskflow.execution.record_io.RunDirError` otherwise)."""
    from taskflow.execution.record_io import MAX_FRAME_BYTES, read_bytes

    return read_bytes(run_dir, rec.file, MAX_FRAME_BYTES)


def nearest(frames: list[FrameRecord], sensor: str, t: float | None) -> FrameRecord | None:
    """The frame of ``sensor`` whose capture time is nearest ``t`` (an earlier one on a tie), or its
    latest when ``t`` is None; None when the sensor has no frame."""
    best: FrameRecord | None = None
    for f in frames:
        if f.sensor != sensor:
            continue
        if best is None or t is None or abs(f.stamp - t) < abs(best.stamp - t) - 1e-12:
            best = f
    return best


__all__ = ["DEFAULT_HZ", "FrameRecord", "FrameRecorder", "encode", "frame_from_dict", "frames_from", "images_in",
           "nearest", "read_frame", "read_frames"]
