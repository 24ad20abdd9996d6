"""What users install: the built wheel, in a fresh virtual environment, never the checkout.

The wheel is built from the checkout, checked to hold every file of the source folders (so a new
subpackage or data file can never be left out again), installed with a real ``pip install -c
requirements.lock`` into a new virtual environment, and driven through its ``taskflow`` script from a
scratch directory with the checkout off the path: ``validate``, ``run`` (the default mission),
``graph`` (Mermaid and dot), ``plot``, ``export``, ``describe`` and a two-trial ``batch``. pip's cache
makes the install quick (``--no-compile``: modules are compiled as they are imported; ~50 s on a
loaded 2-core machine, 1.7 GB written); the module takes about 90 s.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: installed package name → the repository folder it is built from (as setup.py maps them)
SOURCES = {"taskflow": "taskflow", "taskflow_tasks": "tasks", "taskflow_robots": "robots",
           "taskflow_sim": "sim", "taskflow_missions": "missions"}
#: what a development checkout holds besides its sources (environments, caches, earlier builds, runs)
BUILD_LEFTOVERS = (".git", ".venv*", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
                   ".hypothesis", "runs")
COMMON_NAMES = {"tasks", "sim", "robots", "missions", "tests", "benchmarks"}


def _clean_env() -> dict[str, str]:
    """The environment of a user's shell: no PYTHONPATH, no development virtual environment."""
    return {k: v for k, v in os.environ.items() if k not in {"PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME"}}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel built from a copy of the checkout (an in-tree build would reuse a stale ``build/``)."""
    out = tmp_path_factory.mktemp("wheel")
    tree = out / "src"
    shutil.copytree(ROOT, tree, ignore=shutil.ignore_patterns(*BUILD_LEFTOVERS))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(tree), "--no-deps", "-q", "-w", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = out.glob("taskflow-*.whl")
    return whl


@pytest.fixture(scope="module")
def venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtual environment with the wheel installed by pip (its dependencies pinned by the lock)."""
    env_dir = tmp_path_factory.mktemp("fresh") / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(env_dir)], check=True, env=_clean_env())
    start = time.perf_counter()
    r = subprocess.run([str(env_dir / "bin" / "python"), "-m", "pip", "install", "-q", "--no-compile",
                        "-c", str(ROOT / "requirements.lock"), str(wheel)],
                       capture_output=True, text=True, env=_clean_env(), cwd=env_dir.parent)
    assert r.returncode == 0, r.stdout + r.stderr
    print(f"pip install of the wheel into a fresh venv: {time.perf_counter() - start:.1f} s")
    return env_dir


def _source_files() -> set[str]:
    """Every file of the source folders as the wheel names it (build caches and hidden files aside)."""
    out = set()
    for package, folder in SOURCES.items():
        for p in (ROOT / folder).rglob("*"):
            rel = p.relative_to(ROOT / folder)
            if p.is_file() and not any(n == "__pycache__" or n.startswith(".") or n.endswith(".pyc")
                                       for n in rel.parts):
                out.add(f"{package}/{rel.as_posix()}")
    return out


