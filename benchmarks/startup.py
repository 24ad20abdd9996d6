"""How long the command line takes before it does its work (issue 24), measured as separate processes.

- **run**: ``taskflow run`` of the default mission (no file: the shipped default) from the process's start to its
  first tick, split into *imports* (interpreter start and the imports, up to the mission's load), *mission load*
  (``load_mission``), *world build* (robot, record, the world's constructor: up to the executor's construction),
  *endpoint start* (the operator endpoint, on by default: ``ControlServer.start``, uvicorn's imports) and *world
  reset* (``World.reset``: up to ``Executor.start``); the process is killed at its first tick.
- **batch**: ``taskflow batch`` of the default mission (``--trials 2 --workers 2``, the process pool) from the
  process's start to its first trial starting (the first call of ``run_trial``, in whichever process); killed then.
- **validate**: ``taskflow validate`` of the default mission, the whole process.
- **lsp**: ``taskflow lsp`` from the process's start to its answer to ``initialize`` over stdio.

The marks come from a timing hook in the child process (:data:`CHILD`), not from the product: an import hook wraps
``load_mission``, ``Executor.__init__`` / ``start`` / ``tick``, ``ControlServer.start`` and ``run_trial`` when
their modules load, and appends ``name pid time.time()`` to a file at their first call in each process; the process
start is the parent's ``time.time()`` just before it starts the child.  Nothing a run writes changes.  So the same benchmark measures
any checkout: ``--python`` names the interpreters of the checkouts to compare (each its own venv), run alternately,
repeat by repeat, in one session; with two of them the ratios (first / second) of the medians are printed.
``-X importtime`` then gives, once per interpreter, the top-level imports of ``run`` and ``batch`` that cost most.

Usage: ``python benchmarks/startup.py [--repeat 7] [--python BEFORE/bin/python --python AFTER/bin/python]``.
The last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

CHILD = r'''
import os, sys, time, importlib.util
_out = open(os.environ["STARTUP_MARKS"], "a", buffering=1)
_seen = set()
def _mark(name):
    if name not in _seen:
        _seen.add(name)
        _out.write(f"{name} {os.getpid()} {time.time()!r}\n")
def _wrap(fn, name):
    def wrapper(*a, **k):
        _mark(name + ":begin")
        try:
            return fn(*a, **k)
        finally:
            _mark(name + ":end")
    wrapper.__name__, wrapper.__qualname__, wrapper.__module__ = fn.__name__, fn.__qualname__, fn.__module__
    return wrapper
_WRAP = {"taskflow.mission.loader": ["load_mission"], "taskflow.campaigns.backends": ["run_trial"],
         "taskflow.execution.executor": ["Executor.__init__", "Executor.start", "Executor.tick"],
         "taskflow.operate.control_http": ["ControlServer.start"]}
def _patch(module, names):
    for dotted in names:
        owner, attr = module, dotted
        if "." in dotted:
            cls, attr = dotted.split(".")
            owner = getattr(module, cls)
        setattr(owner, attr, _wrap(getattr(owner, attr), dotted))
class _Hook:
    def find_spec(self, name, path=None, target=None):
        if name not in _WRAP:
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        run = spec.loader.exec_module
        def exec_module(module):
            run(module)
            _patch(module, _WRAP[name])
        spec.loader.exec_module = exec_module
        return spec
sys.meta_path.insert(0, _Hook())
from taskflow.cli import main
sys.exit(main(sys.argv[1:]))
'''

PLAIN = "import sys\nfrom taskflow.cli import main\nsys.exit(main(sys.argv[1:]))"  # the console script's body


def _default_mission(python: str) -> str:
    return subprocess.run([python, "-c", "import taskflow_missions; print(taskflow_missions.DEFAULT)"],
                          check=True, capture_output=True, text=True).stdout.strip()


def _read_marks(path: Path) -> dict[str, float]:
    """The earliest time of each mark over every process."""
    marks: dict[str, float] = {}
    for line in path.read_text().splitlines():
        name, _pid, t = line.split()
        marks[name] = min(marks.get(name, float("inf")), float(t))
    return marks


def _until(python: str, args: list[str], until: str, tmp: Path, timeout: float = 120.0) -> dict[str, float]:
    """Start ``taskflow ARGS`` under the timing hook and kill its process group once mark ``until`` is written;
    the marks in seconds from the start."""
    marks_file = tmp / "marks.txt"
    marks_file.write_text("")
    env = {**os.environ, "STARTUP_MARKS": str(marks_file)}
    t0 = time.time()
    proc = subprocess.Popen([python, "-c", CHILD, *args], cwd=tmp, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        while until not in _read_marks(marks_file):
            if proc.poll() is not None:
                raise RuntimeError(f"taskflow {' '.join(args)} ended (exit {proc.returncode}) before {until}: "
                                   f"{proc.stderr.read().decode()[-2000:] if proc.stderr else ''}")
            if time.time() - t0 > timeout:
                raise RuntimeError(f"taskflow {' '.join(args)}: no {until} within {timeout:g} s")
            time.sleep(0.002)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        if proc.stderr:
            proc.stderr.close()
    return {k: v - t0 for k, v in _read_marks(marks_file).items()}


def _fresh(tmp: Path, name: str) -> Path:
    """A directory name not used yet (a batch refuses a directory that holds a campaign)."""
    return Path(tempfile.mkdtemp(prefix=f"{name}-", dir=tmp)) / "out"


def measure_run(python: str, tmp: Path) -> dict[str, float]:
    m = _until(python, ["run", "--out", str(_fresh(tmp, "run"))], "Executor.tick:begin", tmp)
    return {"first_tick_s": m["Executor.tick:begin"], "imports_s": m["load_mission:begin"],
            "mission_load_s": m["load_mission:end"] - m["load_mission:begin"],
            "world_build_s": m["Executor.__init__:begin"] - m["load_mission:end"],
            "endpoint_start_s": m["ControlServer.start:end"] - m["ControlServer.start:begin"],
            "world_reset_s": m["Executor.start:begin"] - m["ControlServer.start:end"]}


def measure_batch(python: str, tmp: Path, mission: str) -> dict[str, float]:
    m = _until(python, ["batch", mission, "--trials", "2", "--workers", "2", "--out", str(_fresh(tmp, "batch"))],
               "run_trial:begin", tmp)
    return {"first_trial_s": m["run_trial:begin"]}


def measure_validate(python: str, tmp: Path, mission: str) -> dict[str, float]:
    t0 = time.perf_counter()
    subprocess.run([python, "-c", PLAIN, "validate", mission], cwd=tmp, check=True, capture_output=True)
    return {"validate_s": time.perf_counter() - t0}


def _lsp_message(payload: dict[str, Any]) -> bytes:
    body = json.dumps(payload).encode()
    return f"Content-Length: {len(body)}\r\n\r\n".encode() + body


def measure_lsp(python: str, tmp: Path) -> dict[str, float]:
    t0 = time.perf_counter()
    proc = subprocess.Popen([python, "-c", PLAIN, "lsp"], cwd=tmp, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL)
    assert proc.stdin is not None and proc.stdout is not None
    try:
        proc.stdin.write(_lsp_message({"jsonrpc": "2.0", "id": 1, "method": "initialize",
                                       "params": {"processId": os.getpid(), "rootUri": None, "capabilities": {}}}))
        proc.stdin.flush()
        length = 0
        while (line := proc.stdout.readline().strip()):
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":")[1])
        reply = json.loads(proc.stdout.read(length))
        elapsed = time.perf_counter() - t0
        if reply.get("id") != 1 or "result" not in reply:
            raise RuntimeError(f"taskflow lsp: unexpected answer to initialize: {reply}")
    finally:
        proc.kill()
        proc.wait()
    return {"lsp_initialize_s": elapsed}


def import_breakdown(python: str, tmp: Path, args: list[str], top: int = 8) -> list[dict[str, Any]]:
    """The top-level imports (as ``python -X importtime`` nests them) that cost most, for ``taskflow ARGS``
    run to its end with trials and world kept short."""
    res = subprocess.run([python, "-X", "importtime", "-c", PLAIN, *args], cwd=tmp, capture_output=True, text=True)
    rows = []
    for line in res.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        _, cum_us, name = line.split("|")
        rows.append((name.rstrip()[1:], int(cum_us)))  # the name after one space; nested ones indent further
    level0 = [(name.strip(), cum) for name, cum in rows if not name.startswith("  ")]
    level0.sort(key=lambda r: -r[1])
    return [{"module": name, "cumulative_ms": round(cum / 1000, 1)} for name, cum in level0[:top]]


def _median(rows: list[dict[str, float]]) -> dict[str, float]:
    return {k: round(statistics.median(r[k] for r in rows), 4) for k in rows[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--python", action="append", default=[],
                    help="an interpreter whose taskflow checkout to measure (repeatable; default: this one)")
    ap.add_argument("--no-lsp", action="store_true", help="skip taskflow lsp")
    args = ap.parse_args()
    pythons = args.python or [sys.executable]
    samples: dict[str, list[dict[str, float]]] = {py: [] for py in pythons}
    missions = {py: _default_mission(py) for py in pythons}
    with tempfile.TemporaryDirectory(prefix="startup-bench-") as d:
        tmp = Path(d)
        for py in pythons:  # warm the file cache once each, not measured
            measure_validate(py, tmp, missions[py])
        for i in range(args.repeat):
            for py in pythons:  # alternately, so the machine's load falls on both alike
                row = {**measure_run(py, tmp), **measure_batch(py, tmp, missions[py]),
                       **measure_validate(py, tmp, missions[py])}
                if not args.no_lsp:
                    row.update(measure_lsp(py, tmp))
                samples[py].append(row)
                print(f"repeat {i + 1} {py}: " + ", ".join(f"{k} {v:.3f}" for k, v in row.items()), file=sys.stderr)
        medians = {py: _median(rows) for py, rows in samples.items()}
        breakdown = {py: {"run": import_breakdown(py, tmp, ["run", "--max-time", "0.05", "--out", str(_fresh(tmp, "r"))]),
                          "batch": import_breakdown(py, tmp, ["batch", missions[py], "--trials", "1", "--workers",
                                                              "1", "--max-time", "0.05", "--out", str(_fresh(tmp, "b"))])}
                     for py in pythons}
    for py in pythons:
        print(f"{py}: medians of {args.repeat} (s)")
        for k, v in medians[py].items():
            print(f"  {k:<18} {v:7.3f}")
        for what, top in breakdown[py].items():
            print(f"  -X importtime, {what}: " + ", ".join(f"{r['module']} {r['cumulative_ms']:.0f} ms" for r in top))
    ratios = None
    if len(pythons) == 2:
        a, b = medians[pythons[0]], medians[pythons[1]]
        ratios = {k: round(a[k] / b[k], 2) if b[k] > 0 else None for k in a}
        print("ratios (first / second): " + ", ".join(f"{k} {v}" for k, v in ratios.items()))
    print(json.dumps({"benchmark": "startup", "repeat": args.repeat, "pythons": pythons, "medians_s": medians,
                      "ratios_first_over_second": ratios, "importtime_top": breakdown,
                      "targets_s": {"first_tick_s": 0.4, "first_trial_s": 1.0}}))


if __name__ == "__main__":
    main()
