"""``check``, ``list`` and ``describe``: what is registered, checked and described."""

from __future__ import annotations

import argparse
import json
import sys

from taskflow.cli.common import UsageError


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
    failed = sum(not r.ok for r in results)
    print(f"{len(results) - failed}/{len(results)} world x robot pairings conform")
    return 1 if failed else 0


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


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs check, list, describe."""
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
