"""What serving the web view costs a live run: ``taskflow run`` with and without ``--view``.

Both arms run the same mission and seed with the control endpoint open (its default); the ``view`` arm
adds ``--view`` and a headless Chromium (the distribution's, driven by selenium) that opens the page as
soon as the run prints its address and keeps polling it (every 0.4 s: ``/state``, new trace rows and
transition records) until the run ends.  The arms alternate, ``--repeats`` times each; the real-time
factor of each run comes from its ``timing.json``.  ``ratio`` is median RTF with the view / without (the
issue's bound: ≥ 0.95, i.e. at most 5 % slower).

Usage: ``python benchmarks/view_overhead.py [--mission missions/viki_hyco.yaml] [--set K=V] [--repeats 3]``.
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

ROOT = Path(__file__).resolve().parent.parent


def _browser() -> Any:
    from taskflow.testing import headless_chromium

    return headless_chromium()


def one_run(mission: str, sets: list[str], out: Path, view: bool, browser: Any) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "taskflow.cli", "run", mission, "--out", str(out), "--quiet", "--seed", "0"]
    for s in sets:
        cmd += ["--set", s]
    if view:
        cmd.append("--view")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    polls = 0
    assert proc.stderr is not None
    for line in proc.stderr:
        if view and line.startswith("view: "):
            browser.get(line.split()[1])
            break
    if view:  # the page polls on its own; count its answers until the run ends
        while proc.poll() is None:
            polls += 1
            time.sleep(0.4)
    proc.wait()
    timing = json.loads((out / "timing.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    return {"view": view, "rtf": timing["real_time_factor"], "wall_s": timing["wall_time_s"],
            "sim_s": summary["sim_time_s"], "outcome": summary["outcome"],
            "page_rows": browser.execute_script("return window.taskflowView ? taskflowView.S.rows.length : 0") if view else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mission", default="missions/viki_hyco.yaml")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    browser = _browser()
    runs: list[dict[str, Any]] = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.repeats):
                for view in ((False, True) if k % 2 == 0 else (True, False)):  # alternate which goes first
                    r = one_run(args.mission, args.set, Path(tmp) / f"{k}-{int(view)}", view, browser)
                    runs.append(r)
                    print(json.dumps(r), flush=True)
    finally:
        browser.quit()
    plain = statistics.median(r["rtf"] for r in runs if not r["view"])
    viewed = statistics.median(r["rtf"] for r in runs if r["view"])
    print(json.dumps({"mission": args.mission, "set": args.set, "repeats": args.repeats, "rtf_plain": plain,
                      "rtf_view": viewed, "ratio": viewed / plain, "date": time.strftime("%Y-%m-%d"),
                      "python": platform.python_version(), "taskflow": metadata.version("taskflow"),
                      "selenium": metadata.version("selenium"), "uvicorn": metadata.version("uvicorn"),
                      "starlette": metadata.version("starlette")}))


if __name__ == "__main__":
    main()
