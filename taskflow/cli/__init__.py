"""``taskflow`` command line: run, view, ctl, validate, graph, schema, batch, compare, teach, plot, export, check, list,
describe.

Exit codes: 0 success; 1 the mission did not succeed / a file is invalid; 2 bad usage;
130 interrupted (Ctrl-C), 143 terminated (SIGTERM) — ``run`` and ``batch`` alike, once the record is written.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from taskflow.errors import MissionError


def default_mission() -> Path:
    """The shipped default mission (package ``taskflow_missions``, the repository's ``missions/``),
    wherever taskflow is installed: a checkout or a wheel."""
    import taskflow_missions

    return taskflow_missions.DEFAULT


def _print_problems(exc: MissionError) -> None:
    for p in exc.problems:
        print(str(p), file=sys.stderr)


class UsageError(Exception):
    """A command-line value that cannot be used: one line on stderr, exit 1."""


def _max_time(text: str | None) -> float | None:
    """``--max-time 30``, ``"30 s"`` or ``"2 min"``: the same rule as ``max_time`` in a file."""
    if text is None:
        return None
    from taskflow.units import UnitError, parse_max_time

    try:
        return parse_max_time(_number_or_text(text))
    except UnitError as exc:
        raise UsageError(f"--max-time {text!r}: {exc}") from None


def _frames_hz(text: str) -> float:
    """``--frames HZ``: frames per simulated second, 0 for none."""
    import math

    try:
        hz = float(text)
    except ValueError:
        hz = math.nan
    if not (math.isfinite(hz) and hz >= 0):
        raise UsageError(f"--frames {text!r}: frames per simulated second — valid: a number >= 0 (0: record none)")
    return hz


def _number_or_text(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text


def _positive(flag: str, value: int | None) -> int | None:
    if value is not None and value < 1:
        raise UsageError(f"{flag} {value}: must be at least 1")
    return value


def _seed(flag: str, value: int | None, count: int = 1) -> int | None:
    """``--seed`` as a mission's ``seed:`` takes it (0 to 2**63 - 1), with room for ``count`` seeds from it."""
    from taskflow.mission.schema import SEED_MAX

    if value is not None and not 0 <= value <= SEED_MAX - (count - 1):
        top = f"{SEED_MAX - (count - 1)} (trial i of {count} runs seed + i)" if count > 1 else f"{SEED_MAX}"
        raise UsageError(f"{flag} {value}: a seed is a whole number from 0 to {top}")
    return value


def _check_batch_options(args: argparse.Namespace) -> None:
    """What ``batch`` can refuse before importing the statistics and the backends (seconds of imports):
    the numbers, the syntax of ``--sweep`` and ``--set``, the mission, and each swept value on it."""
    from taskflow.campaigns.campaign import CampaignError, parse_sweep

    _positive("--workers", args.workers)
    if args.resume is not None or args.mission is None or args.trials is None:
        return  # cmd_batch says what is missing, or --resume checks the campaign's own
    _positive("--trials", args.trials)
    _seed("--seed", args.seed, args.trials)
    _max_time(args.max_time)
    try:
        sweep = parse_sweep(args.sweep, args.set)
    except CampaignError as exc:
        raise UsageError(str(exc)) from None
    _load(args.mission, args.set)
    for key, values in sweep:  # each value once (not the grid): a bad one is named as the --sweep it is
        for v in values:
            item = f"{key}={v}"
            try:
                _load(args.mission, [*args.set, item])
            except MissionError as exc:
                raise MissionError([replace(p, message=p.message.replace(f"--set {item}", f"--sweep {item}"))
                                    for p in exc.problems]) from None


def _load(path: str, overrides: list[str] | None = None):  # type: ignore[no-untyped-def]
    from taskflow.mission.loader import load_mission

    return load_mission(path, overrides)


def _check_display(gui: bool) -> None:
    """``--gui`` opens an X11 window on Linux: without a display PyBullet dies in C, after the run started."""
    import os

    if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise UsageError("--gui: no display (DISPLAY is not set) — run without --gui (headless), or under a "
                         "display (xvfb-run taskflow run --gui …)")


def signal_exit_code(signum: int) -> int:
    """The exit status of a command a signal stopped after it wrote its record: the shell's ``128 + signum``
    (130 for Ctrl-C, 143 for SIGTERM), for ``run`` and ``batch`` alike."""
    return 128 + int(signum)


def cmd_run(args: argparse.Namespace) -> int:
    import signal

    _seed("--seed", args.seed)  # the options first: no simulator import for a bad number
    max_time = _max_time(args.max_time)
    frames_hz = _frames_hz(args.frames)
    _check_display(args.gui)
    from taskflow.execution.runtime import INTERRUPTED, TERMINATED, Progress, print_progress, run_mission

    path = args.mission or str(default_mission())
    mission = _load(path, args.set)
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


def _operator_options(args: argparse.Namespace, mission):  # type: ignore[no-untyped-def]
    """The control endpoint (bound now, so a port in use is a usage error) and the operator script of ``run``."""
    from taskflow.operate.control import ControlError, load_operator_script
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

    from taskflow.operate.control import ControlError
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
        reply = client.send(action, who=args.who, **extra)
    except ControlError as exc:
        raise UsageError(str(exc)) from None
    print(f"{reply['queued']} queued by {reply['who']}: applied at the next tick boundary")
    return 0
def _print_run(result) -> None:  # type: ignore[no-untyped-def]
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
    from taskflow.operate.control import ControlError
    from taskflow.operate.view import ViewError
    from taskflow.operate.view_http import serve_replay, wait_forever

    def announce(url: str, run_dir: Path | None, token: str | None) -> None:
        page = f"{url}/?token={token}" if token else f"{url}/"
        print(f"view: {page}  (replay of {args.run_dir}; Ctrl-C stops)", file=sys.stderr)

    try:
        server = serve_replay(args.run_dir, f"{args.host}:{args.port}", announce)
    except (ViewError, ControlError) as exc:
        raise UsageError(str(exc)) from None
    wait_forever(server)
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    bad = 0
    for f in args.files:
        try:
            m = _load(f, args.set)
        except MissionError as exc:
            _print_problems(exc)
            bad += 1
            continue
        print(f"{f}: ok ({m.name}: {len(m.states)} states, {len(m.transitions)} transitions)")
    return 1 if bad else 0


def cmd_graph(args: argparse.Namespace) -> int:
    from taskflow.catalogue.graph import to_dot, to_mermaid

    m = _load(args.file)
    print(to_mermaid(m) if args.format == "mermaid" else to_dot(m))
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from taskflow.catalogue.completions import completed_json_schema

    print(json.dumps(completed_json_schema(), indent=2))
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    _check_batch_options(args)
    from taskflow.campaigns.backends import BackendError
    from taskflow.campaigns.batch import BatchProgress, BatchStopped, format_table, resume_batch, run_batch
    from taskflow.campaigns.campaign import CampaignError

    _positive("--workers", args.workers)
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
            _positive("--trials", args.trials)
            max_time = _max_time(args.max_time)
            _load(args.mission, args.set)  # fail fast, with file:line:col, before any worker starts
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


def cmd_teach(args: argparse.Namespace) -> int:
    _seed("--seed", args.seed)
    mission = _load(args.mission, args.set)
    if not mission.world_cls.teaches:
        print(f"{args.mission}: world {mission.world_cls.name!r} has nothing to teach "
              "(teach-by-showing needs a world with keyframes, e.g. quad_room)", file=sys.stderr)
        return 1
    seed = mission.spec.seed if args.seed is None else args.seed
    out = Path(args.out) if args.out is not None else Path(mission.file).resolve().parent / "keyframes" / mission.name
    for path in mission.world_cls.teach(mission.build_robot(), mission.world_params(seed), out, seed, mission.name):
        print(path)
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from taskflow.readers.recorded import RunDirError, load_run

    run_dir = Path(args.run_dir)
    if (run_dir / "campaign.json").is_file() and (run_dir / "batch.json").is_file():
        from taskflow.campaigns.campaign import CampaignError
        from taskflow.campaigns.campaign_plots import plot_campaign  # a batch directory: the campaign's figures

        try:
            for f in plot_campaign(run_dir):
                print(f)
        except CampaignError as exc:
            raise UsageError(str(exc)) from None
        return 0
    try:
        run = load_run(args.run_dir)  # a folder that is not a run is refused before matplotlib loads
    except RunDirError as exc:
        raise UsageError(str(exc)) from None
    from taskflow.readers.plots import plot_recorded

    try:
        for f in plot_recorded(run):
            print(f)
    except RunDirError as exc:
        raise UsageError(str(exc)) from None
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


def cmd_check(args: argparse.Namespace) -> int:
    import yaml

    from taskflow.catalogue.conformance import MAX_STEPS, check_all, no_pair_reason, param_problem
    from taskflow.mission.yamlsrc import MissionLoader
    from taskflow.registry import UnknownName

    if not 1 <= args.steps <= MAX_STEPS:
        raise UsageError(f"--steps {args.steps}: ticks per seeded rollout — valid: 1 to {MAX_STEPS}")
    params: dict[str, dict[str, object]] = {}
    given: dict[tuple[str, str], str] = {}
    for item in args.param:
        key, sep, value = item.partition("=")
        world, dot, name = key.partition(".")
        if not (sep and dot and world and name):
            raise UsageError(f"--param {item!r}: expected WORLD.KEY=VALUE, e.g. quad_room.perception=geometric")
        try:
            params.setdefault(world, {})[name] = yaml.load(value, Loader=MissionLoader)
        except yaml.YAMLError:
            raise UsageError(f"--param {item}: the value is not valid YAML") from None
        given[(world, name)] = item
    try:
        for world, values in params.items():
            bad = param_problem(world, values)
            if bad is not None:
                item = given.get((world, bad[0]), next(i for (w, _), i in given.items() if w == world))
                raise UsageError(f"--param {item}: {bad[1]}" + (f" — {bad[2]}" if bad[2] else ""))
        results = check_all(params, args.world or None, args.robot or None, steps=args.steps)
        if not results:
            flags = " ".join([f"--world {w}" for w in args.world] + [f"--robot {r}" for r in args.robot])
            raise UsageError(f"{flags or 'the registries'}: nothing to check: {no_pair_reason(args.world, args.robot)}")
    except UnknownName as exc:
        flag = "--world" if exc.kind == "world" else "--robot"
        if exc.name in params:
            raise UsageError(f"--param {next(i for (w, _), i in given.items() if w == exc.name)}: {exc}") from None
        raise UsageError(f"{flag} {exc.name}: {exc}") from None
    for r in results:
        print(r)
    bad = sum(not r.ok for r in results)
    print(f"{len(results) - bad}/{len(results)} world x robot pairings conform")
    return 1 if bad else 0


def cmd_list(args: argparse.Namespace) -> int:
    from taskflow.catalogue.catalogue import PLURAL, build
    from taskflow.catalogue.catalogue_render import list_text

    cat = build()
    kind = PLURAL.get(args.kind, args.kind)
    if args.json:
        entries = cat.of_kind(kind) if kind else cat.entries
        print(json.dumps([{"kind": e.kind, "name": e.name, "summary": e.summary} for e in entries], indent=2))
    else:
        sys.stdout.write(list_text(cat, kind))
    return 0


def cmd_describe(args: argparse.Namespace) -> int:
    from taskflow.catalogue.catalogue import UnknownEntry, build, entry_to_json
    from taskflow.catalogue.catalogue_render import describe_markdown, describe_text, reference_markdown

    if args.all == (args.name is not None):
        print("taskflow describe: give a NAME or --all (taskflow list shows the names)", file=sys.stderr)
        return 2
    cat = build()
    try:
        entries = [cat.find(args.name, args.kind)] if args.name else [e for e in cat.entries
                                                                       if e.kind == args.kind or not args.kind]
    except UnknownEntry as exc:
        print(f"taskflow describe: {exc}", file=sys.stderr)
        return 2
    if args.json:
        data = [entry_to_json(e) for e in entries]
        print(json.dumps(data if args.all else data[0], indent=2, ensure_ascii=False))
    elif args.markdown:
        whole = args.all and not args.kind
        sys.stdout.write(reference_markdown(cat) if whole else "\n".join(map(describe_markdown, entries)))
    else:
        sys.stdout.write("\n".join(map(describe_text, entries)))
    return 0
def _user() -> str:
    import getpass

    try:
        return getpass.getuser()
    except Exception:
        return "operator"


def build_parser() -> argparse.ArgumentParser:
    from taskflow.execution.frames import DEFAULT_HZ as DEFAULT_FRAMES_HZ

    ap = argparse.ArgumentParser(prog="taskflow", description="Run robot missions written as YAML state machines.")
    sub = ap.add_subparsers(dest="cmd", required=True)

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

    w = sub.add_parser("view", help="replay a finished run in the browser (a local web page)")
    w.add_argument("run_dir")
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
    o.add_argument("--who", default=_user(), help="who asks (recorded in transitions.jsonl; default: your user name)")
    o.set_defaults(fn=cmd_ctl)

    v = sub.add_parser("validate", help="check mission files; exit 1 if any is invalid")
    v.add_argument("files", nargs="+")
    v.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    v.set_defaults(fn=cmd_validate)

    g = sub.add_parser("graph", help="print the machine as a diagram")
    g.add_argument("file")
    g.add_argument("--format", choices=["mermaid", "dot"], default="mermaid")
    g.set_defaults(fn=cmd_graph)

    s = sub.add_parser("schema", help="print the JSON Schema of mission files (registered names and their "
                                      "parameters included, for editors)")
    s.set_defaults(fn=cmd_schema)

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

    c = sub.add_parser("check", help="conformance check of every registered world x robot it hosts; exit 1 on a failure")
    c.add_argument("--world", action="append", default=[], help="only this world (repeatable)")
    c.add_argument("--robot", action="append", default=[], help="only this robot (repeatable)")
    c.add_argument("--param", action="append", default=[], metavar="WORLD.KEY=VALUE",
                   help="world parameter override, e.g. quad_room.perception=geometric")
    c.add_argument("--steps", type=int, default=5, help="ticks per seeded rollout")
    c.set_defaults(fn=cmd_check)

    kinds = ["task", "robot", "world", "sensor"]
    ls = sub.add_parser("list", help="the registered tasks, robots, worlds and sensor streams, one line each")
    ls.add_argument("kind", nargs="?", choices=["tasks", "robots", "worlds", "sensors"], help="only this kind")
    ls.add_argument("--json", action="store_true", help="as JSON: [{kind, name, summary}]")
    ls.set_defaults(fn=cmd_list)

    d = sub.add_parser("describe", help="parameters (types, defaults, units), profile slots, metrics, events, "
                                        "actions, observations of a task, robot, world or sensor stream")
    d.add_argument("name", nargs="?", help="a registered name (taskflow list shows them)")
    d.add_argument("--kind", choices=kinds, help="which kind NAME is, when several have it")
    d.add_argument("--all", action="store_true", help="every registered name (of --kind)")
    fmt = d.add_mutually_exclusive_group()
    fmt.add_argument("--json", action="store_true", help="as JSON (taskflow.catalogue.catalogue.Entry)")
    fmt.add_argument("--markdown", action="store_true", help="as markdown; with --all the page docs/reference.md")
    d.set_defaults(fn=cmd_describe)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.fn(args))
    except MissionError as exc:
        _print_problems(exc)
        return 1
    except UsageError as exc:
        print(f"taskflow {args.cmd}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


