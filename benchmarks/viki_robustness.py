"""ViKi-HyCo complete placement on held-out conditions: bearing, distance, dropout rate and burst length.

One command regenerates the robustness table of BENCHMARKS.md ("ViKi-HyCo on held-out conditions"):
each row is one ``taskflow.campaigns.batch.run_batch`` campaign of ``missions/viki_hyco.yaml`` (trial ``i`` with
seed ``seed + i``; the object's kind and yaw, and whatever the row leaves to the mission, drawn per
trial) with the row's world parameters set.  Reported from the simulator's ground truth per row:
success with its Wilson 95 % interval, the trials that touched the object (``contact``), the smallest
car-object clearance over all trials (``min_clearance_m``), the mean |X| / |Y| final error (cm) and the
failures by final state.

Rows (``--rows`` picks some by name):

* ``shipped``: the mission as shipped (bearing ±0.15 rad, 2.0–2.6 m, 15 % dropout in bursts of 1.5);
* ``bearing-0.45`` / ``bearing+0.45``: the object at -0.45 / +0.45 rad;
* ``near`` / ``far``: the object 1.1 m / 3.6 m away at a bearing drawn in ±0.45 rad;
* ``dropout30`` / ``dropout50``: 30 % / 50 % of the frames missed (bursts of 1.5 frames);
* ``burst5`` / ``burst15``: 50 % missed in bursts of 5 / 15 frames;
* ``edge+0.48`` / ``edge-0.48``: the object at the edge of the front view at the start (issue 25): bearing
  drawn in 0.44–0.52 rad to the left / right, distance in 1.5–2.6 m — its box starts cut by the image border;
* ``worst``: everything at once — bearing ±0.45 rad, 1.1–3.6 m, 50 % dropout in 15-frame bursts.

``--set KEY=VALUE`` applies to every row (e.g. ``--set world.params.fidelity=paper``, or
``--set machine.states.forward.task.params.target_update=first`` for the paper's fixed target).

Usage: ``python benchmarks/viki_robustness.py --trials 20 --workers 2 [--rows near far] [--out DIR]``;
the last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import taskflow_sim.viki.world  # noqa: F401  registers viki_ground (forked batch workers inherit it)
import taskflow_tasks.viki.hyco
import taskflow_tasks.viki.rotation  # noqa: F401  registers viki_rotate

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.stats import wilson_interval

MISSION = Path(__file__).resolve().parents[1] / "missions" / "viki_hyco.yaml"
WIDE_BEARING = "world.params.object_bearing={uniform: [-0.45, 0.45]}"
EDGE_DISTANCE = "world.params.object_distance={uniform: [1.5, 2.6]}"

ROWS: dict[str, tuple[str, list[str]]] = {
    "shipped": ("as shipped", []),
    "bearing-0.45": ("bearing -0.45 rad", ["world.params.object_bearing=-0.45"]),
    "bearing+0.45": ("bearing +0.45 rad", ["world.params.object_bearing=0.45"]),
    "near": ("1.1 m, bearing in ±0.45 rad", ["world.params.object_distance=1.1", WIDE_BEARING]),
    "far": ("3.6 m, bearing in ±0.45 rad", ["world.params.object_distance=3.6", WIDE_BEARING]),
    "dropout30": ("dropout 30 %, bursts 1.5", ["world.params.dropout=0.3"]),
    "dropout50": ("dropout 50 %, bursts 1.5", ["world.params.dropout=0.5"]),
    "burst5": ("dropout 50 %, bursts 5", ["world.params.dropout=0.5", "world.params.dropout_burst=5"]),
    "burst15": ("dropout 50 %, bursts 15", ["world.params.dropout=0.5", "world.params.dropout_burst=15"]),
    "edge+0.48": ("edge of the front view, left: 0.44 to 0.52 rad, 1.5-2.6 m",
                  ["world.params.object_bearing={uniform: [0.44, 0.52]}", EDGE_DISTANCE]),
    "edge-0.48": ("edge of the front view, right: -0.52 to -0.44 rad, 1.5-2.6 m",
                  ["world.params.object_bearing={uniform: [-0.52, -0.44]}", EDGE_DISTANCE]),
    "worst": ("±0.45 rad, 1.1-3.6 m, 50 % in bursts of 15",
              [WIDE_BEARING, "world.params.object_distance={uniform: [1.1, 3.6]}", "world.params.dropout=0.5",
               "world.params.dropout_burst=15"]),
}


def row_stats(result: dict[str, Any]) -> dict[str, Any]:
    """Success [Wilson 95 %], contacts, smallest clearance, mean |X| |Y| and failures of one batch."""
    trials = result["trials"]
    ok = sum(t["outcome"] == "succeeded" for t in trials)
    m = [t["metrics"] for t in trials]
    clear = [x["min_clearance_m"] for x in m if isinstance(x.get("min_clearance_m"), (int, float))]
    fails: dict[str, int] = {}
    for t in trials:
        if t["outcome"] != "succeeded":
            fails[t["final_state"]] = fails.get(t["final_state"], 0) + 1
    return {
        "trials": len(trials), "succeeded": ok, "success_ci95": list(wilson_interval(ok, len(trials))),
        "contacts": sum(bool(x.get("contact")) for x in m),
        "min_clearance_m": min(clear) if clear else None,
        "abs_x_mean": float(np.mean([abs(x["final_error_x_m"]) for x in m])),
        "abs_y_mean": float(np.mean([abs(x["final_error_y_m"]) for x in m])),
        "failures": fails, "failed_seeds": [t["seed"] for t in trials if t["outcome"] != "succeeded"],
        "wall_s": result["timing"]["total_wall_s"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rows", nargs="*", choices=list(ROWS), default=list(ROWS))
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="override for every row (repeatable)")
    ap.add_argument("--out", default=None, help="directory for the batch files (default: a temp dir)")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="viki-robust-"))
    results: dict[str, Any] = {}
    t0 = time.perf_counter()
    for name in args.rows:
        _, overrides = ROWS[name]
        res = run_batch(str(MISSION), trials=args.trials, workers=args.workers, seed=args.seed,
                        overrides=[*overrides, *args.sets], out=out / name)
        results[name] = row_stats(res)
        print(f"  {name}: {args.trials} trials in {res['timing']['total_wall_s']:.0f} s", flush=True)
    print()
    print("ViKi-HyCo complete placement on held-out conditions (ground truth; " +
          (", ".join(args.sets) if args.sets else "fidelity ideal") + ")")
    hdr = (f"{'condition':44s} {'success':>8s} {'95 % Wilson':>12s} {'contacts':>8s} {'min clear m':>11s} "
           f"{'|X| cm':>7s} {'|Y| cm':>7s}  failures")
    print(hdr)
    print("-" * len(hdr))
    for name in args.rows:
        r = results[name]
        lo, hi = r["success_ci95"]
        mc = "-" if r["min_clearance_m"] is None else f"{r['min_clearance_m']:.3f}"
        print(f"{ROWS[name][0]:44s} {r['succeeded']:>3d}/{r['trials']:<4d} {f'{100 * lo:.0f}-{100 * hi:.0f} %':>12s} "
              f"{r['contacts']:>8d} {mc:>11s} {100 * r['abs_x_mean']:7.2f} {100 * r['abs_y_mean']:7.2f}  "
              f"{r['failures'] or '-'}")
    print(f"batch files under {out}; total {time.perf_counter() - t0:.0f} s")
    print(json.dumps({"trials": args.trials, "seed": args.seed, "sets": args.sets, "results": results}))


if __name__ == "__main__":
    main()
