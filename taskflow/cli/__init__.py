"""``taskflow`` command line: run, view, ctl, validate, graph, schema, lsp, verify, batch, compare, teach, plot, export, check,
list, describe.

Exit codes: 0 success; 1 the mission did not succeed / a file is invalid; 2 bad usage;
130 interrupted (Ctrl-C), 143 terminated (SIGTERM) — ``run`` and ``batch`` alike, once the record is written.

May import: every package of the framework (it is the top layer); nothing imports it but its entry point
(``tests/test_dependency_direction.py`` enforces it).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from taskflow.cli import authoring, campaigns, catalogue, outputs, running, verifying
from taskflow.cli.common import UsageError, print_problems
from taskflow.errors import MissionError


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="taskflow", description="Run robot missions written as YAML state machines.")
    sub = ap.add_subparsers(dest="cmd", required=True)
    for group in (running, authoring, verifying, campaigns, outputs, catalogue):  # the order of ``taskflow --help``
        group.add_parsers(sub)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.fn(args))
    except MissionError as exc:
        print_problems(exc)
        return 1
    except UsageError as exc:
        print(f"taskflow {args.cmd}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
