"""Visual path following (Toro-Arcila et al.): the paper's experiments on PyBullet, beside its numbers.

    python benchmarks/visual_path.py                 # all five missions (~5-7 min on 2 cores)
    python benchmarks/visual_path.py --only pose_regulation obstacles
    python benchmarks/visual_path.py --plots figures/   # also the figures of each run
    python benchmarks/visual_path.py --perception geometric --seeds 10   # success rates, fast camera
    python benchmarks/visual_path.py --only oval oval_feedforward --set profiles.visual.paper.w_scale=1.0
    python benchmarks/visual_path.py --perception geometric --seeds 5 --fidelity paper   # the Bebop-like drone
    python benchmarks/visual_path.py --shapes --seeds 10   # robustness over the taught path's shape (geometric)

Each mission runs with the rendered pipeline (320x240 TinyRenderer frames → ORB/LK/RANSAC →
hierarchical homography servoing).  Printed per experiment: completion, final ε (task and ground
truth), final position and yaw error against the last taught pose, minimum obstacle clearance,
collisions, path time, control loop frequency (simulated) and the cost per frame of perception +
control (excluding rendering) with the real-time factor of the whole run.  The last line is JSON.

``--perception geometric`` runs the same missions with the world's geometric camera (landmarks
projected with pixel noise, no rendering) over ``--seeds`` seeds (RANSAC draws and pixel noise
differ), as :func:`taskflow.campaigns.batch.run_batch` trials on every core, and prints success rates (with their
Wilson 95 % intervals; the t interval of the mean final error) with the
mean time and final error of the successes.

``--fidelity paper`` runs every mission with ``world.params.fidelity=paper`` (quad_room's Bebop 2 level:
commands as ViSP's relative moves, 30 fps camera, one cycle of frame latency; ``docs/missions.md``) and
prints the same table; ``ideal`` (default) is the simulation as the missions ship.

``--shapes`` flies the shipped oval's mission (``visual_path_oval.yaml``, no feed-forward) over other
taught paths built by :func:`path_shapes` (a tighter oval, an S-bend, a rounded rectangle), seeds 0 …
``--seeds`` − 1 with the geometric camera, as :func:`taskflow.campaigns.batch.run_batch` trials, and prints success
[Wilson 95 %], the maximum deviation from the taught path (mean and worst over the seeds) and the final
error.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import taskflow_robots.quadcopter  # noqa: F401 - registration
import taskflow_sim.quad.world  # noqa: F401
import taskflow_tasks.quad.visual_path  # noqa: F401
from visual_path_shapes import path_shapes, shape_mission

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.stats import mean_interval, wilson_interval
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.readers.run_files import read_trace

EXPERIMENTS = {
    "pose_regulation": ("visual_path_pose_regulation.yaml",
                        {"completed": True, "path_time_s": 12.0, "loop_hz": 24.7, "collisions": 0}),
    "obstacles": ("visual_path_obstacles.yaml", {"completed": True, "path_time_s": 30.0, "loop_hz": 55.0,
                                                  "collisions": 0}),
    "oval": ("visual_path_oval.yaml", {"completed": True, "path_time_s": 205.0, "loop_hz": 24.0,
                                       "path_length_m": 7.7}),
    "oval_feedforward": ("visual_path_oval_feedforward.yaml",
                         {"completed": True, "path_time_s": 51.32, "loop_hz": 23.0, "path_length_m": 7.71}),
    "oval_feedforward_tuned": ("visual_path_oval_feedforward_tuned.yaml",
                               {"completed": True, "path_time_s": 51.32, "loop_hz": 23.0, "path_length_m": 7.71}),
}
# the paper's times are read from its text: §5.1 "converged at t = 12 s", §5.2 last switch at t = 26 s
# and the end a few seconds later (Fig. 14), §5.3 "about 205 s" and "51.32 s".


def _float(v: str) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def frame_costs(timing: dict) -> dict[str, float]:
    """Perception + control wall time per camera frame (ms), excluding rendering, from the run's
    ``timing.json`` (the task's ``frame`` timing)."""
    frame = timing.get("parts_ms", {}).get("task.frame")
    if not frame:
        return {"frame_ms_mean": math.nan, "frame_ms_median": math.nan, "frame_ms_p95": math.nan}
    return {"frame_ms_mean": frame["mean"], "frame_ms_median": frame["p50"], "frame_ms_p95": frame["p95"]}


def run_experiment(name: str, out: Path, overrides: list[str] | None = None, seed: int | None = None) -> dict:
    file, paper = EXPERIMENTS[name]
    m = load_mission(ROOT / "missions" / file, overrides=overrides or [])
    t0 = time.perf_counter()
    r = run_mission(m, out_dir=out / name, seed=seed)
    wall = time.perf_counter() - t0
    s = r.summary
    mt = s["metrics"]
    res = {
        "experiment": name,
        "completed": r.outcome == "succeeded",
        "outcome": r.outcome,
        "path_time_s": s["sim_time_s"],
        "keyframes": len(s["iterations"]),
        "final_epsilon_px": mt.get("epsilon"),
        "final_epsilon_gt_px": mt.get("final_epsilon_px"),
        "final_position_error_m": mt.get("final_position_error_m"),
        "final_yaw_error_deg": mt.get("final_yaw_error_deg"),
        "min_obstacle_clearance_m": mt.get("min_obstacle_clearance_m"),
        "min_clearance_m": mt.get("min_clearance_m"),
        "collisions": mt.get("collisions"),
        "path_length_m": mt.get("path_length_m"),
        "path_deviation_max_m": mt.get("path_deviation_max_m"),
        "path_deviation_mean_m": mt.get("path_deviation_mean_m"),
        "loop_hz": m.spec.rate_hz,
        "real_time_factor": r.timing["real_time_factor"],
        "wall_s": wall,
        **frame_costs(r.timing),
        "paper": paper,
    }
    return res


def fmt(v, nd=3):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.{nd}f}"
    return str(v)


