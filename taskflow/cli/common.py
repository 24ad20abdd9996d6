"""What the verbs of the command line share: the usage error, the flags' checks (``--max-time``,
``--frames``, ``--seed``, counts), loading a mission, the default mission."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

from taskflow.errors import MissionError

if TYPE_CHECKING:  # the verbs import the machinery when they run (a bad flag answers before it loads)
    from taskflow.mission.model import CompiledMission


def default_mission() -> Path:
    """The shipped default mission (package ``taskflow_missions``, the repository's ``missions/``),
    wherever taskflow is installed: a checkout or a wheel."""
    import taskflow_missions

    return taskflow_missions.DEFAULT


def print_problems(exc: MissionError) -> None:
    for p in exc.problems:
        print(str(p), file=sys.stderr)


class UsageError(Exception):
    """A command-line value that cannot be used: one line on stderr, exit 1."""


def max_time_flag(text: str | None) -> float | None:
    """``--max-time 30``, ``"30 s"`` or ``"2 min"``: the same rule as ``max_time`` in a file."""
    if text is None:
        return None
    from taskflow.units import UnitError, parse_max_time

    try:
        return parse_max_time(number_or_text(text))
    except UnitError as exc:
        raise UsageError(f"--max-time {text!r}: {exc}") from None


def frames_hz_flag(text: str) -> float:
    """``--frames HZ``: frames per simulated second, 0 for none."""
    import math

    try:
        hz = float(text)
    except ValueError:
        hz = math.nan
    if not (math.isfinite(hz) and hz >= 0):
        raise UsageError(f"--frames {text!r}: frames per simulated second — valid: a number >= 0 (0: record none)")
    return hz


def number_or_text(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text


def positive_flag(flag: str, value: int | None) -> int | None:
    if value is not None and value < 1:
        raise UsageError(f"{flag} {value}: must be at least 1")
    return value


def seed_flag(flag: str, value: int | None, count: int = 1) -> int | None:
    """``--seed`` as a mission's ``seed:`` takes it (0 to 2**63 - 1), with room for ``count`` seeds from it."""
    from taskflow.mission.schema import SEED_MAX

    if value is not None and not 0 <= value <= SEED_MAX - (count - 1):
        top = f"{SEED_MAX - (count - 1)} (trial i of {count} runs seed + i)" if count > 1 else f"{SEED_MAX}"
        raise UsageError(f"{flag} {value}: a seed is a whole number from 0 to {top}")
    return value


def load(path: str, overrides: list[str] | None = None) -> CompiledMission:
    from taskflow.mission.loader import load_mission

    return load_mission(path, overrides)


def check_display(gui: bool) -> None:
    """``--gui`` opens an X11 window on Linux: without a display PyBullet dies in C, after the run started."""
    import os

    if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise UsageError("--gui: no display (DISPLAY is not set) — run without --gui (headless), or under a "
                         "display (xvfb-run taskflow run --gui …)")


def signal_exit_code(signum: int) -> int:
    """The exit status of a command a signal stopped after it wrote its record: the shell's ``128 + signum``
    (130 for Ctrl-C, 143 for SIGTERM), for ``run`` and ``batch`` alike."""
    return 128 + int(signum)


def user_name() -> str:
    import getpass

    try:
        return getpass.getuser()
    except Exception:
        return "operator"
