"""``run``, ``view`` and ``ctl``: a mission run (with its operator endpoint and script), a finished run replayed
in the browser, a running mission operated."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from taskflow.cli.common import (
    UsageError,
    check_display,
    default_mission,
    frames_hz_flag,
    load,
    max_time_flag,
    seed_flag,
    signal_exit_code,
    user_name,
)

if TYPE_CHECKING:  # imported when the verb runs
    from taskflow.execution.control import OperatorAction
    from taskflow.execution.summary import RunResult
    from taskflow.mission.model import CompiledMission
    from taskflow.operate.control_http import ControlServer


def cmd_run(args: argparse.Namespace) -> int:
    import signal

    seed_flag("--seed", args.seed)  # the options first: no simulator import for a bad number
    max_time = max_time_flag(args.max_time)
    frames_hz = frames_hz_flag(args.frames)
    check_display(args.gui)
    from taskflow.execution.runtime import INTERRUPTED, TERMINATED, Progress, print_progress, run_mission

    path = args.mission or str(default_mission())
    mission = load(path, args.set)
    progress = Progress(print_progress) if sys.stderr.isatty() and not args.quiet else None
    control, operator = _operator_options(args, mission)
    print(f"running {mission.name} ({path}) seed={args.seed if args.seed is not None else mission.spec.seed}",
          file=sys.stderr)
    result = run_mission(mission, seed=args.seed, out_dir=args.out, gui=args.gui, max_time=max_time,
                         progress=progress, control=control, operator=operator, frames_hz=frames_hz)
    if progress is not None:
        sys.stderr.write("\n")
    s = result.summary
    _print_run(result)
    if args.view and result.run_dir is not None:
        print(f"replay it: taskflow view {result.run_dir}")
    if args.plot and result.run_dir is not None:
        from taskflow.readers.plots import plot_run

        for f in plot_run(result.run_dir):
            print(f"figure: {f}")
    if args.record and result.run_dir is not None:
        from taskflow.readers.telemetry import export_run

        print(f"telemetry: {export_run(result.run_dir, args.record)}")
    if s["outcome"] == "aborted" and s.get("reason") in (INTERRUPTED, TERMINATED):
        return signal_exit_code(signal.SIGINT if s["reason"] == INTERRUPTED else signal.SIGTERM)
    return 0 if result.succeeded else 1


def _operator_options(args: argparse.Namespace, mission: CompiledMission,
                      ) -> tuple[ControlServer | None, list[OperatorAction] | None]:
    """The control endpoint (bound now, so a port in use is a usage error) and the operator script of ``run``."""
    from taskflow.execution.control import ControlError, load_operator_script
    from taskflow.operate.control_http import ControlServer

    operator = (load_operator_script(args.operator_script, mission, live=not args.no_control)
                if args.operator_script else None)
    if args.no_control:
        if args.view:
            raise UsageError("--view needs the control endpoint: drop --no-control")
        return None, operator

    def announce(url: str, run_dir: Path | None, token: str | None) -> None:
        # the token is printed once: with the page's address, or beside the endpoint's without --view
        print(f"control: {url}  (taskflow ctl {run_dir} state|pause|hold|resume|preempt|inject"
              + (")" if args.view else f"; token {token})"), file=sys.stderr)
        if args.view:
            print(f"view: {url}/?token={token}  (open it in a browser)", file=sys.stderr)

    try:
        return ControlServer(args.control, announce, view=args.view), operator
    except ControlError as exc:
        raise UsageError(f"--control: {exc}") from None


def cmd_ctl(args: argparse.Namespace) -> int:
    import os

    from taskflow.execution.control import ControlError
    from taskflow.operate.control_http import ControlClient

    if args.token is not None and args.url is None:
        raise UsageError("--token goes with --url: with RUN_DIR the token is read from RUN_DIR/control.json")
    words = list(args.words)
    try:
        if args.url is None:
            if len(words) < 2:
                raise UsageError("give the run directory and an action: taskflow ctl RUN_DIR pause (or --url URL pause)")
            client = ControlClient.for_run(words.pop(0))
        else:
            client = ControlClient(args.url, token=args.token or os.environ.get("TASKFLOW_TOKEN") or None)
        action, rest = words[0] if words else "", words[1:]
        extra: dict[str, str] = {}
        if action == "inject":
            if len(rest) != 1:
                raise UsageError("inject takes one event name: taskflow ctl RUN_DIR inject EVENT")
            extra["event"] = rest.pop()
        elif action == "preempt" and args.to is not None:
            extra["to"] = args.to
        if rest or (args.to is not None and action != "preempt"):
            raise UsageError(f"{action}: unexpected {' '.join(rest) or '--to'}")
        if action in ("state", "mission"):
            print(json.dumps(client.state() if action == "state" else client.mission(), indent=2))
            return 0
        if action not in ("pause", "hold", "resume", "preempt", "inject"):
            raise UsageError(f"unknown action {action!r}; valid: state, mission, pause, hold, resume, preempt, inject")
        reply = client.send(action, who=args.who if args.who is not None else user_name(), **extra)
    except ControlError as exc:
        raise UsageError(str(exc)) from None
    print(f"{reply['queued']} queued by {reply['who']}: applied at the next tick boundary"
          + (f" — {reply['note']}" if reply.get("note") else ""))
    return 0


def _print_run(result: RunResult) -> None:
    """The terminal summary (:mod:`taskflow.readers.report`) from the run's record, which is read back for it."""
    from taskflow.readers.recorded import RunDirError, load_run
    from taskflow.readers.report import format_report

    s = result.summary
    if result.run_dir is None or not (Path(result.run_dir) / "trace.csv").is_file():
        print(f"outcome: {s['outcome']} ({s.get('reason', '')})")
    else:
        try:
            print(format_report(load_run(result.run_dir), result.timing))
        except RunDirError as exc:
            print(f"outcome: {s['outcome']} ({s.get('reason', '')})\n(no metric summary: {exc})")
    print(f"run record: {result.run_dir}")


