"""Same seed, same bytes, for every shipped mission run to its end: each mission (and each perception mode
its world has) is run twice with one seed in separate processes, and ``trace.csv``,
``transitions.jsonl``, ``summary.json`` and ``mission.yaml`` are compared byte for byte.

Run: ``python benchmarks/determinism.py [--seed 0] [--workers 2] [--only NAME ...]`` — prints one line per
mission and mode, then a JSON line with the counts.  (The test suite checks short runs of one mission
per world and mode: ``tests/missions/test_determinism.py``.)
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RECORDS = ("trace.csv", "transitions.jsonl", "summary.json", "mission.yaml")
MODES = {  # world → the perception modes it has besides its default (overrides)
    "viki_ground": [["world.params.perception=rendered", "world.params.image_size=[320, 180]"]],
    "quad_room": [["world.params.perception=geometric"]],
    "screw_conveyor": [["world.params.perception=rendered"]],
}


def _run(job: tuple[str, list[str], int, str]) -> tuple[str, float]:
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    path, overrides, seed, out = job
    r = run_mission(load_mission(path, overrides), seed=seed, out_dir=out)
    return r.outcome, r.summary["sim_time_s"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", nargs="*", default=None, help="mission file stems to run (default: all)")
    args = ap.parse_args()
    from taskflow.mission.loader import load_mission

    cases = []
    for f in sorted((ROOT / "missions").glob("*.yaml")):
        if args.only and f.stem not in args.only:
            continue
        world = load_mission(f).world_cls.name
        for ov in [[], *MODES.get(world, [])]:
            cases.append((f, ov))
    tmp = Path(tempfile.mkdtemp(prefix="taskflow-determinism-"))
    jobs = []
    for i, (f, ov) in enumerate(cases):
        for rep in ("a", "b"):
            jobs.append((str(f), ov, args.seed, str(tmp / f"{i:02d}-{rep}")))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(_run, jobs))
    identical = 0
    rows = []
    for i, (f, ov) in enumerate(cases):
        a, b = tmp / f"{i:02d}-a", tmp / f"{i:02d}-b"
        diff = [n for n in RECORDS if (a / n).read_bytes() != (b / n).read_bytes()]
        mode = ov[0].split("=")[1] if ov else "default"
        outcome, sim = results[2 * i]
        identical += not diff
        rows.append({"mission": f.stem, "mode": mode, "outcome": outcome, "sim_time_s": sim, "differs": diff})
        print(f"{f.stem:42s} {mode:10s} {outcome:10s} {sim:8.2f} s  "
              f"{'identical' if not diff else 'DIFFERS: ' + ', '.join(diff)}", flush=True)
    print(json.dumps({"seed": args.seed, "runs": len(cases), "identical": identical,
                      "wall_s": round(time.perf_counter() - t0, 1), "rows": rows}))


if __name__ == "__main__":
    main()
