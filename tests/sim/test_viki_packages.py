"""The ViKi-HyCo paper's packages keep the layer rule their ``__init__`` states (read from the source's AST)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: what a paper package may never import: the other papers' packages (and, for control laws, the simulator)
FORBIDDEN = {
    "sim/viki": ("taskflow_sim.screw", "taskflow_sim.quad", "taskflow_tasks"),
    "tasks/viki": ("taskflow_tasks.screw", "taskflow_tasks.quad", "taskflow_sim", "pybullet"),
}


def _imports(path: Path) -> list[str]:
    out: list[str] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append(node.module)
    return out


@pytest.mark.parametrize("folder", sorted(FORBIDDEN))
def test_a_viki_package_imports_no_other_paper_and_keeps_its_layer(folder):
    files = sorted((ROOT / folder).glob("*.py"))
    assert files and (ROOT / folder / "__init__.py").read_text(encoding="utf-8").startswith('"""')
    bad = [(f.name, m) for f in files for m in _imports(f)
           if any(m == x or m.startswith(x + ".") for x in FORBIDDEN[folder])]
    assert bad == []
