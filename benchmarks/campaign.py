"""Campaign throughput: trials per hour of one mission on 1 and 2 local workers and on a local Ray
cluster of two single-CPU worker nodes, the scaling efficiency, and Ray's overhead per trial.

The three runs are the same campaign (``--trials`` seeds of ``--mission``, default the ViKi-HyCo
complete placement in geometric perception) through :func:`taskflow.campaigns.batch.run_batch`:

* ``pool_1`` — the trials one after another in this process (``--workers 1``);
* ``pool_2`` — a local process pool of two workers;
* ``ray_2x1`` — a Ray cluster started here for the benchmark: a head node without CPUs and two worker
  nodes of one CPU each, every node its own ``ray start`` process (what ``ray start --head`` and
  ``ray start --address`` do on separate machines); its start-up is timed apart.

Trials per hour = trials / wall time of the batch (3600 x), start-up included.  Scaling efficiency =
throughput on two workers / (2 x throughput on one).  From each trial's wall-clock stamps
(``timing.json``: ``started``/``ended`` around the trial in its worker): the start-up of each batch
(batch start to the first trial's start: process spawn, or Ray connect and worker start) and the idle
gap of a worker between two consecutive trials.  Ray's overhead per trial = Ray's mean gap − the
pool's (what Ray adds per trial at the same parallelism: scheduling, result transfer), also as a
fraction of a trial's wall time alone (the one-worker batch); and, without a simulation, the round
trip of an empty task on each (Ray task vs pool future).  ``contention_2_workers`` = a trial's wall
time with two workers / alone: 1.0 on two free CPUs; on a shared machine it shows how much of the
missing scaling is other load.  The three campaigns' ``batch.json`` are compared byte for byte (same seeds →
same results whatever the backend).  Wall-clock figures depend on the load of the machine: the
1-minute load average before and after is printed.

Usage: ``python benchmarks/campaign.py [--trials 8] [--mission missions/viki_hyco.yaml] [--out DIR]``;
the last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from taskflow.campaigns.backends import LocalRayCluster
from taskflow.campaigns.batch import run_batch

ROOT = Path(__file__).resolve().parents[1]


def _noop(x: int) -> int:
    return x


def pool_round_trip_ms(n: int = 200) -> float:
    """Median ms to submit an empty call to a warm two-worker pool and get its result."""
    with ProcessPoolExecutor(max_workers=2) as pool:
        pool.submit(_noop, 0).result()
        ts = []
        for i in range(n):
            t0 = time.perf_counter()
            pool.submit(_noop, i).result()
            ts.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(ts)


def ray_round_trip_ms(address: str, n: int = 200) -> float:
    """Median ms for an empty Ray task (one CPU) on the cluster, submitted and fetched one at a time."""
    import ray

    ray.init(address=address, logging_level="WARNING", log_to_driver=False)
    try:
        task = ray.remote(num_cpus=1)(_noop)
        ray.get([task.remote(i) for i in range(4)])  # workers started
        ts = []
        for i in range(n):
            t0 = time.perf_counter()
            ray.get(task.remote(i))
            ts.append(time.perf_counter() - t0)
    finally:
        ray.shutdown()
    return 1e3 * statistics.median(ts)


def _figures(result: dict[str, Any]) -> dict[str, Any]:
    """Throughput, and from the trials' wall-clock stamps: the start-up (batch start to the first trial's
    start) and the idle gap a worker spends between the end of one trial and the start of its next (the
    backend's cost per trial: result transfer, recording, scheduling)."""
    n = len(result["trials"])
    timing = result["timing"]
    wall = timing["total_wall_s"]
    trials = timing["trials"]
    by_worker: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for t in trials:
        by_worker.setdefault((t["host"], t["pid"]), []).append(t)
    gaps = [b["started"] - a["ended"] for ts in by_worker.values()
            for a, b in zip(sorted(ts, key=lambda t: t["started"]), sorted(ts, key=lambda t: t["started"])[1:])]
    return {"trials": n, "wall_s": wall, "trials_per_hour": 3600.0 * n / wall,
            "mean_trial_wall_s": statistics.mean(t["ended"] - t["started"] for t in trials),
            "startup_s": min(t["started"] for t in trials) - timing["started"],
            "mean_gap_between_trials_s": statistics.mean(gaps) if gaps else None, "gaps": len(gaps),
            "worker_processes": len(by_worker), "success_rate": result["aggregate"]["success_rate"],
            "workers": timing["workers"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mission", default=str(ROOT / "missions" / "viki_hyco.yaml"))
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", default=None, help="directory for the three batch directories (default: a temp dir)")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="campaign-bench-"))
    load_before = os.getloadavg()[0]
    common = dict(trials=args.trials, seed=args.seed, overrides=args.set)
    res: dict[str, dict[str, Any]] = {}
    files: dict[str, bytes] = {}
    for name, workers in (("pool_1", 1), ("pool_2", 2)):
        r = run_batch(args.mission, workers=workers, out=out / name, **common)
        res[name], files[name] = _figures(r), Path(r["batch_file"]).read_bytes()
        print(f"  {name}: {res[name]['trials_per_hour']:.0f} trials/h ({res[name]['wall_s']:.1f} s)", flush=True)
    t0 = time.perf_counter()
    cluster = LocalRayCluster(nodes=2, cpus_per_node=1).start(timeout=120)
    cluster_start = time.perf_counter() - t0
    try:
        with cluster.driver_env():
            r = run_batch(args.mission, backend="ray", address=cluster.address, out=out / "ray_2x1", **common)
            res["ray_2x1"], files["ray_2x1"] = _figures(r), Path(r["batch_file"]).read_bytes()
            print(f"  ray_2x1: {res['ray_2x1']['trials_per_hour']:.0f} trials/h ({res['ray_2x1']['wall_s']:.1f} s; "
                  f"cluster start {cluster_start:.1f} s)", flush=True)
            ray_rt = ray_round_trip_ms(cluster.address)
    finally:
        cluster.stop()
    pool_rt = pool_round_trip_ms()
    thr1, thr2, thr_ray = (res[k]["trials_per_hour"] for k in ("pool_1", "pool_2", "ray_2x1"))
    trial_s = res["pool_1"]["mean_trial_wall_s"]  # a trial alone on the machine's CPUs
    gap_ray, gap_pool = res["ray_2x1"]["mean_gap_between_trials_s"], res["pool_2"]["mean_gap_between_trials_s"]
    overhead_s = gap_ray - gap_pool if gap_ray is not None and gap_pool is not None else None
    summary = {
        "mission": Path(args.mission).name, "overrides": args.set, "trials": args.trials,
        "trials_per_hour": {"pool_1": thr1, "pool_2": thr2, "ray_2x1": thr_ray},
        "scaling_efficiency_pool": thr2 / (2 * thr1), "scaling_efficiency_ray": thr_ray / (2 * thr1),
        "mean_trial_wall_s": trial_s, "ray_overhead_per_trial_s": overhead_s,
        "ray_overhead_fraction_of_trial": None if overhead_s is None else overhead_s / trial_s,
        "contention_2_workers": res["pool_2"]["mean_trial_wall_s"] / trial_s,
        "empty_task_round_trip_ms": {"pool": pool_rt, "ray": ray_rt},
        "ray_cluster_start_s": cluster_start,
        "same_batch_json": files["pool_1"] == files["pool_2"] == files["ray_2x1"],
        "loadavg_1min": [load_before, os.getloadavg()[0]], "cpus": os.cpu_count(), "runs": res, "out": str(out),
    }
    print()
    print(f"{'configuration':12s} {'trials/h':>9s} {'wall s':>8s} {'trial s':>8s} {'start-up s':>10s} {'gap ms':>8s}")
    for k, v in res.items():
        gap = "-" if v["mean_gap_between_trials_s"] is None else f"{1e3 * v['mean_gap_between_trials_s']:.1f}"
        print(f"{k:12s} {v['trials_per_hour']:9.0f} {v['wall_s']:8.1f} {v['mean_trial_wall_s']:8.2f} "
              f"{v['startup_s']:10.2f} {gap:>8s}")
    print(f"scaling efficiency 1 -> 2 workers: pool {100 * summary['scaling_efficiency_pool']:.0f} %, "
          f"Ray {100 * summary['scaling_efficiency_ray']:.0f} % (target >= 90 %)")
    if overhead_s is not None:
        print(f"Ray overhead per trial vs the pool (worker idle gap between trials): {1e3 * overhead_s:.1f} ms = "
              f"{100 * overhead_s / trial_s:.2f} % of a trial (target <= 10 %); empty task round trip: Ray "
              f"{ray_rt:.2f} ms, pool {pool_rt:.2f} ms")
    print(f"a trial takes {summary['contention_2_workers']:.2f}x as long with two workers as alone "
          "(1.0 when the two CPUs are free; the scaling efficiency cannot exceed its inverse)")
    print(f"batch.json identical on the three: {summary['same_batch_json']}; load average {load_before:.1f} -> "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
