"""From a campaign to a prediction (issue 22): the chain of a campaign's records solved with Storm, beside the
campaign's measured rates (:func:`taskflow.verify.campaign.predict`).

Give a campaign directory that ``taskflow batch MISSION --keep-runs`` wrote; the mission is the campaign's own
(``campaign.json``: its file and ``--set`` overrides) unless ``--mission`` names another.  With ``--run``, the
campaign is run first (``--trials`` seeds of ``--run``'s mission with ``--set``, one worker, run directories
kept) into the directory.  Prints the prediction's tables (``CampaignPrediction.render``), the time the
prediction took (wall clock: reading the records, the chain, Storm, the posterior samples) and the versions;
the last line is JSON: per condition the outcomes (predicted with interval, measured k/n with Wilson
interval), the expected time to each, the number of configurations and every disagreement.

Usage: ``python benchmarks/verify_campaign.py BATCH_DIR [--run MISSION --trials 20 --set KEY=VALUE ...]
[--mission FILE] [--confidence 0.95] [--samples 2000]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.campaign import Campaign
from taskflow.errors import MissionError
from taskflow.execution.provenance import versions
from taskflow.mission.loader import load_mission
from taskflow.verify.campaign import predict


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("batch_dir")
    ap.add_argument("--run", default=None, metavar="MISSION", help="run this campaign first (kept runs, 1 worker)")
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--mission", default=None, help="the mission file (default: the campaign's own, with its --set)")
    ap.add_argument("--confidence", type=float, default=0.95)
    ap.add_argument("--samples", type=int, default=2000)
    args = ap.parse_args()
    out = Path(args.batch_dir)
    run_s = None
    if args.run is not None:
        t0 = time.perf_counter()
        run_batch(args.run, trials=args.trials, workers=1, overrides=args.set, out=out, keep_runs=True)
        run_s = time.perf_counter() - t0
    try:
        spec = Campaign.open(out).spec
        mission = load_mission(args.mission or spec.mission, None if args.mission else spec.overrides or None)
        t0 = time.perf_counter()
        pred = predict(mission, out, args.confidence, args.samples)
        predict_s = time.perf_counter() - t0
    except MissionError as exc:
        print(exc, file=sys.stderr)
        return 1
    print(pred.render())
    import stormpy

    ver = {**versions(), "stormpy": getattr(stormpy, "__version__", None)}
    print(f"\nprediction: {predict_s:.2f} s wall ({args.samples} posterior samples)"
          + (f"; the campaign: {run_s:.1f} s wall" if run_s is not None else ""))
    print("versions: " + ", ".join(f"{k} {v}" for k, v in ver.items()))
    conditions: list[dict[str, Any]] = []
    for c in pred.as_dict()["conditions"]:
        conditions.append({"condition": c["condition"], "runs": c["runs"], "configurations": len(c["configurations"]),
                           "outcomes": c["outcomes"], "times": c["times"], "unseen": c["unseen"],
                           "disagreements": c["disagreements"]})
    print(json.dumps({"batch_dir": str(out), "mission": pred.mission, "overrides": spec.overrides,
                      "confidence": args.confidence, "samples": args.samples, "agrees": pred.agrees,
                      "predict_s": round(predict_s, 3), "campaign_s": None if run_s is None else round(run_s, 1),
                      "conditions": conditions, "versions": ver}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
