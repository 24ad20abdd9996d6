"""tasks/ and robots/ never import pybullet or sim/ (nor the runtime); sim/ is the only pybullet user and
never imports tasks/ or the framework's machinery (loader, compiler, executor): the plugins see the framework
only through its public modules (:data:`PUBLIC_API`).

Inside the framework the machinery sits in packages by concept, each importing only the layers below it
(:data:`MACHINERY`, the table each package's ``__init__`` states); the public modules import none of them,
and no two framework modules import each other, directly or round a longer circle, at any depth.

The folders install as ``taskflow_tasks``, ``taskflow_robots`` and ``taskflow_sim`` (setup.py
maps them), so a user's own ``tasks`` or ``sim`` package is never shadowed."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE_OF = {"tasks": "taskflow_tasks", "robots": "taskflow_robots", "sim": "taskflow_sim", "taskflow": "taskflow"}
_PLUGINS = ("taskflow_sim", "taskflow_tasks", "taskflow_robots", "sim", "tasks", "robots")
PUBLIC_API = (
    "taskflow.api",  # the contracts: Task, Robot, World, Observation, StrictModel, ...
    "taskflow.specs",  # observation specs (also re-exported by taskflow.api)
    "taskflow.markers",  # scene markers and control points for figures (re-exported by taskflow.api)
    "taskflow.registry",  # register_task / register_robot / register_world
    "taskflow.fidelity",  # a world's named fidelity levels (Fidelity, Sourced)
    "taskflow.messages",  # typed sensor messages: worlds produce them, tasks read them
    "taskflow.spatial",  # rigid-body maths named by direction
    "taskflow.planar",  # planar transforms (re-exported by taskflow.spatial)
    "taskflow.shaping",  # the papers' activation h(t), shared with the executor's blend
    "taskflow.units",  # quantities and units
    "taskflow.errors",  # typed exceptions
)
"""The framework modules ``tasks/``, ``robots/`` and ``sim/`` may import; everything else in ``taskflow``
(loader, schema, compiler, executor, runtime, records, cli, batch, ...) is the machinery that runs them."""
MACHINERY: dict[str, frozenset[str]] = {
    "mission": frozenset(),  # the format and its compiler: the bottom layer
    "execution": frozenset({"mission"}),  # a run: engine, executor, runtime, what it writes
    "readers": frozenset({"mission", "execution"}),  # a finished record read back
    # the HTTP endpoint, the web view; the campaign page reads a batch folder as campaigns writes it
    "operate": frozenset({"mission", "execution", "readers", "campaigns"}),
    "catalogue": frozenset({"mission"}),  # what is registered, described
    "campaigns": frozenset({"mission", "execution", "readers", "catalogue"}),  # many runs, their statistics
    # the finite model, its checks (Storm), counterexamples replayed on the scripted backend, campaign predictions
    "verify": frozenset({"mission", "execution", "readers", "catalogue", "campaigns"}),
    "lsp": frozenset({"mission", "catalogue"}),  # the language server: the load path and the catalogue in the editor
    "cli": frozenset({"mission", "execution", "readers", "operate", "catalogue", "campaigns", "verify", "lsp"}),  # the command
    "testing": frozenset({"mission", "execution"}),  # the pytest plugin (a top-level module)
}
"""Framework package → the machinery packages it may import (the public modules, :data:`PUBLIC_API`, it
may always import)."""
FORBIDDEN = {
    "tasks": ("pybullet", "pybullet_data", "taskflow_sim", "sim"),
    "robots": ("pybullet", "pybullet_data", "taskflow_sim", "sim", "taskflow_tasks", "tasks"),
    # sim/ may import robots/ (descriptions and messages) and the public API, never the control laws
    "sim": ("taskflow_tasks", "tasks"),
    "taskflow": ("pybullet", "pybullet_data", *_PLUGINS),
}


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every absolute import in the file, at any depth (imports inside functions count);
    ``from taskflow import x`` is reported as ``taskflow.x``."""
    tree = ast.parse(path.read_text(), str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "taskflow":
                out += [(node.lineno, f"taskflow.{a.name}") for a in node.names]
            else:
                out.append((node.lineno, node.module))
    return out


def _is(mod: str, prefix: str) -> bool:
    return mod == prefix or mod.startswith(prefix + ".")


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_forbidden_imports_in_source(package):
    bad = []
    for f in sorted((ROOT / package).rglob("*.py")):
        for line, mod in _imports(f):
            if any(_is(mod, fb) for fb in FORBIDDEN[package]):
                bad.append(f"{f.relative_to(ROOT)}:{line}: imports {mod}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("package", ["tasks", "robots", "sim"])
def test_plugins_use_only_the_public_api_of_the_framework(package):
    bad = []
    for f in sorted((ROOT / package).rglob("*.py")):
        for line, mod in _imports(f):
            if _is(mod, "taskflow") and not any(_is(mod, m) for m in PUBLIC_API):
                bad.append(f"{f.relative_to(ROOT)}:{line}: imports {mod} (public: {', '.join(PUBLIC_API)})")
    assert not bad, "\n".join(bad)


def test_importing_sim_loads_no_task_and_no_framework_machinery():
    mods = ["taskflow_sim." + ".".join(f.relative_to(ROOT / "sim").with_suffix("").parts).removesuffix(".__init__")
            for f in sorted((ROOT / "sim").rglob("*.py")) if f.relative_to(ROOT / "sim").parts != ("__init__.py",)]
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        f"public = {PUBLIC_API!r}\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('tasks', 'taskflow_tasks')\n"
        "       or (m.startswith('taskflow.') and not m.startswith(public))]\n"
        "print(bad); sys.exit(1 if bad else 0)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_importing_tasks_and_robots_loads_no_simulator():
    mods = [f"{PACKAGE_OF[p]}.{f.stem}" for p in ("tasks", "robots") for f in sorted((ROOT / p).glob("*.py"))
            if f.stem != "__init__"]
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        "bad = [m for m in sys.modules if m == 'pybullet' or m.split('.')[0] in ('sim', 'taskflow_sim')]\n"
        "print(bad); sys.exit(1 if bad else 0)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def _framework_imports(path: Path) -> list[tuple[int, str]]:
    """Every import of a ``taskflow`` module in the framework file ``path``, relative ones resolved, at any
    depth (inside functions and ``if TYPE_CHECKING:`` too); ``from taskflow.x import y`` gives ``taskflow.x.y``
    when ``y`` is a module, else ``taskflow.x``."""
    rel = path.relative_to(ROOT).with_suffix("").parts
    package = list(rel if rel[-1] == "__init__" else rel[:-1])
    package = [p for p in package if p != "__init__"]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if _is(a.name, "taskflow")]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package[: len(package) - (node.level - 1)]
                base = ".".join([*up, *([node.module] if node.module else [])])
            if not _is(base, "taskflow"):
                continue
            subs = [f"{base}.{a.name}" for a in node.names]
            subs = [m for m in subs if (ROOT / Path(*m.split("."))).with_suffix(".py").exists()
                    or (ROOT / Path(*m.split("."))).is_dir()]
            out += [(node.lineno, m) for m in (subs if len(subs) == len(node.names) else [base, *subs])]
    return out


def _module(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _layer(module: str) -> str | None:
    """The machinery package (or ``testing``) a ``taskflow`` module belongs to; None for a public module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in MACHINERY else None


FRAMEWORK_FILES = sorted((ROOT / "taskflow").rglob("*.py"))


def test_every_machinery_package_says_what_it_holds_and_may_import():
    for name in MACHINERY:
        if name == "testing":
            continue
        doc = ast.get_docstring(ast.parse((ROOT / "taskflow" / name / "__init__.py").read_text())) or ""
        assert "May import" in doc, f"taskflow/{name}/__init__.py: its docstring says what it may import"


def test_machinery_packages_import_only_the_layers_below():
    bad = []
    for f in FRAMEWORK_FILES:
        here = _layer(_module(f))
        for line, mod in _framework_imports(f):
            there = _layer(mod)
            if there is None or there == here:
                continue
            if here is None:
                bad.append(f"{f.relative_to(ROOT)}:{line}: a public module imports the machinery ({mod})")
            elif there not in MACHINERY[here]:
                bad.append(f"{f.relative_to(ROOT)}:{line}: taskflow.{here} imports {mod} "
                           f"(may import: {', '.join(sorted(MACHINERY[here])) or 'the public modules only'})")
    assert not bad, "\n".join(bad)


def test_no_import_cycle_between_framework_modules():
    modules = {_module(f) for f in FRAMEWORK_FILES}
    graph = {_module(f): {m for _, m in _framework_imports(f) if m in modules and m != _module(f)}
             for f in FRAMEWORK_FILES}
    cycles: list[list[str]] = []
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not cycles, "modules that import each other: " + "; ".join(" <-> ".join(c) for c in cycles)
