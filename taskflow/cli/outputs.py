"""``teach``, ``plot`` and ``export``: files made from a mission or a record (keyframe images, figures,
telemetry)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

from taskflow.cli.common import UsageError, load, seed_flag


def cmd_teach(args: argparse.Namespace) -> int:
    seed_flag("--seed", args.seed)
    mission = load(args.mission, args.set)
    if not mission.world_cls.teaches:
        print(f"{args.mission}: world {mission.world_cls.name!r} has nothing to teach "
              "(teach-by-showing needs a world with keyframes, e.g. quad_room)", file=sys.stderr)
        return 1
    seed = mission.spec.seed if args.seed is None else args.seed
    out = Path(args.out) if args.out is not None else Path(mission.file).resolve().parent / "keyframes" / mission.name
    for path in mission.world_cls.teach(mission.build_robot(), mission.world_params(seed), out, seed, mission.name):
        print(path)
    return 0


def _print_files(write: Callable[[], Iterable[Path]], refused: type[Exception]) -> None:
    """Print each file ``write`` makes as it makes it; ``refused`` (a bad record) is a usage error."""
    try:
        for f in write():
            print(f)
    except refused as exc:
        raise UsageError(str(exc)) from None


def cmd_plot(args: argparse.Namespace) -> int:
    from taskflow.readers.recorded import RunDirError, load_run

    run_dir = Path(args.run_dir)
    if (run_dir / "campaign.json").is_file() and (run_dir / "batch.json").is_file():
        from taskflow.campaigns.campaign import CampaignError
        from taskflow.campaigns.campaign_plots import plot_campaign  # a batch directory: the campaign's figures

        _print_files(lambda: plot_campaign(run_dir), CampaignError)
        return 0
    try:
        run = load_run(args.run_dir)  # a folder that is not a run is refused before matplotlib loads
    except RunDirError as exc:
        raise UsageError(str(exc)) from None
    from taskflow.readers.plots import plot_recorded

    _print_files(lambda: plot_recorded(run), RunDirError)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from taskflow.readers.recorded import RunDirError
    from taskflow.readers.telemetry import export_run

    try:
        print(export_run(args.run_dir, args.format, args.output))
    except RunDirError as exc:
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"cannot write {args.output or 'the export'}: {exc.strerror or exc}") from None
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs teach, plot, export."""
    t = sub.add_parser("teach", help="render and store a visual path's keyframe images (teach by showing)")
    t.add_argument("mission")
    t.add_argument("--out", default=None, help="directory for the images and keyframes.json")
    t.add_argument("--seed", type=int, default=None)
    t.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    t.set_defaults(fn=cmd_teach)

    p = sub.add_parser("plot", help="write the figures of a run directory (or of a batch directory) as PNG")
    p.add_argument("run_dir")
    p.set_defaults(fn=cmd_plot)

    e = sub.add_parser("export", help="convert a run directory's record to telemetry viewers open (MCAP: Foxglove, ROS 2)")
    e.add_argument("run_dir")
    e.add_argument("--format", choices=["mcap"], default="mcap")
    e.add_argument("-o", "--output", default=None, help="output file (default RUN_DIR/telemetry.FORMAT)")
    e.set_defaults(fn=cmd_export)
