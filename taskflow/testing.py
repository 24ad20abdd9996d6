"""Testing missions with pytest: a scripted backend, run helpers and assertions.

Two ways to drive a mission in a test:

* :func:`drive` — the mission's machine, exactly as loaded and validated, but its world and tasks
  replaced by a :class:`Script`: metric values as functions of simulated time and of the active
  state, events at given times, asynchronous actions that finish after a delay.  Fast; checks the
  *machine* (paths, timeouts, history, foreach, outcomes).
* :func:`run_on_world` — the mission on its real registered world (PyBullet), recording nothing
  unless asked.  Checks the *behaviour*.

Both return a :class:`~taskflow.execution.summary.RunResult` (``outcome``, ``summary`` — the dict of
``summary.json``, recorded or not —, ``run_dir``, ``executor``, ``timing``; its docstring lists the
summary's keys); assert on it with :func:`assert_path`, :func:`assert_outcome` and :func:`time_in` ::

    from taskflow.testing import Script, drive, assert_path

    def test_lost_marker_resumes(mission):
        script = Script(metrics=lambda s: {"pos_error": 0.0 if s.time_in_state > 1 else 1.0},
                        events=[(3.0, "target_lost"), (4.0, "target_found")])
        result = drive(mission, script, max_time=60)
        assert_path(result, ["operate.approach", "searching", "operate.approach", ...])

The pytest plugin (registered as ``taskflow`` in the ``pytest11`` entry point) provides the
``load_mission`` fixture: ``load_mission("missions/x.yaml", overrides=[...])``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pytest

from taskflow.api import Robot, Task, TaskContext
from taskflow.execution.runtime import run_mission
from taskflow.execution.scripted import MetricFn, Script, ScriptedWorld, ScriptState, drive
from taskflow.execution.summary import RunResult
from taskflow.mission.contracts import build_robot_params
from taskflow.mission.data import DataAccess
from taskflow.mission.loader import load_mission as _load
from taskflow.mission.model import CompiledMission

__all__ = ["MetricFn", "Script", "ScriptState", "ScriptedWorld", "assert_outcome", "assert_path", "browser_paths", "drive",
           "headless_chromium", "load_mission", "run_on_world", "task_context", "time_in"]


def run_on_world(mission: CompiledMission, *, seed: int | None = None, max_time: float | None = None,
                 out_dir: str | Path | None = None) -> RunResult:
    """Run on the mission's registered (PyBullet) world; records only when ``out_dir`` is given."""
    return run_mission(mission, seed=seed, max_time=max_time, out_dir=out_dir, record=out_dir is not None)


# -- assertions ---------------------------------------------------------------------------------


def task_context(task: type[Task[Any, Any]], params: Any, robot: Robot, profiles: dict[str, Any] | None = None, *,
                 t: float = 0.0, memory: dict[str, Any] | None = None, items: dict[str, Any] | None = None,
                 dt: float = 0.0) -> TaskContext[Any, Any]:
    """The context the executor would give ``task`` on entry — for unit tests of one task outside a
    mission: ``robot_params`` is built from the robot's parameters as the framework builds it, and
    ``memory`` (the run's mission data: a plain dict the test may read and fill) is reached through the
    task's declared view, as in a run (an undeclared key is refused); a slot given no profile holds its
    model's defaults when it has them, as the loader binds it."""
    return TaskContext(t=t, params=params, profiles=task.default_profiles(profiles),
                       memory=DataAccess({} if memory is None else memory, task),
                       robot=robot, items=items or {}, dt=dt, robot_params=build_robot_params(task, robot))


def assert_path(result: RunResult, expected: Sequence[str], *, exact: bool = True) -> None:
    """The leaf states visited, in order.  ``exact=False``: ``expected`` is a subsequence."""
    got = list(result.summary["states_visited"])
    if exact:
        if got != list(expected):
            raise AssertionError(_path_diff(got, list(expected)))
        return
    it = iter(got)
    missing = [s for s in expected if not any(s == g for g in it)]
    if missing:
        raise AssertionError(f"states {missing} not visited in that order; path was:\n  " + "\n  ".join(got))


def _path_diff(got: list[str], expected: list[str]) -> str:
    for i, (g, e) in enumerate(zip(got, expected)):
        if g != e:
            return (f"path differs at step {i}: got {g!r}, expected {e!r}\n got: {got}\n expected: {expected}")
    return f"path length {len(got)} != {len(expected)}\n got: {got}\n expected: {expected}"


def assert_outcome(result: RunResult, outcome: str) -> None:
    """``result.outcome`` is ``outcome``; otherwise fail with the run's ``reason``."""
    if result.outcome != outcome:
        raise AssertionError(f"outcome {result.outcome!r} ({result.summary.get('reason')}), expected {outcome!r}")


def time_in(result: RunResult, state: str) -> float:
    """Total simulated seconds spent in leaf ``state`` (or in every leaf under a composite)."""
    spent = result.summary["time_in_state_s"]
    return float(sum(v for k, v in spent.items() if k == state or k.startswith(state + ".")))


# -- pytest plugin --------------------------------------------------------------------------------


@pytest.fixture
def load_mission() -> Callable[..., CompiledMission]:
    """``load_mission(path, overrides=None)`` → a validated :class:`CompiledMission`."""

    def _loader(path: str | Path, overrides: list[str] | None = None) -> CompiledMission:
        return _load(path, overrides)

    return _loader


# -- a real browser for page tests ----------------------------------------------------------------


def _on_path(*names: str) -> str | None:
    import shutil

    for n in names:
        found = shutil.which(n) or (f"/usr/bin/{n}" if Path(f"/usr/bin/{n}").is_file() else None)
        if found:
            return found
    return None


def browser_paths() -> tuple[str | None, str | None]:
    """The distribution's Chromium and chromedriver (None where missing)."""
    return _on_path("chromium", "chromium-browser", "google-chrome"), _on_path("chromedriver")


def headless_chromium(window: tuple[int, int] = (1400, 1000)) -> Any:
    """A headless Chromium driven by selenium (a test dependency), for tests, benchmarks and screenshots of
    the web view; the caller quits it.  Raises RuntimeError naming what is missing."""
    chromium, driver = browser_paths()
    if chromium is None or driver is None:
        raise RuntimeError("a headless browser needs the distribution's chromium and chromedriver "
                           "(apt-get install chromium chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                f"--window-size={window[0]},{window[1]}"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(driver), options=opts)
