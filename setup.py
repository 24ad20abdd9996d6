"""Which packages and files the wheel holds, found by walking the source folders (never a hand list).

Every folder under ``taskflow/``, ``tasks/``, ``robots/``, ``sim/`` and ``missions/`` (``__pycache__``
aside) is a package of the wheel, and every file in it travels: Python modules, the web view's page,
the shipped missions and their ``lib/`` sub-missions, any data file a new folder brings. The four
repository folders install under prefixed names so that they never capture a user's own ``tasks`` or
``sim`` package (docs/design.md, "Packaging"). The project's metadata is in ``pyproject.toml``;
``tests/test_packaging.py`` checks that the wheel holds every file of these folders.
"""

from __future__ import annotations

from pathlib import Path

from setuptools import setup

ROOT = Path(__file__).resolve().parent
#: installed package name → the repository folder it is built from
PACKAGE_DIRS: dict[str, str] = {
    "taskflow": "taskflow",
    "taskflow_tasks": "tasks",
    "taskflow_robots": "robots",
    "taskflow_sim": "sim",
    "taskflow_missions": "missions",
}

def _skipped(name: str) -> bool:
    """Build caches and hidden files (``__pycache__``, ``.mypy_cache``, an editor's ``.swp``) never travel."""
    return name == "__pycache__" or name.startswith(".") or name.endswith(".pyc")


def _folders(folder: Path) -> list[Path]:
    """``folder`` and every folder below it, skipped ones (and what is under them) aside."""
    return [folder] + sorted(p for p in folder.rglob("*")
                             if p.is_dir() and not any(_skipped(n) for n in p.relative_to(folder).parts))


def discover() -> tuple[list[str], dict[str, str], dict[str, list[str]]]:
    """The wheel's packages, their source folders and, per package, its files that are not modules."""
    packages: list[str] = []
    package_dir: dict[str, str] = {}
    package_data: dict[str, list[str]] = {}
    for name, source in PACKAGE_DIRS.items():
        for folder in _folders(ROOT / source):
            rel = folder.relative_to(ROOT / source)
            package = ".".join((name, *rel.parts))
            packages.append(package)
            package_dir[package] = (Path(source) / rel).as_posix()
            data = sorted(p.name for p in folder.iterdir()
                          if p.is_file() and p.suffix != ".py" and not _skipped(p.name))
            if data:
                package_data[package] = data
    return packages, package_dir, package_data


PACKAGES, PACKAGE_DIR, PACKAGE_DATA = discover()
setup(packages=PACKAGES, package_dir=PACKAGE_DIR, package_data=PACKAGE_DATA)
