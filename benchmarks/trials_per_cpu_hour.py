"""Trials per CPU-hour of every shipped mission, measured by ``taskflow batch`` itself (issue 24).

For each ``missions/*.yaml`` (or the stems named), ``taskflow batch MISSION --trials N --workers W`` in its fast
perception mode (:func:`physics_floor.fast_overrides`: ``geometric`` / ``pose``), and from the campaign's
``timing.json`` the trials' CPU time (each trial's ``cpu_s``: its process's CPU from loading the mission to writing
its records) — ``per_trial_cpu_s`` and ``trials_per_cpu_hour``, figures that depend on neither the number of cores
nor what else the machine runs —, beside the wall time, the simulated seconds a trial and the success rate.

Run: ``python benchmarks/trials_per_cpu_hour.py [--trials 4] [--workers 2] [--out DIR] [STEM ...]``.  One line per
mission, then a JSON line with all of them.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from physics_floor import MISSIONS, fast_overrides

from taskflow.execution.provenance import versions


def measure(stem: str, trials: int, workers: int, out: Path) -> dict[str, Any]:
    sets = [a for o in fast_overrides(stem) for a in ("--set", o)]
    cmd = [sys.executable, "-m", "taskflow.cli", "batch", str(MISSIONS / f"{stem}.yaml"), "--trials", str(trials),
           "--workers", str(workers), "--out", str(out / stem), *sets]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if not (out / stem / "timing.json").exists():
        raise SystemExit(f"{stem}: taskflow batch wrote no timing.json (exit {proc.returncode}): {proc.stderr[-500:]}")
    timing = json.loads((out / stem / "timing.json").read_text())
    batch = json.loads((out / stem / "batch.json").read_text())
    agg = batch["aggregate"]
    sim = agg["metrics"].get("sim_time_s", {}).get("mean")
    return {"mission": stem, "perception": fast_overrides(stem), "trials": timing["trials_run"],
            "workers": timing["workers"], "per_trial_cpu_s": timing.get("per_trial_cpu_s"),
            "trials_per_cpu_hour": timing.get("trials_per_cpu_hour"), "total_wall_s": timing["total_wall_s"],
            "sim_time_s_mean": sim, "success_rate": agg["success_rate"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stems", nargs="*", help="mission file stems (default: every shipped mission)")
    ap.add_argument("--trials", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="where the campaigns go (default: a temporary folder)")
    args = ap.parse_args()
    stems = args.stems or sorted(p.stem for p in MISSIONS.glob("*.yaml"))
    out = args.out or Path(tempfile.mkdtemp(prefix="tpch-"))
    rows = []
    print(f"{'mission':36s} {'trials':>6s} {'CPU s/trial':>11s} {'trials/CPU-h':>12s} {'sim s':>7s} {'success':>8s}")
    for stem in stems:
        r = measure(stem, args.trials, args.workers, out)
        rows.append(r)
        print(f"{stem:36s} {r['trials']:6d} {r['per_trial_cpu_s']:11.2f} {r['trials_per_cpu_hour']:12.0f} "
              f"{r['sim_time_s_mean'] or 0:7.1f} {100 * r['success_rate']:7.0f}%", flush=True)
    print(json.dumps({"rows": rows, "trials": args.trials, "workers": args.workers, "versions": versions()}))


if __name__ == "__main__":
    main()
