"""Screw fastening on a moving part: the paper's Tables 1 and 2 beside ours, and a robustness table.

Runs ``missions/screw_fastening.yaml`` (conveyor, 50 mm/s) and ``missions/screw_fastening_trolley.yaml``
(irregular trolley) for N sequences of four screws each (seeds 0..N-1), in the pose perception mode,
without and with the velocity feed-forward (the ``prediction`` profile), under each world fidelity
level asked (``ideal``: the world's defaults; ``paper``: ``world.params.fidelity=paper``, the paper's
latency and platform delay, :class:`taskflow_sim.screw.world.ScrewWorldParams`); then R sequences in the
rendered mode (pixels → ArUco → solvePnP) on the conveyor.  Everything is measured from the simulator's
ground truth.

    python benchmarks/screw_fastening.py                 # 10 x 4 screws per scenario and fidelity, 2 rendered
    python benchmarks/screw_fastening.py --sequences 3 --rendered 0 --workers 2 --fidelity ideal

``--robustness`` instead runs the conveyor mission over part speeds (30, 50, 65, 80 mm/s) and bolt
layouts (``world.params.bolts`` with the matching operation poses ``parameters.screws``) with
:func:`taskflow.campaigns.batch.run_batch` (one campaign per layout and arm, the speeds swept; seeds 0..N-1 in
every condition), with the prediction profile on and, on the default layout, off (the paper's law):
bolts fastened with their Wilson 95 % interval, sequences that met the mission's rule with theirs, and
the ground-truth translation error while the screwdriver ran (mean over every sample at a bolt, max).

    python benchmarks/screw_fastening.py --robustness --sequences 5 --workers 2

The lost marker and the uneven trolleys (issue 25) are named rows in ``benchmarks/screw_faults.py``.

Columns (paper, Table 1): time per screw (one ``foreach`` iteration — one of the mission's
screws — approach, activation, fastening, retract; failed ones included) mean ± std; screwing time
(tool activation start → fastened, over fastened operations) mean ± std; success rate (the mission's
screws whose iteration succeeded / the mission's screws; with its Wilson 95 % interval, which counts every
screw as an independent trial, and the sequences that met the rule with theirs), with the world's count of screwdriver
operations beside it (fastened / started; ``no bolt``: activations with no bolt within the coupling
tolerance); the time per screw has the t 95 % interval of its mean.  Table 2: tool translation and rotation error to the operation's bolt, min / max / mean
over every control tick while the screwdriver ran (activation and fastening), twice: over the
fastened operations only, and over every operation that had a bolt under the tool (fastened or not —
the paper's Table 2 covers all its screwing attempts).  Also: the control tick (both twists, the
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

from taskflow.campaigns.stats import mean_interval, wilson_interval

PAPER = {  # papers/002, Tables 1 and 2 (real robot, 10 sequences x 4 screws per scenario)
    "conveyor": {"time_per_screw": (9.45, 2.07), "screwing": (5.28, 1.88), "success": 92.5,
                 "err_t": (0.11, 8.83, 1.57), "err_r": (0.006, 1.76, 0.097)},
    "trolley": {"time_per_screw": (11.55, 2.51), "screwing": (7.15, 2.59), "success": 67.5,
                "err_t": (0.11, 20.5, 3.82), "err_r": (0.006, 2.91, 0.228)},
}
TARGETS = {"conveyor": (97.5, 1.0), "trolley": (90.0, 2.0)}  # success %, mean translation error mm


def _register() -> None:
    import taskflow_robots.mobile_iiwa  # noqa: F401
    import taskflow_sim.screw.world  # noqa: F401
    import taskflow_tasks.screw.home
    import taskflow_tasks.screw.mobile_pbvs  # noqa: F401


def run_one(job: tuple[str, int, bool, str, str]) -> dict[str, Any]:
    """One sequence: (mission file, seed, feed-forward, perception, fidelity) → its numbers."""
    mission_file, seed, ff, perception, fidelity = job
    _register()
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    overrides = [f"profiles.prediction.feedforward.enabled={'true' if ff else 'false'}",
                 f"world.params.perception={perception}", f"world.params.fidelity={fidelity}"]
    m = load_mission(ROOT / mission_file, overrides)
    t0, c0 = time.perf_counter(), time.process_time()
    r = run_mission(m, seed=seed, record=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = r.summary
    met = s["metrics"]
    its = [it for it in s["iterations"] if it["state"].endswith("operate.screws")]
    log = met.get("operation_log") or []
    n_items = len(m.spec.parameters["screws"])
    out = {
        "mission": mission_file, "seed": seed, "ff": ff, "perception": perception, "fidelity": fidelity, "outcome": r.outcome,
        "sim_s": s["sim_time_s"], "wall_s": wall, "cpu_s": cpu,
        # the mission's screws: an item not reached (the run ended first) counts as not fastened
        "items": n_items, "items_succeeded": sum(it["outcome"] == "succeeded" for it in its),
        "operations": met.get("operations", 0), "operations_fastened": met.get("operations_fastened", 0),
        "operations_no_bolt": met.get("operations_no_bolt", 0),
        "iteration_s": [it["t_end"] - it["t_start"] for it in its],
        "screwing_s": [op["screwing_s"] for op in log if op["outcome"] == "fastened"],
        "perception_rms": (met.get("perception_rms_xy_mm"), met.get("perception_rms_z_mm"), met.get("perception_rms_r_deg")),
        # why each failed item failed: the operation's failure, or the state that gave up before any activation
        "failures": [op["failure"] or op["outcome"] for op in log if op["outcome"] != "fastened"]
                    + ["no activation"] * max(0, sum(it["outcome"] != "succeeded" for it in its) - sum(op["outcome"] == "failed" for op in log)),
    }
    for group in ("fastened", "at_bolt"):
        out[f"{group}_samples"] = met.get(f"{group}_err_samples", 0)
        out[f"{group}_err_t"] = tuple(met.get(f"{group}_err_t_{k}_mm") for k in ("min", "max", "mean"))
        out[f"{group}_err_r"] = tuple(met.get(f"{group}_err_r_{k}_deg") for k in ("min", "max", "mean"))
    return out


def aggregate(runs: list[dict[str, Any]]) -> dict[str, Any]:
    its = [x for r in runs for x in r["iteration_s"]]
    scr = [x for r in runs for x in r["screwing_s"]]
    total = sum(r["items"] for r in runs)
    ok = sum(r["items_succeeded"] for r in runs)

    def stats(group: str, key: str) -> tuple[float, float, float] | None:
        """min / max / sample-weighted mean over the runs' samples of ``group``."""
        withs = [r for r in runs if r[f"{group}_samples"] and r[f"{group}_{key}"][0] is not None]
        if not withs:
            return None
        n = sum(r[f"{group}_samples"] for r in withs)
        return (min(r[f"{group}_{key}"][0] for r in withs), max(r[f"{group}_{key}"][1] for r in withs),
                sum(r[f"{group}_{key}"][2] * r[f"{group}_samples"] for r in withs) / n)

    sim = sum(r["sim_s"] for r in runs)
    wall = sum(r["wall_s"] for r in runs)
    cpu = sum(r["cpu_s"] for r in runs)
    ms = lambda xs: (statistics.fmean(xs), statistics.pstdev(xs)) if xs else (math.nan, math.nan)
    return {"sequences": len(runs), "screws": total, "succeeded": ok, "success": 100.0 * ok / total if total else math.nan,
            "operations": sum(r["operations"] for r in runs), "operations_fastened": sum(r["operations_fastened"] for r in runs),
            "operations_no_bolt": sum(r["operations_no_bolt"] for r in runs),
            "time_per_screw": ms(its), "screwing": ms(scr),
            "err_t": stats("fastened", "err_t"), "err_r": stats("fastened", "err_r"),
            "at_bolt_err_t": stats("at_bolt", "err_t"), "at_bolt_err_r": stats("at_bolt", "err_r"),
            "rtf": sim / wall if wall else math.nan, "rtf_cpu": sim / cpu if cpu else math.nan, "outcomes": [r["outcome"] for r in runs],
            "failures": [f for r in runs for f in r["failures"]],
            "success_ci95": [100 * x for x in wilson_interval(ok, total)] if total else None,
            "sequences_ci95": [100 * x for x in wilson_interval(sum(r["outcome"] == "succeeded" for r in runs), len(runs))]
            if runs else None,
            "time_per_screw_ci95": _ci(its)}


