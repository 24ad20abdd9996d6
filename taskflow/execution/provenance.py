"""What a run's result depends on besides its mission and seed: the versions of the packages that shape
it, and taskflow's own version and commit.  Every ``summary.json`` carries them under ``versions``.

Versions are read from the installed distributions' metadata (nothing is imported); the commit is read
once per process from the checkout taskflow runs from, when it runs from one.
"""

from __future__ import annotations

import functools
import platform
import subprocess
from importlib import metadata
from pathlib import Path

RESULT_PACKAGES = ("pybullet", "opencv-python-headless", "numpy", "scipy", "pin", "transitions", "pydantic")
"""Distributions whose version can change what a mission does (physics, vision, maths, the machine)."""


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def taskflow_commit() -> str | None:
    """``git describe``-like commit of the checkout taskflow is imported from (``+dirty`` when it has
    uncommitted changes), or None for an installed wheel."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                              text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


@functools.lru_cache(maxsize=1)
def versions() -> dict[str, str | None]:
    """``{"python": …, "taskflow": …, "taskflow_commit": …, "pybullet": …, …}``."""
    out: dict[str, str | None] = {"python": platform.python_version(), "taskflow": _version("taskflow"),
                                  "taskflow_commit": taskflow_commit()}
    for dist in RESULT_PACKAGES:
        out[dist] = _version(dist)
    return out
