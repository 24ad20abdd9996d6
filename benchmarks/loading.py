"""How ``taskflow validate`` scales with a mission's size (issue 24: a 10,000-state mission in at most 3 s, linear).

Generated machines of ``--sizes`` states (``tests/verify/machines.py`` ``generate_large``, on the toy robot,
world and tasks of ``tests/toys.py``) are timed two ways:

- **validate**: ``taskflow validate FILE`` in a fresh process (Python's start and the imports included), its wall
  time and its CPU time (user + system: what the 2-core machine shared with others inflates least), each the best
  of ``--repeat``; the toy plugins are registered as a plugin package would register its own;
- **phases**: in this process, the load path split into its steps (CPU time of this process, the best of
  ``--repeat`` loads per size): YAML
  composition (libyaml's composer, or PyYAML's pure-Python one when libyaml is missing — the JSON names which),
  the source map, the construction of the data, ``use:`` expansion, the schema (pydantic), then each compiler
  pass.  A step is timed by wrapping the function that does it (outermost call only); "other" is what the
  load took beyond its steps.

Then the cost per state and the linearity: (time at the largest size / time at the smallest) ÷ (size ratio),
1.0 when linear.  ``--checkout PATH`` times another checkout's code (e.g. a worktree of main for "before"):
its ``taskflow`` package is put first on the path here and in the subprocesses; the generator and the toy plugins
are this checkout's.

Usage: ``python benchmarks/loading.py [--sizes 1000 2000 5000 10000] [--repeat 3] [--checkout PATH]``.
The last line is JSON.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import importlib
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"

PHASES: list[tuple[str, str, str]] = [  # (step, module, attribute); a missing attribute is left out
    ("yaml: node count", "taskflow.mission.yamlsrc", "too_many_nodes"),
    ("yaml: compose", "taskflow.mission.yamlsrc", "_compose"),
    ("yaml: source map", "taskflow.mission.yamlsrc", "_walk"),
    ("yaml: construct", "yaml.constructor", "BaseConstructor.construct_document"),
    ("use: expansion", "taskflow.mission.loader", "expand_uses"),
    ("schema (pydantic)", "taskflow.mission.loader", "Mission.model_validate"),
    ("compile (all passes)", "taskflow.mission.loader", "compile_document"),
    ("pass: components", "taskflow.mission.compile", "resolve_components"),
    ("pass: tree", "taskflow.mission.compile", "build_tree"),
    ("pass: region metrics", "taskflow.mission.compile", "check_region_metrics"),
    ("pass: region names", "taskflow.mission.compile", "check_region_names"),
    ("pass: catalogue", "taskflow.mission.compile", "catalogue"),
    ("pass: data catalogue", "taskflow.mission.compile", "data_catalogue"),
    ("pass: profiles", "taskflow.mission.compile", "bind_profiles"),
    ("pass: parameters", "taskflow.mission.compile", "check_parameters"),
    ("pass: transitions", "taskflow.mission.compile", "compile_transitions"),
    ("pass: structure", "taskflow.mission.compile", "check_structure"),
    ("pass: dataflow", "taskflow.mission.compile", "check_dataflow"),
    ("pass: guard parameters", "taskflow.mission.compile", "guard_params"),
    ("pass: properties", "taskflow.mission.compile", "compile_properties"),
]
TOP = ("load_yaml_text", "compile_mission")  # the two halves of the load, for "other"

VALIDATE = f"""
import os, sys
sys.path[:0] = [{str(TESTS)!r}]
import toys
toys.register()
if os.environ.get("LOADING_MAX_NODES"):
    import taskflow.mission.yamlsrc
    taskflow.mission.yamlsrc.MAX_NODES = int(os.environ["LOADING_MAX_NODES"])
from taskflow.cli import main
sys.exit(main(["validate", *sys.argv[1:]]))
"""


class _Timer:
    """Accumulated seconds per step, each step's function wrapped so that only its outermost call counts."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.depth: dict[str, int] = {}

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            self.depth[name] = self.depth.get(name, 0) + 1
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.depth[name] -= 1
                if self.depth[name] == 0:
                    self.seconds[name] = self.seconds.get(name, 0.0) + time.process_time() - t0
        return timed

    def install(self) -> list[str]:
        installed = []
        for name, module, attr in [*PHASES, *((t, "taskflow.mission.yamlsrc" if t == TOP[0] else "taskflow.mission.loader",
                                                t) for t in TOP)]:
            owner: Any = importlib.import_module(module)
            *outer, last = attr.split(".")
            for part in outer:
                owner = getattr(owner, part, None)
            if owner is None or not hasattr(owner, last):
                continue
            setattr(owner, last, self.wrap(name, getattr(owner, last)))
            installed.append(name)
        # loader.py imported load_yaml_text by name before it was wrapped: route it through the wrapper
        loader = importlib.import_module("taskflow.mission.loader")
        yamlsrc = importlib.import_module("taskflow.mission.yamlsrc")
        loader.load_yaml_text = yamlsrc.load_yaml_text  # type: ignore[attr-defined]
        return installed


