"""Monte Carlo batches: N independent seeded runs in parallel processes.

Trial ``i`` runs with seed ``seed + i``: its world parameters are drawn from the distributions the
mission declares and its sensors' noise from the same seed, each in its own process with its own
PyBullet DIRECT client.  ``batch.json`` holds every trial's summary and the aggregates.
"""

from __future__ import annotations

import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from .records import clean_floats, write_json


def _trial(args: tuple[str, list[str], int, str | None, float | None]) -> dict[str, Any]:
    path, overrides, seed, out, max_time = args
    from .loader import load_mission
    from .runtime import run_mission

    mission = load_mission(path, overrides)
    out_dir = None if out is None else Path(out) / f"trial-{seed:05d}"
    t0 = time.perf_counter()
    result = run_mission(mission, seed=seed, out_dir=out_dir, max_time=max_time, record=out_dir is not None)
    summary = dict(result.summary)
    summary["trial_wall_s"] = time.perf_counter() - t0
    return summary


def aggregate(summaries: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate, outcome counts and mean/std/min/max of every numeric final metric."""
    n = len(summaries)
    outcomes: dict[str, int] = {}
    for s in summaries:
        outcomes[s["outcome"]] = outcomes.get(s["outcome"], 0) + 1
    stats: dict[str, dict[str, float]] = {}
    keys = sorted({k for s in summaries for k, v in s.get("metrics", {}).items()
                   if isinstance(v, (int, float)) and not isinstance(v, bool)})
    for k in keys:
        vals = np.array([s["metrics"][k] for s in summaries
                         if isinstance(s.get("metrics", {}).get(k), (int, float)) and s["metrics"][k] is not None
                         and math.isfinite(s["metrics"][k])], dtype=float)
        if vals.size:
            stats[k] = {"mean": float(vals.mean()), "std": float(vals.std()), "min": float(vals.min()),
                        "max": float(vals.max()), "n": int(vals.size)}
    for k in ("sim_time_s", "wall_time_s"):
        vals = np.array([s[k] for s in summaries], dtype=float)
        if vals.size:
            stats[k] = {"mean": float(vals.mean()), "std": float(vals.std()), "min": float(vals.min()),
                        "max": float(vals.max()), "n": int(vals.size)}
    return {"trials": n, "success_rate": outcomes.get("succeeded", 0) / n if n else 0.0,
            "outcomes": outcomes, "metrics": stats}


def run_batch(path: str, *, trials: int, workers: int | None = None, seed: int = 0,
              overrides: list[str] | None = None, out: str | Path | None = None,
              max_time: float | None = None, keep_runs: bool = False) -> dict[str, Any]:
    """Run the trials, write ``batch.json`` under ``out`` and return its content."""
    from .loader import load_mission

    if trials < 1:
        raise ValueError("--trials must be at least 1")
    mission = load_mission(path, overrides)
    out_dir = Path(out) if out is not None else Path("runs") / f"batch-{mission.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir.mkdir(parents=True, exist_ok=True)
    workers = max(1, min(workers or os.cpu_count() or 1, trials))
    run_root = str(out_dir) if keep_runs else None
    jobs = [(path, list(overrides or []), seed + i, run_root, max_time) for i in range(trials)]
    t0 = time.perf_counter()
    if workers == 1:
        summaries = [_trial(j) for j in jobs]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            summaries = list(pool.map(_trial, jobs))
    wall = time.perf_counter() - t0
    result = {
        "mission": mission.name, "file": path, "overrides": list(overrides or []), "first_seed": seed,
        "workers": workers, "total_wall_s": wall, "per_trial_wall_s": wall / trials,
        "aggregate": aggregate(summaries), "trials": summaries,
    }
    result = clean_floats(result)
    batch_file = out_dir / "batch.json"
    write_json(batch_file, result)
    result["batch_file"] = str(batch_file)
    return result


def format_table(result: dict[str, Any]) -> str:
    agg = result["aggregate"]
    lines = [f"{result['mission']}: {agg['trials']} trials, success {100 * agg['success_rate']:.1f} %  "
             f"outcomes {json.dumps(agg['outcomes'])}  wall {result['total_wall_s']:.1f} s "
             f"({result['workers']} workers)",
             f"{'metric':34s} {'mean':>12s} {'std':>12s} {'min':>12s} {'max':>12s}"]
    for k, s in agg["metrics"].items():
        lines.append(f"{k:34s} {s['mean']:12.5g} {s['std']:12.5g} {s['min']:12.5g} {s['max']:12.5g}")
    return "\n".join(lines)
