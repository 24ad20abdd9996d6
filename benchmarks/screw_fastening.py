"""Screw fastening on a moving part: the paper's Tables 1 and 2 beside ours.

Runs ``missions/screw_fastening.yaml`` (conveyor, 50 mm/s) and ``missions/screw_fastening_trolley.yaml``
(irregular trolley) for N sequences of four screws each (seeds 0..N-1), in the pose perception mode,
without and with the velocity feed-forward; then R sequences in the rendered mode (pixels → ArUco →
solvePnP) on the conveyor.  Everything is measured from the simulator's ground truth.

    python benchmarks/screw_fastening.py                 # 10 x 4 screws per scenario, 2 rendered
    python benchmarks/screw_fastening.py --sequences 3 --rendered 0 --workers 2

Columns (paper, Table 1): time per screw (one ``foreach`` iteration: approach, activation,
fastening, retract) mean ± std; screwing time (tool activation start → fastened) mean ± std; success
rate (bolts fastened / bolts).  Table 2: tool translation and rotation error min / max / mean while
the screwdriver runs (activation and fastening).  Also: the control tick (both twists, the
Jacobian, the admittance; median of a task step on a synthetic observation), the real-time factor
of the pose-mode runs, and the rendered mode's marker error against the truth.  The last line is
JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

PAPER = {  # papers/002, Tables 1 and 2 (real robot, 10 sequences x 4 screws per scenario)
    "conveyor": {"time_per_screw": (9.45, 2.07), "screwing": (5.28, 1.88), "success": 92.5,
                 "err_t": (0.11, 8.83, 1.57), "err_r": (0.006, 1.76, 0.097)},
    "trolley": {"time_per_screw": (11.55, 2.51), "screwing": (7.15, 2.59), "success": 67.5,
                "err_t": (0.11, 20.5, 3.82), "err_r": (0.006, 2.91, 0.228)},
}
TARGETS = {"conveyor": (97.5, 1.0), "trolley": (90.0, 2.0)}  # success %, mean translation error mm


def _register() -> None:
    import taskflow_robots.mobile_iiwa  # noqa: F401
    import taskflow_sim.screw_world  # noqa: F401
    import taskflow_tasks.screw_tasks  # noqa: F401


def run_one(job: tuple[str, int, bool, str]) -> dict[str, Any]:
    """One sequence: (mission file, seed, feed-forward, perception) → its numbers."""
    mission_file, seed, ff, perception = job
    _register()
    from taskflow.loader import load_mission
    from taskflow.runtime import run_mission

    overrides = [f"profiles.prediction.feedforward.enabled={'true' if ff else 'false'}",
                 f"world.params.perception={perception}"]
    m = load_mission(ROOT / mission_file, overrides)
    t0, c0 = time.perf_counter(), time.process_time()
    r = run_mission(m, seed=seed, record=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = r.summary
    met = s["metrics"]
    its = s["iterations"]
    log = met.get("screw_log") or []
    return {
        "mission": mission_file, "seed": seed, "ff": ff, "perception": perception, "outcome": r.outcome,
        "sim_s": s["sim_time_s"], "wall_s": wall, "cpu_s": cpu,
        "screws_total": met.get("screws_total", 4), "screws_succeeded": met.get("screws_succeeded", 0),
        "iteration_s": [it["t_end"] - it["t_start"] for it in its],
        "screwing_s": [e["t_end"] - e["t_activate"] for e in log if e.get("outcome") == "fastened"],
        "samples": met.get("error_samples", 0),
        "err_t": (met.get("err_t_min_mm"), met.get("err_t_max_mm"), met.get("err_t_mean_mm")),
        "err_r": (met.get("err_r_min_deg"), met.get("err_r_max_deg"), met.get("err_r_mean_deg")),
        "perception_rms": (met.get("perception_rms_xy_mm"), met.get("perception_rms_z_mm"), met.get("perception_rms_r_deg")),
        "failures": [e.get("outcome") for e in log if e.get("outcome") != "fastened"],
    }


def aggregate(runs: list[dict[str, Any]]) -> dict[str, Any]:
    its = [x for r in runs for x in r["iteration_s"]]
    scr = [x for r in runs for x in r["screwing_s"]]
    total = sum(r["screws_total"] for r in runs)
    ok = sum(r["screws_succeeded"] for r in runs)
    withs = [r for r in runs if r["samples"] and r["err_t"][0] is not None]
    n = sum(r["samples"] for r in withs)

    def stats(key: str) -> tuple[float, float, float] | None:
        if not withs:
            return None
        return (min(r[key][0] for r in withs), max(r[key][1] for r in withs),
                sum(r[key][2] * r["samples"] for r in withs) / n)

    sim = sum(r["sim_s"] for r in runs)
    wall = sum(r["wall_s"] for r in runs)
    cpu = sum(r["cpu_s"] for r in runs)
    ms = lambda xs: (statistics.fmean(xs), statistics.pstdev(xs)) if xs else (math.nan, math.nan)  # noqa: E731
    return {"sequences": len(runs), "screws": total, "succeeded": ok, "success": 100.0 * ok / total if total else math.nan,
            "time_per_screw": ms(its), "screwing": ms(scr), "err_t": stats("err_t"), "err_r": stats("err_r"),
            "rtf": sim / wall if wall else math.nan, "rtf_cpu": sim / cpu if cpu else math.nan, "outcomes": [r["outcome"] for r in runs],
            "failures": [f for r in runs for f in r["failures"]]}


def control_tick_us(n: int = 3100, feedforward: bool = True) -> float:
    """Wall time of one task step (both twists, Jacobian, admittance; feed-forward on by default):
    the smallest median over batches of 300 ticks."""
    _register()
    import numpy as np

    from taskflow_robots.mobile_iiwa import MobileIiwa
    from taskflow.api import Observation, TaskContext
    from taskflow_tasks.impedance import ImpedanceProfile
    from taskflow_tasks.pid import PidProfile
    from taskflow_tasks.screw_tasks import ArmParams, PbvsArm, Prediction

    robot = MobileIiwa(MobileIiwa.Params())
    pose = {"xyz": [0.0, 0.0, 0.67], "rpy_deg": [145.0, -24.6, -30.8]}
    params = ArmParams.model_validate({"camera_target": pose, "target": {"xyz": [0.14, 0.06, 0.0075], "rpy_deg": [180, 0, -90]}})
    pid = PidProfile(kp=[4, 4, 4, 5, 5, 5], ki=[2, 2, 2, 4, 4, 4], u_max=[0.5, 0.5, 0.5, 0.1, 0.1, 0.1])
    profiles = {"platform": pid, "arm": pid, "impedance": ImpedanceProfile(K=[300, 300, 600], D=[60, 60, 80], force=[0, 0, 3]),
                "prediction": Prediction(enabled=feedforward)}
    task = PbvsArm(TaskContext(0.0, params, profiles, {}, robot, dt=0.01))  # the missions' 100 Hz
    q = np.array(robot.params.q_home)
    H_co = params.camera_target.matrix()
    H_co[0, 3] += 0.01
    times = []
    for k in range(n):
        t = k / 100.0
        marker = {"H_co": H_co, "t": t - 0.03, "seq": k // 3}
        obs = Observation(t, state={"q": q, "q_ref": q, "odom": np.array([0.05 * t, 0.0, 0.0])},
                          sensors={"marker": marker, "wrench": np.array([0.1, -0.2, -3.0, 0.0, 0.0, 0.0])})
        t0 = time.perf_counter()
        task.step(obs)
        times.append(time.perf_counter() - t0)
    # the machine may be shared: the least-disturbed of several batches is the cost of the code
    batches = [times[i:i + 300] for i in range(100, len(times) - 299, 300)]
    return 1e6 * min(statistics.median(b) for b in batches)


def fmt(x: float | None, d: int = 2) -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{d}f}"


def table(rows: list[tuple[str, dict[str, Any]]]) -> str:
    out = ["Table 1 — time per screw, screwing time, success",
           f"{'scenario':38s} {'time/screw (s)':>16s} {'screwing (s)':>15s} {'success':>9s}  sequences"]
    for name, a in rows:
        tp, sc = a["time_per_screw"], a["screwing"]
        out.append(f"{name:38s} {fmt(tp[0]):>7s} ± {fmt(tp[1]):<6s} {fmt(sc[0]):>6s} ± {fmt(sc[1]):<6s} "
                   f"{fmt(a['success'], 1):>7s} %  {a.get('sequences', '—')}")
    out += ["", "Table 2 — errors while the screwdriver runs (activation + operation), ground truth",
            f"{'scenario':38s} {'translation min / max / mean (mm)':>36s} {'rotation min / max / mean (deg)':>36s}"]
    for name, a in rows:
        et, er = a["err_t"] or (None,) * 3, a["err_r"] or (None,) * 3
        out.append(f"{name:38s} {fmt(et[0]):>10s} / {fmt(et[1]):>6s} / {fmt(et[2]):<6s}       "
                   f"{fmt(er[0], 3):>8s} / {fmt(er[1], 3):>6s} / {fmt(er[2], 3):<6s}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequences", type=int, default=10, help="sequences of 4 screws per scenario (pose mode)")
    ap.add_argument("--rendered", type=int, default=2, help="sequences in the rendered mode (conveyor, feed-forward on)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)

    scenarios = [("conveyor", "missions/screw_fastening.yaml"), ("trolley", "missions/screw_fastening_trolley.yaml")]
    jobs: list[tuple[str, int, bool, str]] = [(f, s, ff, "pose") for _, f in scenarios for ff in (False, True)
                                               for s in range(args.sequences)]
    jobs += [("missions/screw_fastening.yaml", s, True, "rendered") for s in range(args.rendered)]
    t0 = time.perf_counter()
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            results = list(pool.map(run_one, jobs))
    else:
        results = []
        for j in jobs:
            results.append(run_one(j))
            r = results[-1]
            print(f"  {Path(r['mission']).stem:26s} seed {r['seed']:2d} ff={int(r['ff'])} {r['perception']:8s} "
                  f"{r['outcome']:9s} {r['screws_succeeded']}/{r['screws_total']} err_t mean {fmt(r['err_t'][2])} mm "
                  f"sim {r['sim_s']:.1f} s wall {r['wall_s']:.1f} s", flush=True)
    wall = time.perf_counter() - t0

    rows: list[tuple[str, dict[str, Any]]] = []
    agg: dict[str, Any] = {}
    for name, f in scenarios:
        rows.append((f"{name} — paper (real robot)", {**PAPER[name], "sequences": 10}))
        for ff in (False, True):
            sel = [r for r in results if r["mission"] == f and r["ff"] == ff and r["perception"] == "pose"]
            a = aggregate(sel)
            key = f"{name}{'_ff' if ff else ''}"
            agg[key] = a
            rows.append((f"{name} — ours, pose{' + feed-forward' if ff else ''}", a))
    rend = [r for r in results if r["perception"] == "rendered"]
    if rend:
        a = aggregate(rend)
        agg["conveyor_rendered_ff"] = a
        rows.append(("conveyor — ours, rendered + ff", a))
    print()
    print(table(rows))
    tick = control_tick_us()
    tick_plain = control_tick_us(feedforward=False)
    pose_agg = aggregate([r for r in results if r["perception"] == "pose"]) if args.sequences else None
    rtf = pose_agg["rtf"] if pose_agg else math.nan
    rtf_cpu = pose_agg["rtf_cpu"] if pose_agg else math.nan
    print()
    print(f"control tick (both twists, Jacobian, admittance): {tick_plain:.0f} µs; with the feed-forward {tick:.0f} µs "
          "(target ≤ 300 µs)")
    print(f"pose mode real-time factor: {rtf:.1f}x wall-clock, {rtf_cpu:.1f}x per CPU second of the process "
          f"(target ≥ 10x); benchmark wall time {wall:.0f} s")
    if rend:
        pr = [r["perception_rms"] for r in rend if r["perception_rms"][0] is not None]
        if pr:
            print("rendered marker error vs truth (RMS over frames): "
                  f"{statistics.fmean(p[0] for p in pr):.2f} mm across, {statistics.fmean(p[1] for p in pr):.2f} mm along the view, "
                  f"{statistics.fmean(p[2] for p in pr):.3f} deg")
    checks = {}
    for name in ("conveyor", "trolley"):
        succ, err = TARGETS[name]
        for suffix in ("", "_ff"):
            a = agg.get(name + suffix)
            if a and a["err_t"]:
                checks[name + suffix] = bool(a["success"] >= succ and a["err_t"][2] <= err and a["time_per_screw"][0] <= 9.45)
    summary = {"benchmark": "screw_fastening", "sequences": args.sequences, "rendered": args.rendered,
               "control_tick_us": round(tick_plain, 1), "control_tick_ff_us": round(tick, 1), "pose_rtf": round(rtf, 2), "pose_rtf_cpu": round(rtf_cpu, 2), "wall_s": round(wall, 1),
               "targets_met": checks,
               "results": {k: {"success_pct": round(a["success"], 1),
                               "time_per_screw_s": [round(x, 2) for x in a["time_per_screw"]],
                               "screwing_s": [round(x, 2) for x in a["screwing"]],
                               "err_t_mm": [round(x, 3) for x in a["err_t"]] if a["err_t"] else None,
                               "err_r_deg": [round(x, 4) for x in a["err_r"]] if a["err_r"] else None,
                               "outcomes": a["outcomes"], "failures": a["failures"]} for k, a in agg.items()}}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