def _ci(xs: list[float]) -> list[float] | None:
    """The t 95 % interval of the mean of ``xs`` (None below two values)."""
    if len(xs) < 2:
        return None
    m = mean_interval(xs)
    return [m.low, m.high]  # type: ignore[list-item]


def control_tick_us(n: int = 3100, feedforward: bool = True) -> float:
    """Wall time of one task step (both twists, Jacobian, admittance; feed-forward on by default):
    the smallest median over batches of 300 ticks."""
    _register()
    import numpy as np
    from taskflow_robots.mobile_iiwa import MobileIiwa
    from taskflow_tasks.core.impedance import ImpedanceProfile
    from taskflow_tasks.core.pid import PidProfile
    from taskflow_tasks.screw.mobile_pbvs import ArmParams, PbvsArm
    from taskflow_tasks.screw.prediction import Prediction

    from taskflow.api import Observation
    from taskflow.messages import MarkerPose, Wrench
    from taskflow.testing import task_context

    robot = MobileIiwa(MobileIiwa.Params())
    pose = {"xyz": [0.0, 0.0, 0.67], "rpy_deg": [145.0, -24.6, -30.8]}
    params = ArmParams.model_validate({"camera_target": pose, "target": {"xyz": [0.14, 0.06, 0.0075], "rpy_deg": [180, 0, -90]}})
    pid = PidProfile(kp=[4, 4, 4, 5, 5, 5], ki=[2, 2, 2, 4, 4, 4], u_max=[0.5, 0.5, 0.5, 0.1, 0.1, 0.1])
    profiles = {"platform": pid, "arm": pid, "impedance": ImpedanceProfile(K=[300, 300, 600], D=[60, 60, 80], force=[0, 0, 3]),
                "prediction": Prediction(enabled=feedforward)}
    task = PbvsArm(task_context(PbvsArm, params, robot, profiles, dt=0.01))  # the missions' 100 Hz
    q = np.array(robot.params.q_home)
    H_co = params.camera_target.matrix()
    H_co[0, 3] += 0.01
    times = []
    for k in range(n):
        t = k / 100.0
        marker = MarkerPose(stamp=t - 0.03, frame="camera", T_camera_object=H_co, seq=k // 3)
        wrench = Wrench(stamp=t, frame="tool", force=np.array([0.1, -0.2, -3.0]), torque=np.zeros(3))
        obs = Observation(t, state={"q": q, "q_ref": q, "odom": np.array([0.05 * t, 0.0, 0.0])},
                          sensors={"marker": marker, "wrench": wrench})
        t0 = time.perf_counter()
        task.step(obs)
        times.append(time.perf_counter() - t0)
    # the machine may be shared: the least-disturbed of several batches is the cost of the code
    batches = [times[i:i + 300] for i in range(100, len(times) - 299, 300)]
    return 1e6 * min(statistics.median(b) for b in batches)


def _r(xs: tuple[float, float, float] | None, d: int) -> list[float] | None:
    return [round(x, d) for x in xs] if xs else None


def fmt(x: float | None, d: int = 2) -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{d}f}"