def print_table(results: list[dict]) -> None:
    rows = [("completed", "completed"), ("path time (s)", "path_time_s"), ("final ε task (px)", "final_epsilon_px"),
            ("final ε ground truth (px)", "final_epsilon_gt_px"), ("final position error (m)", "final_position_error_m"),
            ("final yaw error (deg)", "final_yaw_error_deg"), ("min obstacle clearance (m)", "min_obstacle_clearance_m"),
            ("collisions", "collisions"), ("path length flown (m)", "path_length_m"),
            ("deviation from taught path max (m)", "path_deviation_max_m"),
            ("deviation from taught path mean (m)", "path_deviation_mean_m"), ("control loop (Hz, sim)", "loop_hz"),
            ("perception+control mean (ms)", "frame_ms_mean"), ("perception+control p95 (ms)", "frame_ms_p95"),
            ("real-time factor (with rendering)", "real_time_factor")]
    for r in results:
        print(f"\n== {r['experiment']} ({r['outcome']}) — ours | paper")
        for label, key in rows:
            print(f"  {label:36s} {fmt(r.get(key)):>10s} | {fmt(r['paper'].get(key)):>8s}")
    for name, ratio in time_ratios({r["experiment"]: r["path_time_s"] for r in results}).items():
        print(f"\n{name} takes {100 * ratio:.1f} % of the time of oval (paper: 25 %, target <= 30 %)")


