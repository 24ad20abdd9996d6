"""How long ``taskflow verify`` takes: every shipped mission, and a generated mission of 1,000 states.

For each ``missions/*.yaml``: the model's size (configurations, steps, time step), the time to build it, and
each check's time (``verify_mission``: Storm answers ``no_trap``, ``timed_exit``, ``duration`` and ``outcomes``;
``region_conflicts`` is read off the model), and the total.  Then the same for a machine of ``--size`` states
drawn by ``tests/verify/machines.py`` (``generate(seed, size, ...)`` on the toy robot and world), whose
state-multiplying features are set by ``--p-parallel``, ``--p-history``, ``--p-foreach`` and ``--p-since``
(default 0: plain nested composites with guards, timeouts, events, action ends and ``done`` by outcome; with
history or ``since`` clocks at a few per cent of 1,000 states the model grows past what builds in minutes — see
BENCHMARKS.md).  Targets (issue 22): each shipped mission < 2 s, the 1,000-state machine < 30 s.  Times are wall
clock; ``verify_cpu_s`` is the process's CPU time for the same call (single-threaded, so it is the wall time a quiet
machine gives, and what to compare on a loaded one).
``--prism-build MISSION`` also times Storm's own PRISM parser and builder on the exported text of that shipped
mission against the sparse model the checks build directly (``taskflow.verify.storm.StormModel``).

Usage: ``python benchmarks/verify.py [--size 1000] [--seed 0] [--p-history 0.0] ... [--prism-build NAME]``.  The
last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "verify")]

import toys  # the toy robot, world and tasks the generated machine names
from machines import generate

from taskflow.execution.provenance import versions
from taskflow.mission.loader import load_mission, load_mission_text
from taskflow.mission.model import CompiledMission
from taskflow.verify import verify_mission

CHECKS = ("no_trap", "timed_exit", "duration", "outcomes", "region_conflicts")


def measure(name: str, mission: CompiledMission, load_s: float) -> dict[str, Any]:
    t, cpu = time.perf_counter(), time.process_time()
    v = verify_mission(mission)
    total, cpu = time.perf_counter() - t, time.process_time() - cpu
    m = v.model
    return {"mission": name, "states": len(mission.states), "configurations": m.n_states, "steps": m.n_steps,
            "tick_s": m.quantum, "load_s": load_s, "build_s": v.build_seconds, "verify_s": total, "verify_cpu_s": cpu,
            "checks_s": {c.name: c.seconds for c in v.checks}, "verdicts": {c.name: c.verdict for c in v.checks}}


def prism_vs_direct(path: Path) -> dict[str, Any]:
    """Storm's PRISM route (parse the exported text, build) against the direct sparse build, on one mission."""
    import os
    import tempfile

    import stormpy
    import stormpy.developer as dev

    from taskflow.verify.export import prism_text
    from taskflow.verify.model import build_model
    from taskflow.verify.storm import StormModel

    model = build_model(load_mission(path))
    t = time.perf_counter()
    StormModel(model)
    direct = time.perf_counter() - t
    fd, name = tempfile.mkstemp(suffix=".prism")
    with os.fdopen(fd, "w") as f:
        f.write(prism_text(model))
    try:
        t = time.perf_counter()
        dev.build_sparse_model(stormpy.parse_prism_program(name), dev.BuilderOptions())
        text = time.perf_counter() - t
    finally:
        os.unlink(name)
    return {"mission": path.stem, "configurations": model.n_states, "prism_s": text, "direct_s": direct}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=1000, help="states of the generated machine")
    ap.add_argument("--seed", type=int, default=0)
    for knob in ("parallel", "history", "foreach", "since"):
        ap.add_argument(f"--p-{knob}", type=float, default=0.0)
    ap.add_argument("--prism-build", default=None, metavar="NAME", help="a shipped mission (file stem)")
    args = ap.parse_args()
    toys.register()
    prism = prism_vs_direct(ROOT / "missions" / f"{args.prism_build}.yaml") if args.prism_build else None
    rows = []
    for path in sorted((ROOT / "missions").glob("*.yaml")):
        t = time.perf_counter()
        mission = load_mission(path)
        rows.append(measure(path.stem, mission, time.perf_counter() - t))
    text = generate(args.seed, args.size, p_parallel=args.p_parallel, p_history=args.p_history,
                    p_foreach=args.p_foreach, p_since=args.p_since)
    t = time.perf_counter()
    mission = load_mission_text(text, f"generated_{args.seed}_{args.size}.yaml")
    generated = measure(f"generated (seed {args.seed}, {args.size} states)", mission, time.perf_counter() - t)
    rows.append(generated)

    width = max(len(r["mission"]) for r in rows)
    head = f"{'mission':{width}s} {'states':>6s} {'configs':>8s} {'steps':>8s} {'tick':>5s} {'build':>7s} " + \
        " ".join(f"{c[:10]:>10s}" for c in CHECKS) + f" {'total':>7s}"
    print(head)
    for r in rows:
        fails = [c for c in CHECKS if r["verdicts"].get(c) != "holds"]
        print(f"{r['mission']:{width}s} {r['states']:6d} {r['configurations']:8d} {r['steps']:8d} {r['tick_s']:5g} "
              f"{r['build_s']:7.3f} " + " ".join(f"{r['checks_s'][c]:10.3f}" for c in CHECKS) +
              f" {r['verify_s']:7.3f}" + (f"  fails: {', '.join(fails)}" if fails else ""))
    shipped = rows[:-1]
    worst = max(shipped, key=lambda r: r["verify_s"])
    print(f"slowest shipped mission: {worst['mission']} {worst['verify_s']:.2f} s (CPU {worst['verify_cpu_s']:.2f} s; "
          "target < 2 s); "
          f"generated: {generated['verify_s']:.2f} s for {generated['configurations']} configurations (target < 30 s)")
    if prism is not None:
        print(f"{args.prism_build}: {prism['configurations']} configurations — Storm's PRISM parse + build "
              f"{prism['prism_s']:.2f} s, StormModel built directly {prism['direct_s']:.3f} s")
    print(json.dumps({"shipped": shipped, "generated": generated, "shipped_max_s": worst["verify_s"],
                      "generated_s": generated["verify_s"], "prism_vs_direct": prism, "knobs": vars(args),
                      "versions": versions()}))


if __name__ == "__main__":
    main()
