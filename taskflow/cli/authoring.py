"""``validate``, ``graph`` and ``schema``: what a mission's author checks and looks at."""

from __future__ import annotations

import argparse
import json

from taskflow.cli.common import load, print_problems
from taskflow.errors import MissionError


def cmd_validate(args: argparse.Namespace) -> int:
    bad = 0
    for f in args.files:
        try:
            m = load(f, args.set)
        except MissionError as exc:
            print_problems(exc)
            bad += 1
            continue
        print(f"{f}: ok ({m.name}: {len(m.states)} states, {len(m.transitions)} transitions)")
    return 1 if bad else 0


def cmd_graph(args: argparse.Namespace) -> int:
    from taskflow.catalogue.graph import to_dot, to_mermaid

    m = load(args.file)
    print(to_mermaid(m) if args.format == "mermaid" else to_dot(m))
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from taskflow.catalogue.completions import completed_json_schema

    print(json.dumps(completed_json_schema(), indent=2))
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs validate, graph, schema."""
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
