"""``verify``: prove what a mission's machine does before it runs (:mod:`taskflow.verify`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from taskflow.cli.common import UsageError, load, max_time_flag, positive_flag

if TYPE_CHECKING:  # the verb imports the machinery when it runs (a bad flag answers before it loads)
    from taskflow.verify.checks import Verification



def _limits(args: argparse.Namespace) -> tuple[float | None, int]:
    """``--max-time`` and ``--max-states`` checked before anything loads (the model's budget by default)."""
    from taskflow.verify.model import DEFAULT_BUDGET

    max_time = max_time_flag(args.max_time)
    return max_time, positive_flag("--max-states", args.max_states) or DEFAULT_BUDGET


def _verification(args: argparse.Namespace, file: str) -> Verification:
    from taskflow.verify import verify_mission
    from taskflow.verify.model import StateBudgetExceeded

    max_time, budget = _limits(args)
    mission = load(file, args.set)
    try:
        return verify_mission(mission, max_time, operator=args.operator, budget=budget)
    except StateBudgetExceeded as exc:
        raise UsageError(f"{exc} — valid: a larger --max-states, or fewer clocks (a coarser `after`)") from None


def cmd_verify(args: argparse.Namespace) -> int:
    if args.export is not None:
        return _export(args)
    if args.campaign is not None:
        return _campaign(args)
    if args.replay is not None and len(args.files) != 1:
        raise UsageError("--replay DIR: give one mission file")
    bad = 0
    reports = []
    for f in args.files:
        v = _verification(args, f)
        reports.append(v.as_dict())
        if not args.json:
            print(v.render())
        bad += not v.ok
        if args.replay is not None:
            _replay(v, args)
    if args.json:
        print(json.dumps(reports if len(reports) > 1 else reports[0], indent=1))
    return 1 if bad else 0


def _export(args: argparse.Namespace) -> int:
    from taskflow.verify.export import jani_text, prism_text
    from taskflow.verify.model import StateBudgetExceeded, build_model

    if len(args.files) != 1:
        raise UsageError("--export: give one mission file")
    max_time, budget = _limits(args)
    mission = load(args.files[0], args.set)
    try:
        model = build_model(mission, max_time, operator=args.operator, budget=budget)
    except StateBudgetExceeded as exc:
        raise UsageError(f"{exc} — valid: a larger --max-states") from None
    text = (prism_text if args.export == "prism" else jani_text)(model, timed_only=args.sensor_loss)
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    return 0


def _replay(v: Verification, args: argparse.Namespace) -> None:
    name = args.check
    failing = [c for c in v.checks if c.counterexample is not None and (name is None or c.name == name)]
    if not failing:
        what = f"--check {name}: no such check has a counterexample" if name else "no check has a counterexample"
        raise UsageError(f"--replay: {what} to replay — checks with one: "
                         f"{', '.join(c.name for c in v.checks if c.counterexample) or '(none)'}")
    check = failing[0]
    assert check.counterexample is not None
    out = Path(args.replay)
    replay = check.counterexample.replay(out)
    print(f"replay of {check.name}'s counterexample: {replay.describe()}")
    print(f"  record: {out}  (taskflow view {out})")


def _campaign(args: argparse.Namespace) -> int:
    from taskflow.verify.campaign import predict
    if len(args.files) != 1:
        raise UsageError("--campaign BATCH_DIR: give one mission file")
    mission = load(args.files[0], args.set)
    prediction = predict(mission, Path(args.campaign))
    print(json.dumps(prediction.as_dict(), indent=1) if args.json else prediction.render())
    return 0 if prediction.agrees else 1  # a disagreement: the behaviour depends on more than the configuration


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verb verify."""
    v = sub.add_parser("verify", help="prove what a mission's machine does before it runs: no trap, a timed way out "
                                      "under sensor loss, bounded duration, outcomes reachable, region conflicts "
                                      "(Storm); exit 1 if a check fails")
    v.add_argument("files", nargs="+", metavar="MISSION")
    v.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    v.add_argument("--max-time", default=None, metavar="T",
                   help="the run ends with `timeout` after T (seconds or '2 min'); default: no limit (the file's "
                        "max_time is not assumed: the checks ask whether the machine itself ends)")
    v.add_argument("--operator", action="store_true",
                   help="with an operator who may pre-empt the run to any state or abort it at any moment (taskflow ctl)")
    v.add_argument("--export", choices=["prism", "jani"], default=None,
                   help="print the model as PRISM or JANI text (for Storm's or PRISM's own tools) instead of checking")
    v.add_argument("--sensor-loss", action="store_true",
                   help="with --export: the model under sensor loss (only timers and action ends)")
    v.add_argument("--json", action="store_true", help="print the verdicts as JSON")
    v.add_argument("--replay", default=None, metavar="DIR",
                   help="drive the engine (scripted backend) along the first counterexample (or --check's) and record "
                        "the run in DIR, for `taskflow view DIR`")
    v.add_argument("--check", default=None, metavar="NAME",
                   help="the check whose counterexample --replay drives: no_trap, timed_exit, duration, outcomes, "
                        "region_conflicts or property:NAME (default: the first that has one)")
    v.add_argument("--campaign", default=None, metavar="BATCH_DIR",
                   help="predict P(outcome) and the expected time from a campaign's records and set them beside "
                        "its measured rates")
    v.add_argument("--max-states", type=int, default=None, metavar="N",
                   help="most configurations the model may have (default: taskflow.verify.model.DEFAULT_BUDGET, 2,000,000)")
    v.set_defaults(fn=cmd_verify)