def test_the_wheel_holds_every_file_of_the_source_folders(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    files = _source_files()
    assert "taskflow/mission/compile/__init__.py" in files and "taskflow_missions/lib/screw_operation.yaml" in files
    assert {n for n in files if n.endswith(".py")} - names == set()  # every module, of every subpackage
    assert files - names == set()  # and every data file: web page, missions, lib/ sub-missions


def test_the_wheel_installs_no_common_top_level_name(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert top == set(SOURCES)
    assert not top & COMMON_NAMES


def _taskflow(venv: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    r = subprocess.run([str(venv / "bin" / "taskflow"), *args], cwd=cwd, capture_output=True, text=True,
                       env=_clean_env(), timeout=120)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def test_a_user_drives_the_installed_wheel_from_a_scratch_directory(venv: Path, tmp_path: Path) -> None:
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    site = subprocess.run([str(venv / "bin" / "python"), "-c",
                           "import taskflow, taskflow_missions, pathlib;"
                           "print(pathlib.Path(taskflow.__file__).parent);"
                           "print(pathlib.Path(taskflow_missions.__file__).parent)"],
                          cwd=scratch, capture_output=True, text=True, env=_clean_env(), check=True).stdout.split()
    assert all(Path(p).is_relative_to(venv) for p in site), site  # the fresh environment's copy, not the checkout
    mission = Path(site[1]) / "car_waypoints.yaml"

    r = _taskflow(venv, scratch, "validate", str(mission))
    assert r.returncode == 0 and "ok (car_waypoints" in r.stdout, r.stdout + r.stderr

    r = _taskflow(venv, scratch, "run", "--out", "run", "--quiet", "--seed", "3")
    assert r.returncode == 0, r.stdout + r.stderr
    summary = json.loads((scratch / "run" / "summary.json").read_text())
    assert summary["outcome"] == "succeeded"
    assert Path(summary["file"]).is_relative_to(venv)  # the default mission is the wheel's own

    r = _taskflow(venv, scratch, "verify", str(mission), "--json")  # Storm, from the wheel stormpy installs
    assert r.returncode == 0 and json.loads(r.stdout)["ok"] is True, r.stdout + r.stderr

    r = _taskflow(venv, scratch, "graph", str(mission))
    assert r.returncode == 0 and r.stdout.startswith("stateDiagram-v2"), r.stdout + r.stderr
    r = _taskflow(venv, scratch, "graph", "--format", "dot", str(mission))
    assert r.returncode == 0 and r.stdout.startswith("digraph"), r.stdout + r.stderr
    dot = shutil.which("dot")
    assert dot, "Graphviz `dot` is needed (apt-get install graphviz)"
    svg = subprocess.run([dot, "-Tsvg"], input=r.stdout, capture_output=True, text=True)
    assert svg.returncode == 0 and "<svg" in svg.stdout, svg.stderr

    r = _taskflow(venv, scratch, "plot", "run")
    assert r.returncode == 0, r.stdout + r.stderr
    pngs = sorted((scratch / "run").glob("*.png"))
    assert pngs and all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)

    r = _taskflow(venv, scratch, "export", "run")
    assert r.returncode == 0, r.stdout + r.stderr
    assert (scratch / "run" / "telemetry.mcap").read_bytes()[:8] == b"\x89MCAP0\r\n"

    r = _taskflow(venv, scratch, "describe", "racecar")
    assert r.returncode == 0 and "taskflow_robots.racecar:Racecar" in r.stdout, r.stdout + r.stderr

    r = _taskflow(venv, scratch, "batch", "--trials", "2", "--workers", "2", "--out", "batch", str(mission))
    assert r.returncode == 0, r.stdout + r.stderr
    batch = json.loads((scratch / "batch" / "batch.json").read_text())
    assert [t["outcome"] for t in batch["trials"]] == ["succeeded", "succeeded"]
    assert batch["aggregate"]["trials"] == 2 and batch["aggregate"]["success_rate"] == 1.0


def test_the_installed_wheel_serves_the_language_server(venv: Path, tmp_path: Path) -> None:
    """``taskflow lsp`` of the installed wheel, driven over stdio by the tests' LSP client: a shipped mission with
    its sub-mission (both in the wheel) has no diagnostics, a typo gets one at its line, completion offers the
    registered tasks the wheel's entry points declare."""
    import asyncio

    from lsprotocol import types
    from pytest_lsp import client_capabilities, make_test_lsp_client

    site = subprocess.run([str(venv / "bin" / "python"), "-c", "import taskflow_missions, pathlib;"
                           "print(pathlib.Path(taskflow_missions.__file__).parent)"],
                          cwd=tmp_path, capture_output=True, text=True, env=_clean_env(), check=True).stdout.strip()
    mission = Path(site) / "screw_fastening.yaml"
    text = mission.read_text()
    uri = mission.as_uri()

    async def session() -> tuple[list[types.Diagnostic], list[types.Diagnostic], list[str]]:
        client = make_test_lsp_client()
        await client.start_io(str(venv / "bin" / "taskflow"), "lsp", env=_clean_env(), cwd=str(tmp_path))
        await client.initialize_session(types.InitializeParams(capabilities=client_capabilities("neovim")))
        client.text_document_did_open(types.DidOpenTextDocumentParams(text_document=types.TextDocumentItem(
            uri=uri, language_id="yaml", version=1, text=text)))
        while uri not in client.diagnostics:
            await asyncio.sleep(0.01)
        clean = list(client.diagnostics.pop(uri))
        bad = text.replace("task: {name: arm_home", "task: {name: arm_hom", 1)
        client.text_document_did_change(types.DidChangeTextDocumentParams(
            text_document=types.VersionedTextDocumentIdentifier(uri=uri, version=2),
            content_changes=[types.TextDocumentContentChangeWholeDocument(text=bad)]))
        while uri not in client.diagnostics:
            await asyncio.sleep(0.01)
        typo = list(client.diagnostics[uri])
        at = bad.index("arm_hom") + len("arm_hom")
        position = types.Position(line=bad.count("\n", 0, at), character=at - (bad.rfind("\n", 0, at) + 1))
        result = await client.text_document_completion_async(types.CompletionParams(
            text_document=types.TextDocumentIdentifier(uri=uri), position=position))
        items = result.items if isinstance(result, types.CompletionList) else list(result or [])
        await client.shutdown_session()
        await client.stop()
        return clean, typo, [i.label for i in items]

    clean, typo, labels = asyncio.run(asyncio.wait_for(session(), 120))
    assert clean == []
    assert len(typo) == 1 and "unknown task 'arm_hom'" in typo[0].message
    assert typo[0].range.start.line == text[:text.index("name: arm_home")].count("\n")
    assert "arm_home" in labels and "pbvs_arm" in labels


def test_the_installed_wheel_runs_beside_a_users_own_tasks_and_sim(venv: Path, tmp_path: Path) -> None:
    project = tmp_path / "user_project"  # a user's project with packages of the names we must not capture
    for name in ("tasks", "sim", "robots"):
        (project / name).mkdir(parents=True)
        (project / name / "__init__.py").write_text(f"MINE = {name!r}\n")
    code = (
        "import sys, pathlib\n"
        "import taskflow, tasks, sim\n"
        "assert tasks.MINE == 'tasks' and sim.MINE == 'sim'\n"
        "import taskflow_missions\n"
        "from taskflow.mission.loader import load_mission\n"  # a shipped mission that uses a sub-mission of missions/lib
        "load_mission(pathlib.Path(taskflow_missions.__file__).parent / 'screw_fastening.yaml')\n"
        "from taskflow.cli import main\n"
        "sys.exit(main(['run', '--max-time', '0.5', '--out', 'run', '--quiet']))\n"
    )
    r = subprocess.run([str(venv / "bin" / "python"), "-c", code], cwd=project, capture_output=True, text=True,
                       env=_clean_env())
    # 0.5 s is too short for the waypoints: the run times out (exit 1) but it ran, from the wheel's mission
    assert "Traceback" not in r.stderr, r.stderr
    assert "outcome: timeout" in r.stdout, r.stdout + r.stderr