def _phases(files: dict[int, Path], repeat: int) -> tuple[dict[int, dict[str, float]], list[str]]:
    import toys

    toys.register()
    timer = _Timer()
    installed = timer.install()
    from taskflow.mission.loader import load_mission

    load_mission(files[min(files)])  # imports
    out: dict[int, dict[str, float]] = {}
    for n, path in files.items():
        best: dict[str, float] | None = None
        for _ in range(repeat):
            timer.seconds = {}
            t0 = time.process_time()
            mission = load_mission(path)
            total = time.process_time() - t0
            run = {k: v for k, v in timer.seconds.items()}
            run["total"] = total
            run["states"] = len(mission.states)
            if best is None or total < best["total"]:
                best = run
        assert best is not None
        steps = [p for p, _, _ in PHASES if p in best and not p.startswith("pass:")]
        best["other"] = best["total"] - sum(best[p] for p in steps)
        for t in TOP:
            best.pop(t, None)
        out[n] = best
    return out, installed


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _validate(path: Path, repeat: int, env: dict[str, str]) -> tuple[float, float]:
    """Best wall time and best CPU time (user + system) of ``taskflow validate path`` in a fresh process."""
    wall = cpu = math.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), _cpu_children()
        proc = subprocess.run([sys.executable, "-c", VALIDATE, str(path)], capture_output=True, text=True, env=env)
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, _cpu_children() - c0)
        if proc.returncode != 0 or ": ok (" not in proc.stdout:
            raise SystemExit(f"taskflow validate {path} failed: {proc.stdout}{proc.stderr}")
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 2000, 5000, 10000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--checkout", type=Path, default=ROOT, help="the checkout whose taskflow package is timed")
    ap.add_argument("--no-wall", action="store_true", help="only the in-process phases")
    ap.add_argument("--max-nodes", type=int, default=None,
                    help="set the checkout's YAML node limit (main before issue 24 refuses 10,000 states)")
    args = ap.parse_args()
    checkout = args.checkout.resolve()
    sys.path[:0] = [str(checkout), str(TESTS), str(TESTS / "verify")]
    from machines import generate_large

    import taskflow
    from taskflow.mission import yamlsrc

    assert Path(taskflow.__file__).resolve().is_relative_to(checkout), taskflow.__file__
    if args.max_nodes is not None:
        yamlsrc.MAX_NODES = args.max_nodes
    composer = getattr(yamlsrc, "COMPOSER", "libyaml" if getattr(yamlsrc, "_CParser", None) is not None else "pure Python")
    # the generator takes minutes at 10,000 states: its texts are kept, by the generator's own hash
    tag = hashlib.sha256((TESTS / "verify" / "machines.py").read_bytes()).hexdigest()[:12]
    tmp = Path(tempfile.gettempdir()) / f"taskflow-loading-{tag}"
    tmp.mkdir(exist_ok=True)
    files: dict[int, Path] = {}
    for n in sorted(args.sizes):
        files[n] = tmp / f"generated_{n}.yaml"
        if not files[n].exists():
            part = files[n].with_suffix(".part")
            part.write_text(generate_large(n))
            part.replace(files[n])
    env = {**os.environ, "LOADING_MAX_NODES": str(args.max_nodes or ""), "PYTHONPATH": os.pathsep.join([str(checkout), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    runs = {} if args.no_wall else {n: _validate(p, args.repeat, env) for n, p in files.items()}
    phases, installed = _phases(files, args.repeat)
    lo, hi = min(files), max(files)
    print(f"checkout {checkout} ({composer} composer); best of {args.repeat}")
    print("states: " + ", ".join(f"{n} asked, {int(phases[n]['states'])} made" for n in files))
    names = [p for p, _, _ in PHASES if p in installed] + ["other", "total"]
    width = max(map(len, names))
    print(f"{'step':{width}s} " + " ".join(f"{n:>9d}" for n in files) + "   s/1k states  linearity")
    rows = ([("validate wall", {n: w for n, (w, _) in runs.items()}),
             ("validate cpu", {n: c for n, (_, c) in runs.items()})] if runs else []) + [(p, {n: phases[n].get(p, 0.0) for n in files}) for p in names]
    table: dict[str, dict[str, Any]] = {}
    for name, by_size in rows:
        lin = (by_size[hi] / by_size[lo]) / (hi / lo) if by_size[lo] > 0 else float("nan")
        per_k = 1000 * by_size[hi] / hi
        print(f"{name:{width}s} " + " ".join(f"{by_size[n]:9.3f}" for n in files) + f"   {per_k:11.3f}  {lin:9.2f}")
        table[name] = {"seconds": {str(n): round(by_size[n], 4) for n in files}, "per_1k_states_s": round(per_k, 4),
                       "linearity": round(lin, 2)}
    import yaml

    from taskflow.execution.provenance import versions

    print(json.dumps({"benchmark": "loading", "target": {"states": 10000, "validate_wall_s": 3.0},
                      "checkout": str(checkout), "composer": composer, "max_nodes": yamlsrc.MAX_NODES, "sizes": sorted(files),
                      "states": {str(n): int(phases[n]["states"]) for n in files}, "repeat": args.repeat,
                      "steps": table, "versions": {**versions(), "pyyaml": yaml.__version__,
                                                   "libyaml": getattr(yaml, "__with_libyaml__", False)}}))


if __name__ == "__main__":
    main()
