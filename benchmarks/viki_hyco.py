"""ViKi-HyCo Monte Carlo campaign next to the paper's numbers (REFERENCE.md §1), plus costs.

Batches (``taskflow.batch.run_batch``, trial ``i`` with seed ``seed + i``, object kind/pose drawn per
trial from the missions' distributions):

* geometric perception, ``--trials`` each: forward positioning, backward positioning, complete placement
  (15 % dropout), the VS-only baseline (15 % dropout) and the MGBM-YOLO baseline (no dropout);
* rendered perception (TinyRenderer at ``--rendered-size``, LiDAR fusion for the front camera),
  ``--rendered-trials`` complete placements.

Reported per batch: success rate with its Wilson 95 % interval, final error of the object in the robot
frame against the goal (ground
truth; |X| and |Y| mean ± std, as the paper reports, with the t 95 % interval of each mean, and the
signed means), time to complete (simulated
seconds of the successful trials) and the real-time factor (simulated / wall time inside each trial).
The real-time factor is also measured for one complete placement run alone in the main process (the batch
workers compete for the cores).  Costs: µs per control tick of the law alone (eq. 19–26 + eq. 5, no perception; :func:`viki_velocity`)
for a visual and a kinematic tick and for the whole task step on a synthetic detection, and the
rendered perception's ms per frame at 320x180 and 640x360 (front camera with LiDAR fusion, rear camera).

Fidelity: forward, backward and complete placement run again at each ``--fidelity`` level of
``viki_ground`` (default ``paper``: ``world.params.fidelity=paper`` — the paper's 1280x720 images, 44 ms
latency, YOLO-like box jitter and bias, RealSense depth noise, drifting odometry; docs/missions.md), so
the paper's table is printed under both the ideal and the paper-like world next to the published
numbers.  ``--table-only`` runs just those batches.

Usage: ``python benchmarks/viki_hyco.py --workers 2`` (``--quick`` for 3 + 1 trials; ``--fidelity`` with no
level for the ideal world only).  The last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import time
import timeit
from pathlib import Path
from typing import Any

import numpy as np
import taskflow_sim.viki_world  # noqa: F401  registers viki_ground (forked batch workers inherit it)
import taskflow_tasks.viki_hyco
import taskflow_tasks.viki_rotation  # noqa: F401  registers viki_rotate
from taskflow_robots.racecar import Racecar
from taskflow_tasks.viki_hyco import ViKiGains, ViKiHyCo
from taskflow_tasks.viki_laws import ServoInputs, viki_velocity

from taskflow.api import Observation
from taskflow.batch import run_batch
from taskflow.messages import Detection
from taskflow.stats import mean_interval, wilson_interval
from taskflow.testing import task_context

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = ROOT / "missions"

# (name, mission, overrides, paper: (X mean, X std, Y mean, Y std) in m or a note)
PAPER = {
    "forward": ((0.0911, 0.0631, 0.0457, 0.0437), "ViKi-HyCo forward, 20 runs"),
    "backward": ((0.0375, 0.0334, 0.0452, 0.0601), "ViKi-HyCo backward, 20 runs"),
    "complete": ((0.0428, 0.0467, 0.0515, 0.0313), "complete placement, 12 runs"),
    "vs_only": ((1.202, None, 0.105, None), "VS-only forward, bad case: stopped early"),
    "mgbm": (None, "MGBM-YOLO: never settles, velocities oscillate"),
    "complete_rendered": ((0.0428, 0.0467, 0.0515, 0.0313), "complete placement, 12 runs"),
}
PAPER_TABLE = ("forward", "backward", "complete")  # the experiments run again at each non-ideal fidelity level


def batch_stats(result: dict[str, Any]) -> dict[str, Any]:
    trials = result["trials"]
    ok = [s for s in trials if s["outcome"] == "succeeded"]

    def col(key: str, rows: list[dict[str, Any]]) -> np.ndarray:
        return np.array([s["metrics"][key] for s in rows if isinstance(s["metrics"].get(key), (int, float))], float)

    ex, ey = col("final_error_x_m", trials), col("final_error_y_m", trials)
    t_ok = np.array([s["sim_time_s"] for s in ok], float)
    ci_x, ci_y = mean_interval(np.abs(ex)), mean_interval(np.abs(ey))
    rtf = np.array([t["real_time_factor"] for t in result["timing"]["trials"] if t.get("real_time_factor")], float)
    outcomes: dict[str, int] = {}
    for s in trials:
        key = f"{s['outcome']}:{s['final_state']}"
        outcomes[key] = outcomes.get(key, 0) + 1
    return {
        "trials": len(trials),
        "success_rate": len(ok) / len(trials),
        "success_ci95": list(wilson_interval(len(ok), len(trials))),
        "abs_x_ci95": [ci_x.low, ci_x.high], "abs_y_ci95": [ci_y.low, ci_y.high],
        "outcomes": outcomes,
        "abs_x_mean": float(np.mean(np.abs(ex))), "abs_x_std": float(np.std(np.abs(ex))),
        "abs_y_mean": float(np.mean(np.abs(ey))), "abs_y_std": float(np.std(np.abs(ey))),
        "x_mean": float(np.mean(ex)), "y_mean": float(np.mean(ey)),
        "max_abs_err": float(max(np.max(np.abs(ex)), np.max(np.abs(ey)))),
        "time_s_mean": float(np.mean(t_ok)) if t_ok.size else None,
        "time_s_std": float(np.std(t_ok)) if t_ok.size else None,
        "rtf_mean": float(np.mean(rtf)) if rtf.size else None,
        "rtf_min": float(np.min(rtf)) if rtf.size else None,
        "batch_wall_s": result["timing"]["total_wall_s"],
        "batch_file": result.get("batch_file"),
    }


def law_costs(repeat: int = 7, number: int = 2000) -> dict[str, float]:
    """µs per call: eq. 19–26 + eq. 5 (visual tick, kinematic tick) and the whole task step."""
    robot = Racecar(Racecar.Params())
    rp = robot.params
    T = rp.rear_camera.T_body_camera()
    K = (rp.rear_camera.focal_px(),) * 2 + (320.0, 179.0)
    kw = dict(intrinsics=K, T_robot_camera=T, lam=np.array([0.85, 1.05, 1.0, 1.0, 1.0]), k1=np.array([1.0, 2.0]), d=rp.wheelbase,
              wheelbase=rp.wheelbase, v_max=rp.v_max, psi_max=rp.psi_max)
    out = {}
    for name, seen in (("law_visual_tick_us", True), ("law_kinematic_tick_us", False)):
        inp = ServoInputs(pose=np.array([0.1, 0.2, 0.3]), detected=seen, bbox=np.array([300.0, 120.0, 330.0, 190.0]),
                          Z_o=1.4, Z_d=1.1, centre=np.array([320.0, 170.0]), target=np.array([-1.0, 0.5]),
                          v_prev=np.array([0.1, 0.05]))
        out[name] = min(timeit.repeat(lambda inp=inp: viki_velocity(inp, **kw), number=number,
                                      repeat=repeat)) / number * 1e6
    ctx = task_context(ViKiHyCo, ViKiHyCo.Params(camera="rear", desired=(-0.9, 0.0)), robot,
                       {"gains": ViKiGains(lam=(0.85, 1.05, 1.0, 1.0, 1.0), k1=(1.0, 2.0))})
    task = ViKiHyCo(ctx)
    det = Detection(stamp=0.0, frame="rear_camera", camera="rear", seq=0, bbox=(300.0, 120.0, 330.0, 190.0), depth=1.4,
                    intrinsics=K, width=640, height=360, depth_at=lambda u, v: 1.1, depth_in=lambda box: 1.1)
    obs = Observation(t=0.0, state={"pose": np.array([0.1, 0.2, 0.3]), "v": 0.0}, sensors={"detection": det})
    out["task_step_us"] = min(timeit.repeat(lambda: task.step(obs), number=number, repeat=repeat)) / number * 1e6
    return out


def render_costs(sizes: tuple[tuple[int, int], ...] = ((320, 180), (640, 360)), frames: int = 5) -> dict[str, float]:
    """ms per rendered frame (median): front camera with LiDAR fusion (the LiDAR scanned every frame
    here, i.e. worst case; in a run it scans at 10 Hz) and rear camera."""
    from taskflow_sim.viki_world import VikiGround

    robot = Racecar(Racecar.Params())
    out = {}
    for w_, h_ in sizes:
        for cam, bearing in (("front", 0.1), ("rear", math.pi + 0.1)):
            w = VikiGround(robot, VikiGround.Params(perception="rendered", image_size=(w_, h_), initial_camera=cam,
                                                    object_distance=1.6, object_bearing=bearing), seed=0)
            w.reset()
            try:
                w.observe()
                per = w._perceptor(cam)
                T_world_robot = w.T_world_robot()
                T_world_camera = w.cameras[cam].pose(T_world_robot)
                ts = []
                for _ in range(frames):
                    if w._lidar is not None:
                        w._lidar.next_scan = 0.0
                    t0 = time.perf_counter()
                    per.detect(T_world_camera, 0.0, T_world_robot)
                    ts.append(time.perf_counter() - t0)
                out[f"render_{cam}_{w_}x{h_}_ms"] = 1e3 * statistics.median(ts)
            finally:
                w.close()
    return out


def single_process_rtf(rendered_overrides: list[str], seed: int) -> dict[str, float]:
    """Real-time factor of one complete placement run alone in this process (no batch workers competing)."""
    from taskflow.loader import load_mission
    from taskflow.runtime import run_mission

    out = {}
    for name, ov in (("geometric", []), ("rendered", rendered_overrides)):
        r = run_mission(load_mission(str(MISSIONS / "viki_hyco.yaml"), ov), seed=seed, record=False)
        out[f"rtf_single_{name}"] = float(r.timing["real_time_factor"])
    return out


def fmt(v: float | None, scale: float = 100.0, nd: int = 1) -> str:
    return "-" if v is None else f"{v * scale:.{nd}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--rendered-trials", type=int, default=5)
    ap.add_argument("--rendered-size", default="320x180")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="directory for the batch.json files (default: a temp dir)")
    ap.add_argument("--quick", action="store_true", help="3 geometric and 1 rendered trial per batch")
    ap.add_argument("--fidelity", nargs="*", default=["paper"], metavar="LEVEL",
                    help="viki_ground fidelity levels (besides ideal) at which forward, backward and complete "
                         "placement run again (default: paper; none: ideal only)")
    ap.add_argument("--table-only", action="store_true",
                    help="only the paper's table (forward, backward, complete at each level): no baselines, no "
                         "rendered runs, no costs")
    args = ap.parse_args()
    if args.quick:
        args.trials, args.rendered_trials = 3, 1
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="viki-bench-"))
    rw, rh = (int(v) for v in args.rendered_size.lower().split("x"))
    batches = [
        ("forward", MISSIONS / "viki_forward.yaml", [], args.trials),
        ("backward", MISSIONS / "viki_backward.yaml", [], args.trials),
        ("complete", MISSIONS / "viki_hyco.yaml", [], args.trials),
        ("vs_only", MISSIONS / "viki_vs_only.yaml", [], args.trials),
        ("mgbm", MISSIONS / "viki_mgbm.yaml", [], args.trials),
        ("complete_rendered", MISSIONS / "viki_hyco.yaml",
         ["world.params.perception=rendered", f"world.params.image_size=[{rw}, {rh}]"], args.rendered_trials),
    ]
    rendered_overrides = batches[-1][2]
    if args.table_only:
        batches = [b for b in batches if b[0] in PAPER_TABLE]
    for level in args.fidelity:
        batches += [(f"{name}_{level}", path, [*ov, f"world.params.fidelity={level}"], n)
                    for name, path, ov, n in batches if name in PAPER_TABLE]
    results: dict[str, Any] = {}
    t_all = time.perf_counter()
    for name, path, overrides, n in batches:
        res = run_batch(str(path), trials=n, workers=args.workers, seed=args.seed, overrides=overrides,
                        out=out / name)
        results[name] = batch_stats(res)
        print(f"  {name}: {n} trials in {res['timing']['total_wall_s']:.1f} s", flush=True)
    costs: dict[str, float] = {}
    if not args.table_only:
        costs = law_costs()
        costs.update(render_costs())
        costs.update(single_process_rtf(rendered_overrides, args.seed))
    total = time.perf_counter() - t_all

    print()
    print("ViKi-HyCo in simulation vs the paper (final object position in the robot frame minus the goal; "
          "cm, |error| mean ± std over all trials)")
    hdr = (f"{'experiment':22s} {'n':>3s} {'success':>8s} {'95 % Wilson':>12s} {'|X| cm':>13s} {'|X| mean 95 %':>14s} "
           f"{'|Y| cm':>13s} {'|Y| mean 95 %':>14s} {'X,Y mean cm':>13s} {'time s':>12s} {'RTF':>6s} | paper")
    print(hdr)
    print("-" * len(hdr))
    for name, _, _, _ in batches:
        r = results[name]
        paper, note = PAPER[name.split("_")[0] if name.split("_")[-1] in args.fidelity else name]
        if paper is None:
            ptxt = note
        else:
            px, psx, py, psy = paper
            ptxt = (f"X {100 * px:.2f}" + (f" ± {100 * psx:.2f}" if psx is not None else "") +
                    f", Y {100 * py:.2f}" + (f" ± {100 * psy:.2f}" if psy is not None else "") + f" ({note})")
        t = "-" if r["time_s_mean"] is None else f"{r['time_s_mean']:.1f}±{r['time_s_std']:.1f}"
        wil = f"{100 * r['success_ci95'][0]:.0f}-{100 * r['success_ci95'][1]:.0f} %"
        cix = "-" if r["abs_x_ci95"][0] is None else f"{fmt(r['abs_x_ci95'][0])}-{fmt(r['abs_x_ci95'][1])}"
        ciy = "-" if r["abs_y_ci95"][0] is None else f"{fmt(r['abs_y_ci95'][0])}-{fmt(r['abs_y_ci95'][1])}"
        print(f"{name:22s} {r['trials']:3d} {100 * r['success_rate']:7.0f}% {wil:>12s} "
              f"{fmt(r['abs_x_mean']):>6s}±{fmt(r['abs_x_std']):<6s} {cix:>14s} "
              f"{fmt(r['abs_y_mean']):>6s}±{fmt(r['abs_y_std']):<6s} {ciy:>14s} "
              f"{fmt(r['x_mean']):>6s},{fmt(r['y_mean']):<6s} {t:>12s} {r['rtf_mean'] or 0:6.1f} | {ptxt}")
    print()
    for name in results:
        print(f"  {name}: outcomes {results[name]['outcomes']}")
    print()
    if args.table_only:
        print(f"batch files under {out}; total {total:.0f} s")
        print(json.dumps({"workers": args.workers, "trials": args.trials, "fidelity": args.fidelity, "seed": args.seed,
                          "results": results, "total_wall_s": total}))
        return
    print(f"control law alone (eq. 19-26 + eq. 5): visual tick {costs['law_visual_tick_us']:.0f} us, kinematic tick "
          f"{costs['law_kinematic_tick_us']:.0f} us, whole task step {costs['task_step_us']:.0f} us "
          f"(paper: 2 ms; target <= 100 us)")
    print("rendered perception per frame: " + ", ".join(f"{k[7:-3]} {v:.0f} ms" for k, v in costs.items()
                                                        if k.startswith("render_")) + " (paper: 12 + 30 ms)")
    print(f"real-time factor, complete placement, mean per trial in the batches ({args.workers} workers): geometric "
          f"{results['complete']['rtf_mean']:.1f}x (target >= 20x), rendered {rw}x{rh} "
          f"{results['complete_rendered']['rtf_mean']:.2f}x (target >= 1x); one run alone in this process: "
          f"geometric {costs['rtf_single_geometric']:.1f}x, rendered {costs['rtf_single_rendered']:.2f}x")
    print(f"batch files under {out}; total {total:.0f} s")
    print(json.dumps({"workers": args.workers, "trials": args.trials, "fidelity": args.fidelity,
                      "rendered_trials": args.rendered_trials,
                      "rendered_size": [rw, rh], "seed": args.seed, "results": results, "costs": costs,
                      "total_wall_s": total}))


if __name__ == "__main__":
    main()
