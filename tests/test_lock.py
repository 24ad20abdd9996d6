"""The environment is the one the suite was verified with: every package pinned in requirements.lock is
installed at exactly that version, and every dependency taskflow declares is pinned.

``.ci/run-latest`` deliberately installs the newest releases instead; it sets ``TASKFLOW_UNLOCKED=1``,
the only case in which the version comparison does not apply.
"""

from __future__ import annotations

import os
import re
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _canon(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _lock() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            name, sep, version = line.partition("==")
            assert sep, f"requirements.lock: {line!r} is not NAME==VERSION"
            pins[_canon(name)] = version
    return pins


def test_every_declared_dependency_is_pinned() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    declared = list(project["dependencies"]) + [d for deps in project["optional-dependencies"].values() for d in deps]
    names = {_canon(re.split(r"[<>=!~\[; ]", d, maxsplit=1)[0]) for d in declared}
    missing = names - set(_lock())
    assert not missing, f"declared but not pinned in requirements.lock: {sorted(missing)}"


def test_installed_versions_match_the_lock() -> None:
    if os.environ.get("TASKFLOW_UNLOCKED") == "1":
        pytest.skip("TASKFLOW_UNLOCKED=1: .ci/run-latest tests the newest releases on purpose")
    wrong = {}
    for name, version in _lock().items():
        try:
            have = metadata.version(name)
        except metadata.PackageNotFoundError:
            have = None
        if have != version:
            wrong[name] = (version, have)
    assert not wrong, ("installed versions differ from requirements.lock (pinned, installed): "
                       f"{wrong} — install with the README's command (pip install -c requirements.lock ...)")
