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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .messages import Image

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

    px = np.ascontiguousarray(image.pixels)
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
            self._index = open(self.dir / INDEX, "w")
        self._index.write(json.dumps(rec.as_dict()) + "\n")
        self._index.flush()
        self._last[name] = image.stamp
        self.count += 1

    def close(self) -> None:
        if self._index is not None:
            self._index.close()
            self._index = None


def read_frames(run_dir: str | Path) -> list[FrameRecord]:
    """The frames a run recorded, in the order written (empty when it recorded none)."""
    path = Path(run_dir) / INDEX
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        if line.strip():
            try:
                out.append(FrameRecord(**json.loads(line)))
            except (ValueError, TypeError):
                break  # a line cut short by a crash: the frames before it stand
    return out


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


__all__ = ["DEFAULT_HZ", "FrameRecord", "FrameRecorder", "encode", "images_in", "nearest", "read_frames"]
