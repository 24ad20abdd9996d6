"""Real-time factor of shipped missions, one run each with seed 0, read from each run's ``timing.json``.

Run: ``python benchmarks/mission_rtf.py OUT MISSION[@rendered|@geometric] ...`` — e.g.
``python benchmarks/mission_rtf.py /tmp/rtf/after car_waypoints viki_hyco@rendered``.  The missions and
code are those of the checkout installed in the running interpreter, so running this file with two
checkouts' environments, alternately and one process at a time, compares their speed on one machine
(`BENCHMARKS.md`, "the refactor keeps every figure").  Prints one JSON line per run, then a JSON line
with all of them.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import taskflow_missions

MISSIONS = Path(taskflow_missions.__file__).resolve().parent


def overrides(stem: str, mode: str) -> list[str]:
    if mode == "rendered":
        return ["world.params.perception=rendered"] + (["world.params.image_size=[320, 180]"]
                                                       if stem.startswith("viki") else [])
    if mode == "geometric":
        return ["world.params.perception=geometric"]
    return []


def main(argv: list[str]) -> None:
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    if len(argv) < 2:
        raise SystemExit(__doc__)
    out, rows = Path(argv[0]), []
    for name in argv[1:]:
        stem, _, mode = name.partition("@")
        run = run_mission(load_mission(MISSIONS / f"{stem}.yaml", overrides(stem, mode)), seed=0, out_dir=out / name)
        timing = json.loads((out / name / "timing.json").read_text())
        row = {"mission": name, "outcome": run.outcome, "sim_s": run.summary["sim_time_s"],
               "rtf": timing.get("real_time_factor"), "wall_s": timing.get("wall_time_s")}
        rows.append(row)
        print(json.dumps(row), flush=True)
    print(json.dumps({"runs": rows}))


if __name__ == "__main__":
    main(sys.argv[1:])
