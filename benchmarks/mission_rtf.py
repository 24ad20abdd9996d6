"""Real-time factor of shipped missions, one run each with seed 0, read from each run's ``timing.json``.

Run: ``python benchmarks/mission_rtf.py OUT MISSION[@rendered|@geometric] ...`` — e.g.
``python benchmarks/mission_rtf.py /tmp/rtf/after car_waypoints viki_hyco@rendered``.  The missions and
code are those of the checkout installed in the running interpreter, so running this file with two
checkouts' environments, alternately and one process at a time, compares their speed on one machine
(`BENCHMARKS.md`, "the refactor keeps every figure").  Prints one JSON line per run, then a JSON line
with all of them.

``python benchmarks/mission_rtf.py --floor OUT [--repeats N] [MISSION ...]`` (issue 24): each mission (all of
``missions/*.yaml`` when none is named) in its fast perception mode (``geometric`` / ``pose``,
:func:`physics_floor.fast_overrides`), then its world's driven floor (:func:`physics_floor.floor_run`: the
same scene for the same simulated seconds, a fixed command, no control law), alternately, ``N`` times (default
1); prints per mission the median RTFs and ``ratio``, the median over the pairs of mission RTF ÷ floor RTF, against
the issue's target 0.6.
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path
from typing import Any

from physics_floor import MISSIONS, fast_overrides, floor_run, load

TARGET = 0.6
"""Issue 24's target for a mission's RTF ÷ its world's floor."""


def overrides(stem: str, mode: str) -> list[str]:
    if mode == "rendered":
        return ["world.params.perception=rendered"] + (["world.params.image_size=[320, 180]"]
                                                       if stem.startswith("viki") else [])
    if mode == "geometric":
        return ["world.params.perception=geometric"]
    return []


def mission_run(mission: Any, out: Path, name: str) -> dict[str, Any]:
    from taskflow.execution.runtime import run_mission

    run = run_mission(mission, seed=0, out_dir=out / name)
    timing = json.loads((out / name / "timing.json").read_text())
    return {"mission": name, "outcome": run.outcome, "sim_s": run.summary["sim_time_s"],
            "rtf": timing.get("real_time_factor"), "wall_s": timing.get("wall_time_s")}


def floor_mode(out: Path, stems: list[str], repeats: int) -> None:
    from taskflow.execution.provenance import versions

    stems = stems or sorted(p.stem for p in MISSIONS.glob("*.yaml"))
    modes = {stem: fast_overrides(stem) for stem in stems}
    missions = {stem: load(stem, modes[stem]) for stem in stems}
    runs: dict[str, list[tuple[dict[str, Any], dict[str, Any]]]] = {stem: [] for stem in stems}
    for r in range(repeats):
        for stem in stems:  # mission, then its floor: machine noise hits both
            m = mission_run(missions[stem], out / f"r{r}", stem)
            f = floor_run(missions[stem], float(m["sim_s"]))
            runs[stem].append((m, f))
    rows = []
    for stem in stems:
        m_rtf = statistics.median(m["rtf"] for m, _ in runs[stem])
        f_rtf = statistics.median(f["rtf"] for _, f in runs[stem])
        ratio = statistics.median(m["rtf"] / f["rtf"] for m, f in runs[stem])  # per alternated pair
        m0 = runs[stem][0][0]
        row = {"mission": stem, "world": missions[stem].spec.world.name, "robot": missions[stem].build_robot().name,
               "overrides": modes[stem], "outcome": m0["outcome"], "sim_s": m0["sim_s"], "repeats": repeats,
               "mission_rtf": round(m_rtf, 2), "floor_rtf": round(f_rtf, 2), "ratio": round(ratio, 3),
               "target_met": ratio >= TARGET,
               "mission_rtfs": [round(m["rtf"], 2) for m, _ in runs[stem]],
               "floor_rtfs": [round(f["rtf"], 2) for _, f in runs[stem]]}
        rows.append(row)
        print(json.dumps(row), flush=True)
    v = versions()
    print(json.dumps({"target": TARGET, "ratios": rows,
                      "versions": {k: v.get(k) for k in ("python", "pybullet", "numpy")}}))


def main(argv: list[str]) -> None:
    from taskflow.mission.loader import load_mission

    if argv[:1] == ["--floor"]:
        rest = argv[1:]
        repeats = 1
        if "--repeats" in rest:
            i = rest.index("--repeats")
            repeats = int(rest[i + 1])
            del rest[i:i + 2]
        if not rest:
            raise SystemExit(__doc__)
        floor_mode(Path(rest[0]), rest[1:], repeats)
        return
    if len(argv) < 2:
        raise SystemExit(__doc__)
    out, rows = Path(argv[0]), []
    for name in argv[1:]:
        stem, _, mode = name.partition("@")
        row = mission_run(load_mission(MISSIONS / f"{stem}.yaml", overrides(stem, mode)), out, name)
        rows.append(row)
        print(json.dumps(row), flush=True)
    print(json.dumps({"runs": rows}))


if __name__ == "__main__":
    main(sys.argv[1:])
