"""Monte Carlo batches: N independent seeded runs in parallel processes.

Trial ``i`` runs with seed ``seed + i``: its world parameters are drawn from the distributions the
mission declares and its sensors' noise from the same seed, each in its own process with its own
PyBullet DIRECT client.  ``batch.json`` holds every trial's summary and the aggregates: mission success
and, for missions that loop over items (screws, waypoints), item success beside it.  Wall-clock figures
live under ``timing`` only, so the rest of ``batch.json`` depends on the mission and the seeds alone.

Ctrl-C or SIGTERM stops a batch at once: unfinished trials are cancelled, running workers are
terminated, and ``batch.json`` is written with the trials that finished (``interrupted: true``).
"""

from __future__ import annotations

import json
import math
import os
import signal
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

import numpy as np

from .records import clean_floats, write_json


class BatchInterrupted(Exception):
    """Raised inside the parent on SIGTERM so the batch ends like on Ctrl-C."""


def _worker_init() -> None:
    # Ctrl-C reaches every process of the terminal's group: only the parent decides what happens, and
    # ends a worker with SIGTERM (a run in progress then records itself as aborted)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _trial(args: tuple[str, list[str], int, str | None, float | None]) -> tuple[dict[str, Any], dict[str, Any]]:
    path, overrides, seed, out, max_time = args
    from .loader import load_mission
    from .runtime import run_mission

    mission = load_mission(path, overrides)
    out_dir = None if out is None else Path(out) / f"trial-{seed:05d}"
    result = run_mission(mission, seed=seed, out_dir=out_dir, max_time=max_time, record=out_dir is not None,
                         frames_hz=0)  # kept trials hold no camera frames: ~100 KB each, times every trial
    return result.summary, {"seed": seed, "wall_time_s": result.timing.get("wall_time_s"),
                            "real_time_factor": result.timing.get("real_time_factor")}


def _stats(vals: np.ndarray) -> dict[str, float]:
    return {"mean": float(vals.mean()), "std": float(vals.std()), "min": float(vals.min()),
            "max": float(vals.max()), "n": int(vals.size)}


def aggregate(summaries: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate, outcome counts, item success per foreach loop, and mean/std/min/max of every
    numeric final metric."""
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
            stats[k] = _stats(vals)
    vals = np.array([s["sim_time_s"] for s in summaries], dtype=float)
    if vals.size:
        stats["sim_time_s"] = _stats(vals)
    items: dict[str, dict[str, Any]] = {}
    for s in summaries:
        for loop, c in s.get("items", {}).items():
            agg = items.setdefault(loop, {"attempted": 0, "succeeded": 0, "rule": c.get("rule")})
            agg["attempted"] += c["attempted"]
            agg["succeeded"] += c["succeeded"]
    for agg in items.values():
        agg["failed"] = agg["attempted"] - agg["succeeded"]
        agg["success_rate"] = agg["succeeded"] / agg["attempted"] if agg["attempted"] else None
    return {"trials": n, "success_rate": outcomes.get("succeeded", 0) / n if n else 0.0,
            "outcomes": outcomes, "items": items, "metrics": stats}


def run_batch(path: str, *, trials: int, workers: int | None = None, seed: int = 0,
              overrides: list[str] | None = None, out: str | Path | None = None,
              max_time: float | None = None, keep_runs: bool = False) -> dict[str, Any]:
    """Run the trials, write ``batch.json`` under ``out`` and return its content.  On Ctrl-C / SIGTERM
    the partial ``batch.json`` is written and :class:`KeyboardInterrupt` is raised again."""
    from .loader import load_mission

    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    mission = load_mission(path, overrides)
    out_dir = Path(out) if out is not None else Path("runs") / f"batch-{mission.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir.mkdir(parents=True, exist_ok=True)
    workers = max(1, min(workers or os.cpu_count() or 1, trials))
    run_root = str(out_dir) if keep_runs else None
    jobs = [(path, list(overrides or []), seed + i, run_root, max_time) for i in range(trials)]
    done: dict[int, tuple[dict[str, Any], dict[str, Any]]] = {}
    t0 = time.perf_counter()
    interrupted: BaseException | None = None
    old_term = _on_sigterm()
    try:
        if workers == 1:
            from .runtime import INTERRUPTED, TERMINATED

            for i, job in enumerate(jobs):
                summary, timing = _trial(job)
                if summary.get("reason") in (INTERRUPTED, TERMINATED):
                    # the run in this process saw the signal and stopped itself: the batch ends here too,
                    # without counting the cut trial (as a worker's trial cut by the pool is not counted)
                    raise KeyboardInterrupt()
                done[i] = (summary, timing)
        else:
            _run_pool(jobs, workers, done)
    except (KeyboardInterrupt, BatchInterrupted) as exc:
        interrupted = exc
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    wall = time.perf_counter() - t0
    finished = [done[i] for i in sorted(done)]
    summaries = [s for s, _ in finished]
    result = {
        "mission": mission.name, "file": path, "overrides": list(overrides or []), "first_seed": seed,
        "trials_requested": trials, "interrupted": interrupted is not None,
        "aggregate": aggregate(summaries), "trials": summaries,
        "timing": {"workers": workers, "total_wall_s": wall, "per_trial_wall_s": wall / max(1, len(finished)),
                   "trials": [t for _, t in finished]},
    }
    result = clean_floats(result)
    batch_file = out_dir / "batch.json"
    write_json(batch_file, result)
    result["batch_file"] = str(batch_file)
    if interrupted is not None:
        raise KeyboardInterrupt(str(batch_file)) from None
    return result


def _run_pool(jobs: list[tuple[Any, ...]], workers: int, done: dict[int, Any]) -> None:
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_worker_init)
    futures: dict[Future[Any], int] = {pool.submit(_trial, job): i for i, job in enumerate(jobs)}
    try:
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in finished:
                done[futures[f]] = f.result()
    except BaseException:
        # stop now: nothing new starts, and the running trials are ended (their workers terminated)
        for proc in list(getattr(pool, "_processes", {}).values()):  # no public API before Python 3.14
            proc.terminate()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _on_sigterm() -> Any:
    def handler(signum: int, frame: Any) -> None:
        raise BatchInterrupted()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        return None


def format_table(result: dict[str, Any]) -> str:
    agg, timing = result["aggregate"], result.get("timing", {})
    head = (f"{result['mission']}: {agg['trials']} trials, success {100 * agg['success_rate']:.1f} %  "
            f"outcomes {json.dumps(agg['outcomes'])}  wall {timing.get('total_wall_s', 0):.1f} s "
            f"({timing.get('workers', '?')} workers)")
    if result.get("interrupted"):
        head += f"  INTERRUPTED after {agg['trials']} of {result.get('trials_requested')}"
    lines = [head]
    for loop, c in agg.get("items", {}).items():
        rate = c["success_rate"]
        lines.append(f"items of {loop}: {c['succeeded']}/{c['attempted']} succeeded"
                     + (f" ({100 * rate:.1f} %)" if rate is not None else "") + f", rule per run: {c['rule']}")
    lines.append(f"{'metric':34s} {'mean':>12s} {'std':>12s} {'min':>12s} {'max':>12s}")
    for k, s in agg["metrics"].items():
        lines.append(f"{k:34s} {s['mean']:12.5g} {s['std']:12.5g} {s['min']:12.5g} {s['max']:12.5g}")
    return "\n".join(lines)
