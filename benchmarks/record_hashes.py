"""Fingerprints of every shipped mission's records, to show that a refactor changed nothing a run writes.

Each shipped mission runs to its end with seed 0 in its default perception mode and in the other modes
of its world (as `benchmarks/determinism.py`); for each run one JSON line gives the outcome and the
sha256 of `trace.csv`, `transitions.jsonl` and `summary.json` (the summary without `file` and
`versions.taskflow_commit`, which name the checkout).  With `--compare OLD.jsonl` (this script's output
on another checkout) the last line counts the runs whose three fingerprints are identical.  `--skip-summary-key
KEY` leaves a top-level summary key out of the summary's fingerprint (a key the other checkout does not
write, e.g. `outputs` against a checkout from before mission data); each row then also lists that key's
value, so what was left out is shown.

Run: ``python benchmarks/record_hashes.py [--workers 2] [--only NAME ...] [--compare OLD.jsonl]
[--skip-summary-key KEY ...] > NEW.jsonl``
(the missions and code are those of the checkout installed in the running interpreter: run the same
file with another checkout's environment to fingerprint that one).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import taskflow_missions
from determinism import MODES

MISSIONS = Path(taskflow_missions.__file__).resolve().parent  # the installed checkout's missions


def _fingerprints(job: tuple[str, list[str], str, list[str]]) -> dict[str, object]:
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    path, overrides, out, skip = job
    result = run_mission(load_mission(path, overrides), seed=0, out_dir=out)
    summary = json.loads((Path(out) / "summary.json").read_text())
    summary.pop("file", None)
    summary.get("versions", {}).pop("taskflow_commit", None)
    skipped = {key: summary.pop(key) for key in skip if key in summary}
    digest = {name: hashlib.sha256((Path(out) / name).read_bytes()).hexdigest()
              for name in ("trace.csv", "transitions.jsonl")}
    digest["summary.json"] = hashlib.sha256(json.dumps(summary, sort_keys=True).encode()).hexdigest()
    row: dict[str, object] = {"run": f"{Path(path).stem}{'@' + overrides[0].split('=')[1] if overrides else ''}",
                              "outcome": result.outcome, "sha256": digest}
    if skipped:
        row["skipped_summary_keys"] = skipped
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", nargs="*", default=None, help="mission file stems")
    ap.add_argument("--compare", type=Path, default=None, help="this script's output on another checkout")
    ap.add_argument("--skip-summary-key", nargs="*", default=[], metavar="KEY",
                    help="top-level summary keys left out of the summary's fingerprint (listed in each row)")
    args = ap.parse_args()
    from taskflow.mission.loader import load_mission

    tmp = Path(tempfile.mkdtemp(prefix="record-hashes-"))
    jobs = []
    for f in sorted(MISSIONS.glob("*.yaml")):
        if args.only and f.stem not in args.only:
            continue
        for i, overrides in enumerate([[], *MODES.get(load_mission(f).world_cls.name, [])]):
            jobs.append((str(f), overrides, str(tmp / f"{f.stem}-{i}"), list(args.skip_summary_key)))
    rows = []
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        for row in pool.map(_fingerprints, jobs):
            rows.append(row)
            print(json.dumps(row), flush=True)
    tally: dict[str, object] = {"runs": len(rows)}
    if args.compare is not None:
        old = {r["run"]: r for r in map(json.loads, args.compare.read_text().splitlines()) if "run" in r}
        same = [r["run"] for r in rows if r["run"] in old and old[r["run"]]["sha256"] == r["sha256"]]
        tally.update(identical=len(same), different=sorted(r["run"] for r in rows if r["run"] in old
                                                           and r["run"] not in same),
                     not_in_old=sorted(r["run"] for r in rows if r["run"] not in old))
    print(json.dumps(tally))


if __name__ == "__main__":
    main()
