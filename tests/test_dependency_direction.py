"""tasks/ and robots/ never import pybullet or sim/ (nor the runtime); sim/ is the only pybullet user and
never imports tasks/ or the framework's machinery (loader, compiler, executor): the plugins see the framework
only through its public modules (:data:`PUBLIC_API`).

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
    "taskflow.shaping",  # the papers' activation h(t), shared with the executor's blend
    "taskflow.units",  # quantities and units
    "taskflow.errors",  # typed exceptions
)
"""The framework modules ``tasks/``, ``robots/`` and ``sim/`` may import; everything else in ``taskflow``
(loader, schema, compiler, executor, runtime, records, cli, batch, ...) is the machinery that runs them."""
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