def cmd_view(args: argparse.Namespace) -> int:
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port {args.port}: a TCP port — valid: 0 to 65535 (0: any free port)")
    from taskflow.execution.control import ControlError
    from taskflow.operate.campaign_view import is_campaign
    from taskflow.operate.replay import serve_replay, wait_forever
    from taskflow.operate.view import ViewError

    what = "campaign" if is_campaign(args.run_dir) else "replay"

    def announce(url: str, run_dir: Path | None, token: str | None) -> None:
        page = f"{url}/?token={token}" if token else f"{url}/"
        print(f"view: {page}  ({what} of {args.run_dir}; Ctrl-C stops)", file=sys.stderr)

    try:
        server = serve_replay(args.run_dir, f"{args.host}:{args.port}", announce)
    except (ViewError, ControlError) as exc:
        raise UsageError(str(exc)) from None
    wait_forever(server)
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs run, view, ctl."""
    from taskflow.execution.frames import DEFAULT_HZ as DEFAULT_FRAMES_HZ

    r = sub.add_parser("run", help="run a mission (default: the shipped default mission), headless unless --gui")
    r.add_argument("mission", nargs="?", help=f"mission file (default: the shipped missions/{default_mission().name})")
    r.add_argument("--seed", type=int, default=None)
    r.add_argument("--out", default=None, help="run directory (default runs/NAME-seedN-TIME)")
    r.add_argument("--gui", action="store_true", help="open a PyBullet window")
    r.add_argument("--max-time", default=None, help="simulated time before 'timeout': seconds, or '30 s', '2 min'")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a mission key")
    r.add_argument("--plot", action="store_true", help="write the figures into the run directory")
    r.add_argument("--quiet", action="store_true", help="no progress line")
    r.add_argument("--control", default="127.0.0.1:0", metavar="HOST:PORT",
                   help="operator endpoint for taskflow ctl (default 127.0.0.1, any free port; written to RUN_DIR/control.json)")
    r.add_argument("--no-control", action="store_true", help="no operator endpoint")
    r.add_argument("--operator-script", default=None, metavar="FILE.yaml",
                   help="operator actions to apply at given sim times: a list of {t, action, args, who}")
    r.add_argument("--record", choices=["mcap"], default=None,
                   help="also write the run's telemetry in this format (RUN_DIR/telemetry.mcap) when it ends")
    r.add_argument("--frames", default=str(DEFAULT_FRAMES_HZ), metavar="HZ",
                   help=f"record the camera images the world observes (rendered modes) at HZ frames per simulated "
                        f"second into RUN_DIR/frames (default {DEFAULT_FRAMES_HZ:g}; 0: none)")
    r.add_argument("--view", action="store_true",
                   help="serve the web view of the live run on the control endpoint (its address is printed)")
    r.set_defaults(fn=cmd_run)

    w = sub.add_parser("view", help="replay a finished run, or show a campaign (a batch folder), in the browser "
                                    "(a local web page)")
    w.add_argument("run_dir", metavar="RUN_DIR|BATCH_DIR")
    w.add_argument("--port", type=int, default=8765, help="port (default 8765; 0: any free port)")
    w.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    w.set_defaults(fn=cmd_view)

    o = sub.add_parser("ctl", help="operate a running mission: state, mission, pause, hold, resume, preempt, inject")
    o.add_argument("words", nargs="+", metavar="[RUN_DIR] ACTION [EVENT]",
                   help="the run directory (unless --url), then the action; inject takes the event name")
    o.add_argument("--url", default=None, help="the endpoint's address instead of RUN_DIR/control.json")
    o.add_argument("--token", default=None, help="with --url: the run's token (default: $TASKFLOW_TOKEN; "
                   "with RUN_DIR it is read from control.json)")
    o.add_argument("--to", default=None, metavar="STATE_PATH", help="preempt: the state to go to (default: abort the run)")
    o.add_argument("--who", default=None, help="who asks (recorded in transitions.jsonl; default: your user name)")
    o.set_defaults(fn=cmd_ctl)