def table(rows: list[tuple[str, dict[str, Any]]]) -> str:
    out = ["Table 1 — time per screw, screwing time, success (the mission's screws); sequences that met the mission's "
           "rule (every screw fastened: outcome succeeded); screwdriver operations",
           f"{'scenario':38s} {'time/screw (s)':>16s} {'mean 95 %':>12s} {'screwing (s)':>15s} {'success':>9s} "
           f"{'95 % Wilson':>12s}  {'sequences ok':>12s} {'95 % Wilson':>12s}  operations fastened / started (no bolt)"]
    for name, a in rows:
        tp, sc = a["time_per_screw"], a["screwing"]
        ops = (f"{a['operations_fastened']} / {a['operations']} ({a['operations_no_bolt']})" if "operations" in a else "—")
        seqs = (f"{a['outcomes'].count('succeeded')} / {a['sequences']}" if "outcomes" in a else "—")
        iv = lambda k, d=0: (f"{fmt(a[k][0], d)}-{fmt(a[k][1], d)}" if a.get(k) else "—")  # noqa: B023 - used in this iteration
        out.append(f"{name:38s} {fmt(tp[0]):>7s} ± {fmt(tp[1]):<6s} {iv('time_per_screw_ci95', 2):>12s} "
                   f"{fmt(sc[0]):>6s} ± {fmt(sc[1]):<6s} {fmt(a['success'], 1):>7s} % {iv('success_ci95') + ' %':>12s}  "
                   f"{seqs:>12s} {iv('sequences_ci95') + ' %':>12s}  {ops}")
    for key, title in (("", "over the fastened operations"),
                       ("at_bolt_", "over every operation with a bolt under the tool (fastened or failed)")):
        out += ["", f"Table 2{'b' if key else ''} — tool error to the bolt while the screwdriver runs (activation + "
                f"operation), ground truth, {title}" + ("; paper: all its attempts" if not key else ""),
                f"{'scenario':38s} {'translation min / max / mean (mm)':>36s} {'rotation min / max / mean (deg)':>36s}"]
        for name, a in rows:
            if key and "real robot" in name:
                continue
            et, er = a[key + "err_t"] or (None,) * 3, a[key + "err_r"] or (None,) * 3
            out.append(f"{name:38s} {fmt(et[0]):>10s} / {fmt(et[1]):>6s} / {fmt(et[2]):<6s}       "
                       f"{fmt(er[0], 3):>8s} / {fmt(er[1], 3):>6s} / {fmt(er[2], 3):<6s}")
    return "\n".join(out)


