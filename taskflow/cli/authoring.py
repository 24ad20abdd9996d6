"""``validate``, ``graph``, ``schema`` and ``lsp``: what a mission's author checks and looks at, on the command line
and in the editor."""

from __future__ import annotations

import argparse
import json
import sys

from taskflow.cli.common import UsageError, load, print_problems
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
        if args.verify:
            from taskflow.verify import verify_mission

            v = verify_mission(m)
            failing = [c for c in v.checks if c.verdict == "fails"]
            took = v.build_seconds + sum(c.seconds for c in v.checks)
            if not failing:
                print(f"{f}: verified ({len(v.checks)} checks hold on {v.model.n_states} configurations, {took:.2f} s)")
            for c in failing:
                print(f"{f}: {c.name} {c.verdict} — {c.detail}")
                if c.counterexample is not None:
                    print(c.counterexample.render(indent="    "))
            bad += bool(failing)
    return 1 if bad else 0


def cmd_graph(args: argparse.Namespace) -> int:
    from taskflow.catalogue.graph import Highlight, to_dot, to_mermaid

    m = load(args.file)
    highlight = None
    if args.counterexample is not None:
        from taskflow.verify import verify_mission

        try:
            check = verify_mission(m).check(args.counterexample)
        except KeyError as exc:
            raise UsageError(f"--counterexample {exc.args[0]}") from None
        if check.counterexample is None:
            raise UsageError(f"--counterexample {args.counterexample}: the check {check.verdict} on {args.file}, so it "
                             "has no counterexample to draw")
        cex = check.counterexample
        highlight = Highlight(states={*cex.states_visited(), *cex.highlight},
                              transitions={s.transition for _, s in cex.path if s.transition is not None})
        print(f"{args.file}: {check.name} {check.verdict} — {check.detail}", file=sys.stderr)
    print(to_mermaid(m, highlight) if args.format == "mermaid" else to_dot(m, highlight))
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from taskflow.catalogue.completions import completed_json_schema

    print(json.dumps(completed_json_schema(), indent=2))
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The verbs validate, graph, schema, lsp."""
    v = sub.add_parser("validate", help="check mission files; exit 1 if any is invalid")
    v.add_argument("files", nargs="+")
    v.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    v.add_argument("--verify", action="store_true",
                   help="also run `taskflow verify`'s checks on each valid file (exit 1 if one fails)")
    v.set_defaults(fn=cmd_validate)

    g = sub.add_parser("graph", help="print the machine as a diagram")
    g.add_argument("file")
    g.add_argument("--format", choices=["mermaid", "dot"], default="mermaid")
    g.add_argument("--counterexample", default=None, metavar="CHECK",
                   help="highlight the path of a failing `taskflow verify` check's counterexample (no_trap, timed_exit, "
                        "duration, outcomes, region_conflicts or property:NAME)")
    g.set_defaults(fn=cmd_graph)

    s = sub.add_parser("schema", help="print the JSON Schema of mission files (registered names and their "
                                      "parameters included, for editors)")
    s.set_defaults(fn=cmd_schema)

    lsp = sub.add_parser("lsp", help="serve the Language Server Protocol on stdin/stdout for an editor: diagnostics as "
                                     "you type, completion, hover, navigation, rename, code actions (docs/editors.md)")
    lsp.add_argument("--stdio", action="store_true", help="accepted for editors that pass it; stdio is the only transport")
    lsp.set_defaults(fn=cmd_lsp)


def cmd_lsp(args: argparse.Namespace) -> int:
    from taskflow.lsp.server import main as serve

    return serve()
