"""``batch`` and ``compare``: campaigns of seeded runs and the comparison of two."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from taskflow.cli.common import UsageError, load, max_time_flag, positive_flag, seed_flag, signal_exit_code
from taskflow.errors import MissionError


def _check_batch_options(args: argparse.Namespace) -> None:
    """What ``batch`` can refuse before importing the campaign machinery and the backends: the numbers, the
    syntax of ``--sweep`` and ``--set``, the mission (with file:line:col, before any worker starts), and each
    swept value on it."""
    from taskflow.campaigns.campaign import CampaignError, parse_sweep

    positive_flag("--workers", args.workers)
    if args.resume is not None or args.mission is None or args.trials is None:
        return  # cmd_batch says what is missing, or --resume checks the campaign's own
    positive_flag("--trials", args.trials)
    seed_flag("--seed", args.seed, args.trials)
    max_time_flag(args.max_time)
    try:
        sweep = parse_sweep(args.sweep, args.set)
    except CampaignError as exc:
        raise UsageError(str(exc)) from None
    load(args.mission, args.set)
    for key, values in sweep:  # each value once (not the grid): a bad one is named as the --sweep it is
        for v in values:
            item = f"{key}={v}"
            try:
                load(args.mission, [*args.set, item])
            except MissionError as exc:
                raise MissionError([replace(p, message=p.message.replace(f"--set {item}", f"--sweep {item}"))
                                    for p in exc.problems]) from None


def cmd_batch(args: argparse.Namespace) -> int:
    _check_batch_options(args)
    from taskflow.campaigns.backends import BackendError
    from taskflow.campaigns.batch import BatchProgress, BatchStopped, format_table, resume_batch, run_batch
    from taskflow.campaigns.campaign import CampaignError

    positive_flag("--workers", args.workers)
    if args.address is not None and args.backend != "ray":
        raise UsageError(f"--address {args.address}: a cluster address needs --backend ray")
    if args.address is not None and args.workers is not None:
        raise UsageError("--workers with --address: the cluster's CPUs set how many trials run at once; drop --workers")
    try:
        if args.resume is not None:
            given = [flag for flag, v in (("MISSION", args.mission), ("--trials", args.trials), ("--seed", args.seed),
                                          ("--set", args.set), ("--sweep", args.sweep), ("--out", args.out),
                                          ("--max-time", args.max_time), ("--keep-runs", args.keep_runs))
                     if v is not None and v is not False and v != []]
            if given:
                raise UsageError(f"--resume {args.resume} runs the campaign as its campaign.json says: drop "
                                 + ", ".join(given))
            result = resume_batch(args.resume, workers=args.workers, backend=args.backend, address=args.address,
                                  progress=BatchProgress())
        else:
            if args.mission is None:
                raise UsageError("name a mission file, or --resume DIR to finish a campaign")
            if args.trials is None:
                raise UsageError("--trials N is required (trials per condition)")
            positive_flag("--trials", args.trials)
            max_time = max_time_flag(args.max_time)  # the mission loaded in _check_batch_options: it is valid
            result = run_batch(args.mission, trials=args.trials, workers=args.workers,
                               seed=0 if args.seed is None else args.seed, overrides=args.set, out=args.out,
                               max_time=max_time, keep_runs=args.keep_runs, sweep=args.sweep,
                               backend=args.backend, address=args.address, progress=BatchProgress())
    except BatchStopped as exc:  # a Ctrl-C before the campaign starts is main's plain "interrupted"
        import signal

        signum = exc.signum
        print(f"{'terminated' if signum == signal.SIGTERM else 'interrupted'}: finished trials recorded in {exc}; "
              f"finish with taskflow batch --resume {Path(str(exc)).parent}", file=sys.stderr)
        return signal_exit_code(signum)
    except (CampaignError, BackendError) as exc:
        raise UsageError(str(exc)) from None
    print(format_table(result))
    print(f"batch record: {result['batch_file']}")
    if args.plot:
        from taskflow.campaigns.campaign_plots import plot_campaign

        for f in plot_campaign(Path(result["batch_file"]).parent):
            print(f"figure: {f}")
    return 0 if result["aggregate"]["success_rate"] == 1.0 and not result["interrupted"] else 1


def cmd_compare(args: argparse.Namespace) -> int:
    from taskflow.campaigns.campaign import CampaignError
    from taskflow.campaigns.compare import compare, format_comparison, load_batch

    try:
        a, b = load_batch(args.a), load_batch(args.b)
        results = compare(a, b, args.metric or None)
        if args.plot is not None:
            from taskflow.campaigns.campaign_plots import plot_success_comparison

            figure = plot_success_comparison([(a["mission"], a), (b["mission"], b)], args.plot)
    except CampaignError as exc:
        raise UsageError(str(exc)) from None
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        print(format_comparison((args.a, args.b), results))
    if args.plot is not None:
        print(f"figure: {figure}")
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs batch, compare."""
    b = sub.add_parser("batch", help="N seeded runs per condition on a process pool or a Ray cluster; writes batch.json")
    b.add_argument("mission", nargs="?", help="mission file (omit with --resume)")
    b.add_argument("--trials", type=int, default=None, help="trials per condition")
    b.add_argument("--workers", type=int, default=None, help="local worker processes (or local Ray CPUs)")
    b.add_argument("--seed", type=int, default=None, help="first seed (default 0); trial i uses seed+i")
    b.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    b.add_argument("--sweep", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="run every condition of the grid of the swept values (repeatable)")
    b.add_argument("--out", default=None, help="batch directory (default runs/batch-NAME-TIME)")
    b.add_argument("--max-time", default=None, help="as for run")
    b.add_argument("--keep-runs", action="store_true", help="also write every trial's run directory")
    b.add_argument("--backend", choices=["pool", "ray"], default="pool",
                   help="pool: local processes (default); ray: a Ray cluster (pip install 'taskflow[cluster]')")
    b.add_argument("--address", default=None, help="with --backend ray: the cluster's head HOST:PORT "
                   "(default: start a local cluster)")
    b.add_argument("--resume", default=None, metavar="DIR", help="run the missing trials of the campaign in DIR")
    b.add_argument("--plot", action="store_true", help="write the campaign's figures into its directory")
    b.set_defaults(fn=cmd_batch)

    cm = sub.add_parser("compare", help="do two batches differ? success (Fisher, two-proportion z), "
                        "metrics (Mann-Whitney)")
    cm.add_argument("a", help="batch directory (or its batch.json)")
    cm.add_argument("b", help="batch directory (or its batch.json)")
    cm.add_argument("--metric", action="append", default=[], help="compare only this metric (repeatable)")
    cm.add_argument("--json", action="store_true", help="print the comparison as JSON")
    cm.add_argument("--plot", default=None, metavar="FILE.png",
                    help="both campaigns' success against the key they swept, on one figure")
    cm.set_defaults(fn=cmd_compare)