# --robustness: conveyor speeds and bolt layouts (in the part frame P; the marker frame, in which the mission
# gives its operation poses, lies 0.12 m behind P's origin, and a bolt's head top 7.5 mm above the face)
SPEEDS = (0.03, 0.05, 0.065, 0.08)  # m/s
LAYOUTS = {
    "square (default)": ((0.02, 0.06), (0.02, -0.06), (0.12, 0.06), (0.12, -0.06)),
    "two, offset": ((0.06, 0.08), (0.10, -0.07)),
    "wide corners": ((-0.02, 0.10), (-0.02, -0.10), (0.17, 0.10), (0.17, -0.10)),
}


def layout_overrides(bolts: tuple[tuple[float, float], ...]) -> list[str]:
    """The world's ``bolts`` and the mission's matching operation poses ``screws`` (marker frame)."""
    screws = ", ".join(f"{{xyz: [{x + 0.12:.4f}, {y:.4f}, 0.0075], rpy_deg: [180, 0, -90]}}" for x, y in bolts)
    return [f"world.params.bolts={[list(b) for b in bolts]}", f"parameters.screws=[{screws}]"]


def robustness_row(trials: list[dict[str, Any]]) -> dict[str, Any]:
    """Bolts fastened and sequences ok (with Wilson 95 % intervals) and the ground-truth translation error
    at the bolts (sample-weighted mean, max) over a condition's trials (batch summaries)."""
    mets = [t["metrics"] for t in trials]
    bolts = sum(int(m.get("bolts_on_part") or 0) for m in mets)
    done = sum(int(m.get("bolts_fastened") or 0) for m in mets)
    ok = sum(t["outcome"] == "succeeded" for t in trials)
    withs = [m for m in mets if m.get("at_bolt_err_samples")]
    n = sum(m["at_bolt_err_samples"] for m in withs)
    return {"sequences": len(trials), "sequences_ok": ok, "sequences_ci95": [100 * x for x in wilson_interval(ok, len(trials))],
            "bolts": bolts, "bolts_fastened": done, "bolts_ci95": [100 * x for x in wilson_interval(done, bolts)] if bolts else None,
            "err_t_mean_mm": sum(m["at_bolt_err_t_mean_mm"] * m["at_bolt_err_samples"] for m in withs) / n if n else None,
            "err_t_max_mm": max(m["at_bolt_err_t_max_mm"] for m in withs) if withs else None,
            "outcomes": [t["outcome"] for t in trials]}


