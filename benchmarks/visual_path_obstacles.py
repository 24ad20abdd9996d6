"""Visual path following past columns placed anywhere near the taught line: a robustness table.

    python benchmarks/visual_path_obstacles.py                     # both missions, 30 trials each (~4 min)
    python benchmarks/visual_path_obstacles.py --trials 10 --only obstacles
    python benchmarks/visual_path_obstacles.py --set profiles.hierarchy.paper.memory=false   # the paper's task
    python benchmarks/visual_path_obstacles.py --scale 2       # columns twice as wide and deep, sigma x 2
    python benchmarks/visual_path_obstacles.py --only figure_eight s_bend --trials 20   # beside other paths

Each trial of ``visual_path_obstacles`` and ``visual_path_pose_regulation`` (geometric camera by default)
draws its columns' places from the seed (``world.params.obstacles`` with ``{uniform: [a, b]}`` inside,
:mod:`taskflow.mission.distributions`): every column anywhere within ``--offset`` (0.2 m) of the taught line
across it and over a stretch of the line along it (``PLACEMENTS``), with the shipped sizes times
``--scale`` (and the collision references σ alike: the task starts at the same distance).  The trials
run through :func:`taskflow.campaigns.batch.run_batch`; collisions, clearance and final error are the world's
ground truth (``quad_room``: PyBullet ``getClosestPoints`` between the drone's collision shapes and the
columns).  Printed per mission: success with its Wilson 95 % interval, trials with a collision, the
minimum obstacle clearance (over all trials and its median), final position error of the successes,
path time, and the trials that failed with the drawn places; the last line is JSON.

``figure_eight`` and ``s_bend`` (:data:`BESIDE`) fly ``visual_path_oval``'s mission over a figure-eight and the
S-bend of :mod:`visual_path_shapes` with the collision task on (:func:`visual_path_shapes.with_columns`): two
cylinders per trial, places and widths (6–16 cm) drawn from the seed — beside the figure-eight's first
straight leg, one each side within 0.15 m of it, or beside the S-bend's left and right quarter circles.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import taskflow_robots.quadcopter  # noqa: F401 - registration
import taskflow_sim.quad.world  # noqa: F401
import taskflow_tasks.quad.visual_path  # noqa: F401
from visual_path_shapes import figure_eight, path_shapes, shape_mission, with_columns

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.stats import wilson_interval
from taskflow.mission.loader import load_mission

# per mission: each column's stretch along the taught line (x, m; the line runs along y = 0) and its
# size (as shipped); its distance across the line is drawn within ±offset
PLACEMENTS: dict[str, tuple[str, list[tuple[tuple[float, float], dict[str, float]]]]] = {
    "obstacles": ("visual_path_obstacles.yaml",
                  [((0.6, 1.1), {"width": 0.11}), ((2.5, 3.0), {"width": 0.05, "depth": 0.02})]),
    "pose_regulation": ("visual_path_pose_regulation.yaml", [((0.6, 1.0), {"width": 0.05, "depth": 0.02})]),
}
# paths of visual_path_shapes flown by visual_path_oval's mission with the collision task on (with_columns):
# per column, its box (x range, y range; world frame) and width range (cylinders, m), drawn per trial
BESIDE: dict[str, tuple[str, list[tuple[tuple[float, float], tuple[float, float], tuple[float, float]]]]] = {
    # the first straight leg runs along y = 0, x 0 -> 2.04 m, crossed by the second leg at x = 1.02 m:
    # one column left of it before the crossing, one right of it after, each within 0.15 m of the line
    "figure_eight": ("figure_eight", [((0.4, 0.75), (0.0, 0.15), (0.06, 0.16)),
                                      ((1.3, 1.65), (-0.15, 0.0), (0.06, 0.16))]),
    # outside the S-bend's left and right quarter circles (radius 0.6 m, centres (1, 0.6) and (2.2, 0.6)), in
    # 10 cm squares centred 0.1 m beyond their mid-arc points (1.42, 0.18) and (1.78, 1.02): the first on the
    # drone's right, the second on its left, 0.03-0.17 m from the line
    "s_bend": ("s_bend", [((1.445, 1.545), (0.055, 0.155), (0.06, 0.16)), ((1.655, 1.755), (1.045, 1.145), (0.06, 0.16))]),
}


def placement(columns: list[tuple[tuple[float, float], dict[str, float]]], offset: float, scale: float = 1.0) -> str:
    """The ``world.params.obstacles`` override drawing every column's place per trial (sizes times ``scale``)."""
    items = []
    for (x0, x1), size in columns:
        extra = ", ".join(f"{k}: {v * scale:g}" for k, v in size.items())
        items.append(f"{{x: {{uniform: [{x0}, {x1}]}}, y: {{uniform: [{-offset}, {offset}]}}, {extra}}}")
    return "world.params.obstacles=[" + ", ".join(items) + "]"


def sigma_overrides(path: Path, scale: float) -> list[str]:
    """With columns ``scale`` times as wide, the collision references σ (eq. 8; per keyframe in
    ``parameters.path``, else the hierarchy profile's) scaled alike, so the task starts avoiding at the
    same distance as with the shipped columns; none when ``scale`` is 1."""
    if scale == 1.0:
        return []
    spec = yaml.safe_load(path.read_text())
    out = []
    kfs = spec.get("parameters", {}).get("path", [])
    if any("sigma" in k for k in kfs):
        scaled = [{**k, "sigma": k["sigma"] * scale} if "sigma" in k else k for k in kfs]
        out.append(f"parameters.path={json.dumps(scaled)}")
    for name, prof in spec.get("profiles", {}).get("hierarchy", {}).items():
        if "sigma" in prof:
            out.append(f"profiles.hierarchy.{name}.sigma={prof['sigma'] * scale:g}")
    return out


