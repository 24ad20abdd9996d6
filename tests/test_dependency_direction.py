"""tasks/ and robots/ never import pybullet or sim/ (nor the runtime); sim/ is the only pybullet user.

The folders install as ``taskflow_tasks``, ``taskflow_robots`` and ``taskflow_sim`` (pyproject.toml's
``package-dir``), so a user's own ``tasks`` or ``sim`` package is never shadowed."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE_OF = {"tasks": "taskflow_tasks", "robots": "taskflow_robots", "sim": "taskflow_sim", "taskflow": "taskflow"}
_PLUGINS = ("taskflow_sim", "taskflow_tasks", "taskflow_robots", "sim", "tasks", "robots")
FORBIDDEN = {
    "tasks": ("pybullet", "pybullet_data", "taskflow_sim", "sim", "taskflow.runtime", "taskflow.executor", "taskflow.cli"),
    "robots": ("pybullet", "pybullet_data", "taskflow_sim", "sim", "taskflow.runtime", "taskflow.executor", "taskflow.cli"),
    "taskflow": ("pybullet", "pybullet_data", *_PLUGINS),
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
    return out


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_forbidden_imports_in_source(package):
    bad = []
    for f in sorted((ROOT / package).rglob("*.py")):
        for line, mod in _imports(f):
            if any(mod == fb or mod.startswith(fb + ".") for fb in FORBIDDEN[package]):
                bad.append(f"{f.relative_to(ROOT)}:{line}: imports {mod}")
    assert not bad, "\n".join(bad)


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