def plots(results: list[dict], out: Path, fig_dir: Path) -> list[Path]:
    """Top view against the taught poses and obstacles; velocities with avoidance shaded; h_a, h_m;
    ε and the task error with keyframe switches marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for r in results:
        name = r["experiment"]
        tr = read_trace(out / name)
        mfile = out / name / "mission.yaml"
        mission = yaml.safe_load(mfile.read_text()) if mfile.exists() else None
        t = np.array([_float(v) for v in tr["t"]])
        g = {k: np.array([_float(v) for v in tr[f"gt.{k}"]]) for k in ("x", "y")}
        nu = np.array([[_float(v) for v in tr[f"cmd.nu.{i}"]] for i in range(4)])

        def col(k: str, tr: dict = tr, n: int = len(t)) -> np.ndarray:
            return np.array([_float(v) for v in tr.get(f"m.{k}", [math.nan] * n)])

        kf = col("keyframe")
        switches = t[1:][np.diff(np.nan_to_num(kf, nan=-1)) != 0]
        fig, ax = plt.subplots(2, 2, figsize=(12, 8))
        a = ax[0, 0]
        a.plot(g["x"], g["y"], label="flown (ground truth)")
        params = (mission or {}).get("world", {}).get("params", {}) if mission else {}
        kfs = params.get("keyframes", [])
        if kfs:
            a.plot([k["pose"][0] for k in kfs], [k["pose"][1] for k in kfs], "o", ms=4, label="taught poses")
        for o in params.get("obstacles", []):
            a.add_patch(plt.Circle((o["x"], o["y"]), max(o["width"], o.get("depth", 0)) / 2, color="g"))
        a.set_aspect("equal")
        a.set_title(f"{name}: top view")
        a.legend()
        a = ax[0, 1]
        for i, lab in enumerate(("vx", "vy", "vz", "wz")):
            a.plot(t, nu[i], label=lab)
        ha = col("h_a")
        on = np.nan_to_num(ha) > 0
        for i in np.flatnonzero(np.diff(on.astype(int)) == 1):
            j = i + 1 + (np.argmax(~on[i + 1:]) if np.any(~on[i + 1:]) else len(on) - i - 1)
            a.axvspan(t[i], t[min(j, len(t) - 1)], color="c", alpha=0.2)
        for s in switches:
            a.axvline(s, color="k", ls=":", lw=0.8)
        a.set_title("velocities (avoidance shaded)")
        a.legend()
        a = ax[1, 0]
        a.plot(t, ha, label="h_a")
        a.plot(t, col("h_m"), label="h_m")
        a.plot(t, col("h_t"), label="h_t")
        a.set_title("activations")
        a.legend()
        a = ax[1, 1]
        a.plot(t, col("epsilon"), label="ε (px)")
        a2 = a.twinx()
        a2.plot(t, col("task_error"), "r", label="‖e‖")
        for s in switches:
            a.axvline(s, color="k", ls=":", lw=0.8)
        a.set_title("ε and task error (keyframe switches dotted)")
        a.legend(loc="upper left")
        a2.legend(loc="upper right")
        fig.tight_layout()
        f = fig_dir / f"visual_path_{name}.png"
        fig.savefig(f, dpi=90)
        plt.close(fig)
        written.append(f)
    return written


def time_ratios(path_times: dict[str, float]) -> dict[str, float]:
    """Path time of each feed-forward oval over the oval's without feed-forward (the paper's 25 %)."""
    return {name: path_times[name] / path_times["oval"] for name in ("oval_feedforward", "oval_feedforward_tuned")
            if "oval" in path_times and name in path_times}


def batch(names: list[str], out: Path, perception: str, seeds: int, overrides: list[str]) -> dict:
    """Every experiment over seeds 0 … ``seeds`` − 1 (:func:`taskflow.campaigns.batch.run_batch`, one process per
    core): success rate, time and final error of the successes."""
    rows = {}
    for name in names:
        res = run_batch(str(ROOT / "missions" / EXPERIMENTS[name][0]), trials=seeds, seed=0, out=out / name,
                        overrides=[f"world.params.perception={perception}", *overrides])
        trials = res["trials"]
        ok = [s for s in trials if s["outcome"] == "succeeded"]

        def stat(values: list) -> tuple[float, float]:
            v = np.array([x for x in values if x is not None], dtype=float)
            return (float(v.mean()), float(v.std())) if len(v) else (math.nan, math.nan)

        err_ok = [s["metrics"].get("final_position_error_m") for s in ok]
        err_ok = [x for x in err_ok if x is not None]
        err_ci = mean_interval(err_ok) if err_ok else None
        rows[name] = {"runs": len(trials), "succeeded": len(ok), "success_ci95": list(wilson_interval(len(ok), len(trials))),
                      "final_position_error_ci95_m": None if err_ci is None or err_ci.low is None else [err_ci.low, err_ci.high],
                      "path_time_s": stat([s["sim_time_s"] for s in ok]),
                      "final_position_error_m": stat([s["metrics"].get("final_position_error_m") for s in ok]),
                      "path_deviation_max_m": stat([s["metrics"].get("path_deviation_max_m") for s in ok]),
                      "collisions_max": max(int(s["metrics"].get("collisions") or 0) for s in trials),
                      "wall_s_per_run": res["timing"]["per_trial_wall_s"],
                      "failures": [(i, s["outcome"], s["sim_time_s"]) for i, s in enumerate(trials)
                                   if s["outcome"] != "succeeded"],
                      "paper_time_s": EXPERIMENTS[name][1]["path_time_s"]}
    print(f"\n{perception} camera, {seeds} seeds — success, path time and final error of the successes (mean ± sd)")
    for name, r in rows.items():
        t, e, dv = r["path_time_s"], r["final_position_error_m"], r["path_deviation_max_m"]
        ci, eci = r["success_ci95"], r["final_position_error_ci95_m"]
        eci_text = "" if eci is None else f" (mean 95 %: {100 * eci[0]:.1f}-{100 * eci[1]:.1f})"
        print(f"  {name:22s} {r['succeeded']:2d}/{r['runs']:<2d} (95 % Wilson {100 * ci[0]:.0f}-{100 * ci[1]:.0f} %)"
              f"  time {t[0]:6.1f} ± {t[1]:4.1f} s (paper {r['paper_time_s']:g})"
              f"  final error {100 * e[0]:4.1f} ± {100 * e[1]:3.1f} cm{eci_text}  max path deviation {100 * dv[0]:4.0f} cm"
              f"  max collisions {r['collisions_max']}  wall {r['wall_s_per_run']:.1f} s/run")
    for name, ratio in time_ratios({n: r["path_time_s"][0] for n, r in rows.items()}).items():
        print(f"  {name} / oval (successful runs): {100 * ratio:.1f} % (paper 25 %, target <= 30 %)")
    return rows


def shapes(out: Path, seeds: int, overrides: list[str]) -> dict:
    """The shipped oval mission over every :func:`path_shapes` path (its keyframes replaced; the others in
    a room 1.6 m beyond the path), geometric camera, seeds 0 … ``seeds`` − 1: success [Wilson 95 %], max
    deviation (mean, worst), final error."""
    rows = {}
    for name, poses in path_shapes().items():
        file = shape_mission(name, poses, out, room_margin=None if name == "oval" else 1.6)
        res = run_batch(str(file), trials=seeds, seed=0, out=out / name,
                        overrides=["world.params.perception=geometric", *overrides])
        trials = res["trials"]
        ok = [t for t in trials if t["outcome"] == "succeeded"]
        dev = [t["metrics"].get("path_deviation_max_m") for t in trials]
        err = [t["metrics"].get("final_position_error_m") for t in ok]
        rows[name] = {"keyframes": len(poses), "runs": len(trials), "succeeded": len(ok),
                      "success_ci95": list(wilson_interval(len(ok), len(trials))),
                      "path_deviation_max_m": [float(np.mean(dev)), float(np.max(dev))],
                      "final_position_error_m": [float(np.mean(err)), float(np.max(err))] if err else None,
                      "path_time_s": float(np.mean([t["sim_time_s"] for t in ok])) if ok else None,
                      "collisions_max": max(int(t["metrics"].get("collisions") or 0) for t in trials)}
    print(f"\npath shapes (visual_path_oval's mission, geometric camera, {seeds} seeds"
          f"{', ' + ' '.join(overrides) if overrides else ''})")
    print(f"  {'path':18s} {'kf':>3s}  success [95 % Wilson]   max deviation cm (mean / worst)  final error cm (mean / worst)  time s")
    for name, r in rows.items():
        ci, d, e = r["success_ci95"], r["path_deviation_max_m"], r["final_position_error_m"]
        etext = "-" if e is None else f"{100 * e[0]:4.1f} / {100 * e[1]:4.1f}"
        ttext = "-" if r["path_time_s"] is None else f"{r['path_time_s']:.1f}"
        print(f"  {name:18s} {r['keyframes']:3d}  {r['succeeded']:2d}/{r['runs']:<2d} [{100 * ci[0]:3.0f}, {100 * ci[1]:3.0f}]"
              f"           {100 * d[0]:5.1f} / {100 * d[1]:5.1f}                 {etext:>13s}           "
              f"{ttext}")
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", nargs="*", choices=sorted(EXPERIMENTS), help="experiments to run (default: all)")
    ap.add_argument("--out", type=Path, default=None, help="run records (default: a temporary directory)")
    ap.add_argument("--plots", type=Path, default=None, help="write figures into this directory")
    ap.add_argument("--perception", choices=("rendered", "geometric"), default="rendered",
                    help="geometric: the fast camera over --seeds seeds (success rates)")
    ap.add_argument("--seeds", type=int, default=10, help="seeds per experiment with --perception geometric")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                    help="override a key of every mission run (as taskflow run --set), e.g. a gain")
    ap.add_argument("--fidelity", choices=("ideal", "paper"), default="ideal",
                    help="quad_room's fidelity level (paper: the Bebop 2 of the paper, docs/missions.md)")
    ap.add_argument("--shapes", action="store_true", help="robustness over the taught path's shape (geometric)")
    args = ap.parse_args(argv)
    names = args.only or list(EXPERIMENTS)
    out = args.out or Path(tempfile.mkdtemp(prefix="visual_path_bench_"))
    if args.fidelity != "ideal":
        args.overrides = [f"world.params.fidelity={args.fidelity}", *args.overrides]
    print(f"fidelity: {args.fidelity}")
    if args.shapes:
        rows = shapes(out, args.seeds, args.overrides)
        print(json.dumps({"benchmark": "visual_path_shapes", "seeds": args.seeds, "overrides": args.overrides,
                          "results": rows}))
        return 0
    if args.perception == "geometric":
        rows = batch(names, out, args.perception, args.seeds, args.overrides)
        print(json.dumps({"benchmark": "visual_path", "perception": "geometric", "seeds": args.seeds,
                          "overrides": args.overrides, "results": rows},
                         default=lambda o: None if isinstance(o, float) and math.isnan(o) else o))
        return 0
    results = [run_experiment(n, out, args.overrides) for n in names]
    print_table(results)
    if args.plots is not None:
        for f in plots(results, out, args.plots):
            print(f"figure: {f}")
    summary = {"benchmark": "visual_path", "runs": out.as_posix(),
               "results": [{k: v for k, v in r.items() if k != "paper"} for r in results]}
    for name, ratio in time_ratios({r["experiment"]: r["path_time_s"] for r in results}).items():
        summary[f"{name}_time_ratio"] = ratio
    print(json.dumps(summary, default=lambda o: None if isinstance(o, float) and math.isnan(o) else o))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
