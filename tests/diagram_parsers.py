"""Diagrams checked by their own parsers: Mermaid text by Mermaid's parser (the ``mermaid`` npm package
under Node, installed by ``npm ci`` in ``tests/js/`` — by the first test that needs it, or by ``.ci/run``), dot text by Graphviz's ``dot``.

Reused by the graph tests and the user-journey tests.  A missing parser is an error, never a skip: CI
(``.ci/run``) installs both, so a machine without them fails with a message saying how to install them.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

JS = Path(__file__).resolve().parent / "js"
"""The folder holding the pinned Mermaid package (``package.json``, ``package-lock.json``) and its script."""
MERMAID_SCRIPT = JS / "mermaid_parse.mjs"
"""Reads a JSON array of Mermaid texts on stdin, writes a JSON array of errors (``null`` for accepted)."""


class ParserMissing(RuntimeError):
    """A diagram parser (Node with the ``mermaid`` package, or Graphviz's ``dot``) is not installed."""


def mermaid_errors(texts: list[str], timeout: float = 120.0) -> list[str | None]:
    """For each Mermaid text, ``None`` when Mermaid's own parser accepts it, else the parser's message.
    Every text is parsed in one Node process (Node and Mermaid's import take about a second)."""
    node = shutil.which("node")
    if node is None:
        raise ParserMissing("node is not on PATH: install Node.js 20 (CI's .ci/run expects it)")
    _install_mermaid()
    proc = subprocess.run([node, str(MERMAID_SCRIPT)], input=json.dumps(texts), capture_output=True,
                          text=True, timeout=timeout, cwd=JS)
    if proc.returncode not in (0, 1):
        raise ParserMissing(f"{MERMAID_SCRIPT.name} exited {proc.returncode}: {proc.stderr.strip()[-2000:]}")
    errors = json.loads(proc.stdout)
    if not isinstance(errors, list) or len(errors) != len(texts):
        raise RuntimeError(f"{MERMAID_SCRIPT.name} answered {len(errors)} results for {len(texts)} texts")
    return errors


def _install_mermaid() -> None:
    """Install the pinned npm packages of ``tests/js`` (``npm ci``, the lock file's exact versions) when they
    are missing, so the README's test command needs no extra step; without npm, or when the install fails,
    say so."""
    if (JS / "node_modules" / "mermaid" / "package.json").is_file():
        return
    npm = shutil.which("npm")
    if npm is None:
        raise ParserMissing(f"the mermaid npm package is not installed and npm is not on PATH: install Node.js 20 "
                            f"with npm, then run `npm ci` in {JS}")
    proc = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=JS, capture_output=True,
                          text=True, timeout=600)
    if proc.returncode != 0 or not (JS / "node_modules" / "mermaid" / "package.json").is_file():
        raise ParserMissing(f"`npm ci` in {JS} failed (exit {proc.returncode}): {proc.stderr.strip()[-2000:]}")


def dot_errors(text: str, timeout: float = 60.0) -> str | None:
    """``None`` when Graphviz's ``dot -Tsvg`` lays ``text`` out without an error or warning, else what
    ``dot`` printed (its stderr, or its exit status)."""
    dot = shutil.which("dot")
    if dot is None:
        raise ParserMissing("Graphviz's dot is not on PATH: install graphviz (CI's .ci/run does)")
    proc = subprocess.run([dot, "-Tsvg"], input=text, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or proc.stderr.strip():
        return proc.stderr.strip() or f"dot exited {proc.returncode}"
    if "<svg" not in proc.stdout:
        return "dot wrote no SVG"
    return None
