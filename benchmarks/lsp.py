"""How fast ``taskflow lsp`` answers, measured through the client the tests use (pytest-lsp's LanguageClient over
stdio, the server a separate ``taskflow lsp`` process).

- **diagnostics after a change**: the wall time from sending ``didChange`` (the whole text, one character of a
  number edited, alternately valid and invalid so that every publish differs) to receiving the
  ``publishDiagnostics`` for it — the debounce (``taskflow.lsp.server.DEBOUNCE_S``) included;
- **completion**: the round trip of a ``textDocument/completion`` request at each of several places in the file
  (a task name, a transition target, an event, a guard's metric, a state key, a profile in ``bind``);
- **hover**: the round trip of a ``textDocument/hover`` at the same places.

On the largest shipped mission (``missions/screw_fastening.yaml``, 27 states with its sub-mission) and on
``missions/viki_hyco.yaml``; then, past the shipped sizes, diagnostics on a generated machine of ``--states``
states (``tests/verify/machines.py``, the toy plugins: the server is ``tests/lsp/toy_server.py``).  Targets
(issue 23): diagnostics within 300 ms of a change, completion within 100 ms, on the shipped missions.

Usage: ``python benchmarks/lsp.py [--repeat 30] [--states 1000]``.  The last line is JSON.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from lsprotocol import types
from pytest_lsp import client_capabilities, make_test_lsp_client

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from importlib.metadata import version as _version

from taskflow.execution.provenance import versions
from taskflow.lsp.server import DEBOUNCE_S

PLACES = {  # file → (what, text just before the cursor) — each at the end of the first occurrence
    "screw_fastening.yaml": [("state key", "  cell:\n      "), ("event", "on: target_l"),
                             ("transition target", "to: error_s"), ("use file", "use: lib/")],
    "viki_hyco.yaml": [("task name", "task: {name: viki_h"), ("guard metric", 'when: "pos_e'),
                       ("transition target", "to: backw"), ("profile in bind", "bind: {")],
}


def _pos(text: str, before: str) -> types.Position | None:
    at = text.find(before)
    if at < 0:
        return None
    at += len(before)
    return types.Position(line=text.count("\n", 0, at), character=at - (text.rfind("\n", 0, at) + 1))


def _summary(xs: list[float]) -> dict[str, float]:
    xs = sorted(xs)
    return {"median_ms": round(1000 * statistics.median(xs), 1), "p90_ms": round(1000 * xs[int(0.9 * (len(xs) - 1))], 1),
            "max_ms": round(1000 * xs[-1], 1), "n": len(xs)}


async def _measure(name: str, repeat: int, text: str | None = None) -> dict[str, Any]:
    path = ROOT / "missions" / name
    text = path.read_text() if text is None else text
    uri = path.resolve().as_uri()
    client = make_test_lsp_client()
    if name in PLACES:
        await client.start_io(sys.executable, "-m", "taskflow.cli", "lsp")
    else:  # a generated machine on the toy robot, world and tasks
        await client.start_io(sys.executable, str(ROOT / "tests" / "lsp" / "toy_server.py"))
    await client.initialize_session(types.InitializeParams(capabilities=client_capabilities("visual-studio-code"),
                                                           root_uri=path.parent.as_uri()))
    client.text_document_did_open(types.DidOpenTextDocumentParams(text_document=types.TextDocumentItem(
        uri=uri, language_id="yaml", version=1, text=text)))
    while uri not in client.diagnostics:  # the first analysis imports the tasks and worlds the mission names
        await asyncio.sleep(0.005)
    at = text.index("rate_hz:") + len("rate_hz: ")
    diag_times: list[float] = []
    flagged = 0  # invalid edits that got their diagnostic (the analysis really ran on each change)
    for k in range(repeat):
        edited = text[:at] + ("0" if k % 2 == 0 else "") + text[at:]  # rate_hz: 0 is refused, then restored
        client.diagnostics.pop(uri, None)
        t0 = time.perf_counter()
        client.text_document_did_change(types.DidChangeTextDocumentParams(
            text_document=types.VersionedTextDocumentIdentifier(uri=uri, version=k + 2),
            content_changes=[types.TextDocumentContentChangeWholeDocument(text=edited)]))
        while uri not in client.diagnostics:
            await asyncio.sleep(0.001)
        diag_times.append(time.perf_counter() - t0)
        flagged += k % 2 == 0 and any("rate_hz" in d.message for d in client.diagnostics[uri])
    doc = types.TextDocumentIdentifier(uri=uri)
    completion: dict[str, list[float]] = {}
    hover: list[float] = []
    items: dict[str, int] = {}
    for what, before in PLACES.get(name, []):
        p = _pos(text, before)
        if p is None:
            continue
        for _ in range(repeat):
            t0 = time.perf_counter()
            result = await client.text_document_completion_async(types.CompletionParams(text_document=doc, position=p))
            completion.setdefault(what, []).append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            await client.text_document_hover_async(types.HoverParams(text_document=doc, position=p))
            hover.append(time.perf_counter() - t0)
        got = result.items if isinstance(result, types.CompletionList) else (result or [])
        items[what] = len(got)
    await client.shutdown_session()
    await client.stop()
    every = [x for xs in completion.values() for x in xs]
    out: dict[str, Any] = {"mission": name, "lines": text.count("\n"), "diagnostics": _summary(diag_times),
                           "invalid_edits": (repeat + 1) // 2, "invalid_edits_flagged": flagged}
    if every:
        out.update(completion=_summary(every), completion_by_place={k: _summary(v) for k, v in completion.items()},
                   completion_items=items, hover=_summary(hover))
    return out


def _in_process(text: str, file: str) -> dict[str, float]:
    """The server's analysis of ``text`` and its YAML step alone, timed in this process (best of 5, ms): where a
    large machine's diagnostics time goes, without the protocol."""
    import toys  # tests/toys.py: the toy plugins the generated machine is written against

    from taskflow.lsp.analysis import analyse
    from taskflow.mission.yamlsrc import load_yaml_text

    toys.register()
    analyse(text, file)  # imports
    out = {}
    for name, fn in (("analyse", lambda: analyse(text, file)), ("load_yaml_text", lambda: load_yaml_text(text, file))):
        best = math.inf
        for _ in range(5):
            t0 = time.perf_counter()
            fn()
            best = min(best, time.perf_counter() - t0)
        out[name] = round(best * 1000, 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--states", type=int, default=1000, help="states of the generated machine (0: none)")
    args = ap.parse_args()
    results = []
    if args.states:
        sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "verify")]
        from machines import generate_large

        text = generate_large(args.states)
        r = asyncio.run(_measure(f"generated_{args.states}.yaml", max(3, args.repeat // 5), text))
        r["in_process_ms"] = _in_process(text, str(ROOT / "missions" / f"generated_{args.states}.yaml"))
        results.append(r)
        print(f"a generated machine ({text.count(chr(10))} lines, {args.states} states): diagnostics after a change "
              f"median {r['diagnostics']['median_ms']} ms, max {r['diagnostics']['max_ms']} ms; in this process, "
              f"best of 5: the analysis {r['in_process_ms']['analyse']} ms, of it composing the YAML with its source "
              f"map {r['in_process_ms']['load_yaml_text']} ms")
    for name in PLACES:
        r = asyncio.run(_measure(name, args.repeat))
        results.append(r)
        print(f"{name} ({r['lines']} lines): diagnostics after a change median {r['diagnostics']['median_ms']} ms, "
              f"p90 {r['diagnostics']['p90_ms']} ms, max {r['diagnostics']['max_ms']} ms (debounce {DEBOUNCE_S * 1000:.0f} ms "
              f"included); completion median {r['completion']['median_ms']} ms, p90 {r['completion']['p90_ms']} ms, "
              f"max {r['completion']['max_ms']} ms; hover median {r['hover']['median_ms']} ms")
        for what, s in r["completion_by_place"].items():
            print(f"    completion at {what}: median {s['median_ms']} ms, max {s['max_ms']} ms, "
                  f"{r['completion_items'][what]} items")
    print(json.dumps({"benchmark": "lsp", "targets_ms": {"diagnostics": 300, "completion": 100},
                      "results": results,
                      "versions": {**versions(), **{d: _version(d) for d in ("pygls", "lsprotocol", "pytest-lsp")}}}))


if __name__ == "__main__":
    main()
