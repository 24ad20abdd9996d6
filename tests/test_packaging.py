"""The built wheel, not the checkout: shipped missions are inside it, and it installs no top-level
package with a common name (``tasks``, ``sim``, ``robots``, ``missions``) that would capture a user's own.

The wheel is unpacked into a folder that goes first on ``sys.path``, so the run below imports taskflow
from the wheel's files while the third-party dependencies come from the test environment.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
COMMON_NAMES = {"tasks", "sim", "robots", "missions", "tests", "benchmarks"}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = out.glob("taskflow-*.whl")
    return whl


def test_wheel_holds_the_missions_and_no_common_top_level_name(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert top == {"taskflow", "taskflow_tasks", "taskflow_robots", "taskflow_sim", "taskflow_missions"}
    assert not top & COMMON_NAMES
    shipped = {p.relative_to(ROOT / "missions").as_posix() for p in (ROOT / "missions").rglob("*.yaml")}
    assert "lib/screw_operation.yaml" in shipped  # the sub-missions the shipped missions use travel with them
    assert shipped and {f"taskflow_missions/{n}" for n in shipped} <= set(names)
    page = {f"taskflow/web/{p.name}" for p in (ROOT / "taskflow" / "web").iterdir()}  # the web view's page
    assert page and page <= set(names)


def test_the_wheel_runs_its_default_mission_beside_a_users_own_tasks_and_sim(wheel: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    project = tmp_path / "user_project"  # a user's project with packages of the names we must not capture
    for name in ("tasks", "sim", "robots"):
        (project / name).mkdir(parents=True)
        (project / name / "__init__.py").write_text(f"MINE = {name!r}\n")
    code = (
        "import sys\n"
        f"sys.path[:0] = [{str(project)!r}, {str(site)!r}]\n"
        "import taskflow, tasks\n"
        f"assert taskflow.__file__.startswith({str(site)!r}), taskflow.__file__\n"
        "assert tasks.MINE == 'tasks'\n"
        "import pathlib, taskflow_missions\n"
        "from taskflow.loader import load_mission\n"  # a shipped mission that uses a sub-mission of missions/lib
        "load_mission(pathlib.Path(taskflow_missions.__file__).parent / 'screw_fastening.yaml')\n"
        "from taskflow.cli import main\n"
        "sys.exit(main(['run', '--max-time', '0.5', '--out', 'run', '--quiet']))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    r = subprocess.run([sys.executable, "-c", code], cwd=project, capture_output=True, text=True, env=env)
    # 0.5 s is too short for the waypoints: the run times out (exit 1) but it ran, from the wheel's mission
    assert "Traceback" not in r.stderr, r.stderr
    assert "outcome: timeout" in r.stdout, r.stdout + r.stderr
    assert "taskflow_missions" in (project / "run" / "summary.json").read_text()