def beside(name: str) -> str:
    """The ``world.params.obstacles`` override of a :data:`BESIDE` condition (places and widths drawn per trial)."""
    items = [f"{{x: {{uniform: [{x0}, {x1}]}}, y: {{uniform: [{y0}, {y1}]}}, width: {{uniform: [{w0}, {w1}]}}}}"
             for (x0, x1), (y0, y1), (w0, w1) in BESIDE[name][1]]
    return "world.params.obstacles=[" + ", ".join(items) + "]"


def campaign(name: str, trials: int, offset: float, perception: str, overrides: list[str], out: Path,
             workers: int | None, scale: float = 1.0) -> dict:
    if name in BESIDE:
        shape = BESIDE[name][0]
        poses = figure_eight() if shape == "figure_eight" else path_shapes()[shape]
        path = with_columns(shape_mission(shape, poses, out / "missions"))
        file, where = path.name, beside(name)
        sets = [f"world.params.perception={perception}", where, *overrides]
    else:
        file, columns = PLACEMENTS[name]
        path = ROOT / "missions" / file
        where = placement(columns, offset, scale)
        sets = [f"world.params.perception={perception}", where, *sigma_overrides(path, scale), *overrides]
    res = run_batch(str(path), trials=trials, seed=0, out=out / name, overrides=sets, workers=workers)
    mission = load_mission(path, overrides=sets)
    trials_out = res["trials"]
    ok = [s for s in trials_out if s["outcome"] == "succeeded"]
    clear = [s["metrics"].get("min_obstacle_clearance_m") for s in trials_out]
    clear = [c for c in clear if c is not None]
    err = [s["metrics"]["final_position_error_m"] for s in ok]
    failed = []
    for s in trials_out:
        if s["outcome"] != "succeeded" or s["metrics"].get("collisions"):
            obs = mission.world_params(int(s["seed"])).obstacles  # the places this trial drew
            failed.append({"seed": s["seed"], "final_state": s["final_state"], "collisions": s["metrics"].get("collisions"),
                           "obstacles": [[round(o.x, 3), round(o.y, 3), round(o.width, 3)] for o in obs]})
    lo, hi = wilson_interval(len(ok), len(trials_out))
    return {"mission": file, "trials": len(trials_out), "succeeded": len(ok), "success_ci95": [lo, hi],
            "with_collision": sum(1 for s in trials_out if s["metrics"].get("collisions")),
            "min_clearance_m": min(clear) if clear else math.nan,
            "median_min_clearance_m": float(np.median(clear)) if clear else math.nan,
            "final_error_m": [float(np.mean(err)), float(np.max(err))] if err else [math.nan, math.nan],
            "final_error_over_5cm": sum(1 for e in err if e > 0.05),
            "path_time_s": [float(np.mean([s["sim_time_s"] for s in ok])), float(np.max([s["sim_time_s"] for s in ok]))]
            if ok else [math.nan, math.nan],
            "path_deviation_3d_max_m": max((s["metrics"].get("path_deviation_3d_max_m") or 0.0) for s in trials_out),
            "failed": failed, "placement": where, "sigma": sigma_overrides(path, scale) if name in PLACEMENTS else []}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", choices=sorted([*PLACEMENTS, *BESIDE]), default=sorted(PLACEMENTS),
                    help="conditions (default: the two shipped missions; figure_eight, s_bend: columns beside other paths)")
    ap.add_argument("--trials", type=int, default=30)
    ap.add_argument("--offset", type=float, default=0.2, help="columns within this distance of the taught line (m)")
    ap.add_argument("--scale", type=float, default=1.0, help="column width and depth times this")
    ap.add_argument("--perception", choices=["geometric", "rendered"], default="geometric")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="another mission override")
    ap.add_argument("--out", type=Path, default=None, help="batch directories (default: a temporary one)")
    args = ap.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="vp_obstacles_"))
    rows = {n: campaign(n, args.trials, args.offset, args.perception, args.set, out, args.workers, args.scale)
            for n in args.only}
    print(f"\n{'mission':<16} {'succeeded [95 %]':<22} {'collided':>8} {'min clearance cm (median)':>26} "
          f"{'final error cm mean / max':>26} {'> 5 cm':>7} {'path time s mean / max':>23}")
    for n, r in rows.items():
        lo, hi = r["success_ci95"]
        print(f"{n:<16} {r['succeeded']}/{r['trials']} [{100 * lo:.0f}, {100 * hi:.0f}]{'':<6} {r['with_collision']:>8} "
              f"{100 * r['min_clearance_m']:>17.1f} ({100 * r['median_min_clearance_m']:.1f}) "
              f"{100 * r['final_error_m'][0]:>17.1f} / {100 * r['final_error_m'][1]:.1f} {r['final_error_over_5cm']:>7} "
              f"{r['path_time_s'][0]:>15.1f} / {r['path_time_s'][1]:.1f}")
        for f in r["failed"]:
            print(f"    seed {f['seed']}: {f['final_state']}, collisions {f['collisions']}, columns at {f['obstacles']}")
    print(json.dumps({"perception": args.perception, "offset_m": args.offset, "scale": args.scale, "overrides": args.set,
                      "rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