def robustness(sequences: int, workers: int, out: Path | None) -> dict[str, Any]:
    """The robustness table (see the module docstring): one :func:`taskflow.campaigns.batch.run_batch` campaign per
    layout and arm, sweeping ``world.params.speed``."""
    import tempfile

    from taskflow.campaigns.batch import run_batch

    root = Path(tempfile.mkdtemp(prefix="screw-robustness-")) if out is None else out
    sweep = ["world.params.speed=" + ",".join(f"{v:g}" for v in SPEEDS)]
    arms = [(name, bolts, True) for name, bolts in LAYOUTS.items()] + [("square (default)", LAYOUTS["square (default)"], False)]
    rows = []
    for k, (name, bolts, ff) in enumerate(arms):
        res = run_batch(str(ROOT / "missions/screw_fastening.yaml"), trials=sequences, workers=workers, seed=0,
                        overrides=[f"profiles.prediction.feedforward.enabled={'true' if ff else 'false'}", *layout_overrides(bolts)],
                        sweep=sweep, out=root / f"arm{k}")
        for c in res["conditions"]:
            row = robustness_row([t for t in res["trials"] if t["condition"] == c["index"]])
            rows.append({"layout": name, "bolts_per_part": len(bolts), "prediction": ff,
                         "speed_mm_s": round(1e3 * float(c["values"]["world.params.speed"]), 1), **row})
    print(f"\nRobustness — missions/screw_fastening.yaml, pose mode, {sequences} sequences per condition (seeds 0..{sequences - 1}); "
          "error: ground truth while the screwdriver ran, over every operation at a bolt (mm)")
    print(f"{'layout':18s} {'prediction':>10s} {'speed mm/s':>10s} {'bolts fastened':>15s} {'95 % Wilson':>13s} "
          f"{'sequences ok':>12s} {'95 % Wilson':>13s} {'mean / max err mm':>18s}")
    for r in rows:
        ci, sci = r["bolts_ci95"], r["sequences_ci95"]
        print(f"{r['layout']:18s} {'on' if r['prediction'] else 'off':>10s} {r['speed_mm_s']:10g} "
              f"{r['bolts_fastened']:>7d} / {r['bolts']:<5d} {fmt(ci[0], 0) + '-' + fmt(ci[1], 0) + ' %':>13s} "
              f"{r['sequences_ok']:>5d} / {r['sequences']:<4d} {fmt(sci[0], 0) + '-' + fmt(sci[1], 0) + ' %':>13s} "
              f"{fmt(r['err_t_mean_mm']):>8s} / {fmt(r['err_t_max_mm']):<6s}")
    summary = {"benchmark": "screw_fastening_robustness", "sequences": sequences, "records": str(root), "rows": rows}
    print(json.dumps(summary))
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequences", type=int, default=10, help="sequences of 4 screws per scenario (pose mode)")
    ap.add_argument("--rendered", type=int, default=2, help="sequences in the rendered mode (conveyor, feed-forward on)")
    ap.add_argument("--fidelity", nargs="+", default=["ideal", "paper"], choices=["ideal", "paper"],
                    help="world fidelity levels to tabulate (world.params.fidelity)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--robustness", action="store_true", help="the robustness table over speeds and bolt layouts instead")
    ap.add_argument("--out", type=Path, default=None, help="--robustness: the campaigns' directory (default: a temporary one)")
    args = ap.parse_args(argv)
    if args.robustness:
        robustness(args.sequences, args.workers, args.out)
        return 0

    scenarios = [("conveyor", "missions/screw_fastening.yaml"), ("trolley", "missions/screw_fastening_trolley.yaml")]
    jobs: list[tuple[str, int, bool, str, str]] = [(f, s, ff, "pose", fid) for fid in args.fidelity for _, f in scenarios
                                                   for ff in (False, True) for s in range(args.sequences)]
    jobs += [("missions/screw_fastening.yaml", s, True, "rendered", "ideal") for s in range(args.rendered)]
    t0 = time.perf_counter()
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            results = list(pool.map(run_one, jobs))
    else:
        results = []
        for j in jobs:
            results.append(run_one(j))
            r = results[-1]
            print(f"  {Path(r['mission']).stem:26s} seed {r['seed']:2d} ff={int(r['ff'])} {r['perception']:8s} {r['fidelity']:5s} "
                  f"{r['outcome']:9s} {r['items_succeeded']}/{r['items']} err_t mean {fmt(r['fastened_err_t'][2])} mm (fastened) "
                  f"sim {r['sim_s']:.1f} s wall {r['wall_s']:.1f} s", flush=True)
    wall = time.perf_counter() - t0

    rows: list[tuple[str, dict[str, Any]]] = []
    agg: dict[str, Any] = {}
    for name, f in scenarios:
        rows.append((f"{name} — paper (real robot)", {**PAPER[name], "sequences": 10}))
        for fid in args.fidelity:
            for ff in (False, True):
                sel = [r for r in results if r["mission"] == f and r["ff"] == ff and r["perception"] == "pose" and r["fidelity"] == fid]
                a = aggregate(sel)
                key = f"{name}{'_ff' if ff else ''}{'' if fid == 'ideal' else '_' + fid}"
                agg[key] = a
                rows.append((f"{name} — {fid}, pose{' + prediction' if ff else ''}", a))
    rend = [r for r in results if r["perception"] == "rendered"]
    if rend:
        a = aggregate(rend)
        agg["conveyor_rendered_ff"] = a
        rows.append(("conveyor — ideal, rendered + prediction", a))
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
    for key, a in agg.items():
        name = key.split("_")[0]
        if name in TARGETS and a and a["at_bolt_err_t"]:
            if key.endswith("_paper"):  # under the paper-like world: better than the paper's own figures
                checks[key] = bool(a["success"] > PAPER[name]["success"] and a["at_bolt_err_t"][2] < PAPER[name]["err_t"][2])
            elif "rendered" not in key:  # the error target over every attempt at a bolt, as the paper's Table 2
                succ, err = TARGETS[name]
                checks[key] = bool(a["success"] >= succ and a["at_bolt_err_t"][2] <= err and a["time_per_screw"][0] <= 9.45)
    summary = {"benchmark": "screw_fastening", "sequences": args.sequences, "rendered": args.rendered, "fidelity": args.fidelity,
               "control_tick_us": round(tick_plain, 1), "control_tick_ff_us": round(tick, 1), "pose_rtf": round(rtf, 2), "pose_rtf_cpu": round(rtf_cpu, 2), "wall_s": round(wall, 1),
               "targets_met": checks,
               "results": {k: {"success_pct": round(a["success"], 1), "success_ci95_pct": a.get("success_ci95"),
                               "sequences_ci95_pct": a.get("sequences_ci95"),
                               "time_per_screw_ci95_s": a.get("time_per_screw_ci95"),
                               "screws": a["screws"], "screws_succeeded": a["succeeded"],
                               "operations": a["operations"], "operations_fastened": a["operations_fastened"],
                               "operations_no_bolt": a["operations_no_bolt"],
                               "time_per_screw_s": [round(x, 2) for x in a["time_per_screw"]],
                               "screwing_s": [round(x, 2) for x in a["screwing"]],
                               "fastened_err_t_mm": _r(a["err_t"], 3), "fastened_err_r_deg": _r(a["err_r"], 4),
                               "at_bolt_err_t_mm": _r(a["at_bolt_err_t"], 3), "at_bolt_err_r_deg": _r(a["at_bolt_err_r"], 4),
                               "outcomes": a["outcomes"], "failures": a["failures"]} for k, a in agg.items()}}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
