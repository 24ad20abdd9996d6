"""What recording camera frames costs a rendered run: ``taskflow run --frames 0`` against ``--frames HZ``.

Both arms run the same rendered mission and seed (default: the quadcopter's pose regulation, perception
``rendered``, 320x240 camera at 25 Hz, the control at 25 Hz) for ``--max-time`` simulated seconds; the arms
alternate, ``--repeats`` times each; each run's real-time factor comes from its ``timing.json``.  Also
timed in-process, on a frame of the recorded run: :meth:`taskflow.execution.frames.FrameRecorder.offer` on a tick
with no frame due (µs), and one frame encoded and written (ms).  ``ratio`` is median RTF with frames /
without.

Usage: ``python benchmarks/frames_overhead.py [--mission M] [--set K=V] [--hz 2] [--max-time 10] [--repeats 3]``.
The last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def one_run(mission: str, sets: list[str], out: Path, hz: float, max_time: float) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "taskflow.cli", "run", mission, "--out", str(out), "--quiet", "--seed", "0",
           "--no-control", "--max-time", str(max_time), "--frames", str(hz)]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT, check=False)
    timing = json.loads((out / "timing.json").read_text())
    frames = out / "frames.jsonl"
    return {"hz": hz, "rtf": timing["real_time_factor"], "tick_ms_mean": timing["tick_ms"]["mean"],
            "frames": len(frames.read_text().splitlines()) if frames.is_file() else 0,
            "frames_bytes": sum(f.stat().st_size for f in (out / "frames").rglob("*.png"))}


def micro(run_dir: Path) -> dict[str, float]:
    """``offer`` with no frame due (µs) and one frame written (ms), on the run's first recorded image."""
    import cv2

    from taskflow.execution.frames import FrameRecorder, read_frames
    from taskflow.messages import Image

    first = read_frames(run_dir)[0]
    px = np.ascontiguousarray(cv2.imread(str(run_dir / first.file), cv2.IMREAD_COLOR)[:, :, ::-1])
    with tempfile.TemporaryDirectory() as tmp:
        rec = FrameRecorder(Path(tmp), 1.0)
        sensors = {"image": Image(stamp=0.0, frame="camera", pixels=px)}
        rec.offer(0.0, 0, sensors)
        n = 200_000
        t0 = time.perf_counter()
        for k in range(n):
            rec.offer(0.5, k, sensors)
        idle_us = (time.perf_counter() - t0) / n * 1e6
        writes = []
        for k in range(1, 41):
            t0 = time.perf_counter()
            rec.offer(float(k), k, {"image": Image(stamp=float(k), frame="camera", pixels=px)})
            writes.append(time.perf_counter() - t0)
        rec.close()
    return {"offer_idle_us": idle_us, "frame_write_ms": 1e3 * statistics.median(writes),
            "frame_px": f"{px.shape[1]}x{px.shape[0]}"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mission", default="missions/visual_path_pose_regulation.yaml")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--hz", type=float, default=2.0)
    ap.add_argument("--max-time", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeats):
            for hz in ((0.0, args.hz) if k % 2 == 0 else (args.hz, 0.0)):  # alternate which goes first
                r = one_run(args.mission, args.set, Path(tmp) / f"{k}-{hz}", hz, args.max_time)
                runs.append(r)
                print(json.dumps(r), flush=True)
        m = micro(Path(tmp) / f"0-{args.hz}")
    plain = statistics.median(r["rtf"] for r in runs if r["hz"] == 0)
    framed = statistics.median(r["rtf"] for r in runs if r["hz"] != 0)
    print(json.dumps({"mission": args.mission, "set": args.set, "hz": args.hz, "max_time": args.max_time,
                      "repeats": args.repeats, "rtf_no_frames": plain, "rtf_frames": framed,
                      "ratio": framed / plain, **m, "date": time.strftime("%Y-%m-%d"),
                      "python": platform.python_version(), "taskflow": metadata.version("taskflow"),
                      "opencv": metadata.version("opencv-python-headless"), "pybullet": metadata.version("pybullet"),
                      "numpy": metadata.version("numpy")}))


if __name__ == "__main__":
    main()
