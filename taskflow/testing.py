"""Testing missions with pytest: a scripted backend, run helpers and assertions.

Two ways to drive a mission in a test:

* :func:`drive` — the mission's machine, exactly as loaded and validated, but its world and tasks
  replaced by a :class:`Script`: metric values as functions of simulated time and of the active
  state, events at given times, asynchronous actions that finish after a delay.  Fast; checks the
  *machine* (paths, timeouts, history, foreach, outcomes).
* :func:`run_on_world` — the mission on its real registered world (PyBullet), recording nothing
  unless asked.  Checks the *behaviour*.

Both return a :class:`~taskflow.runtime.RunResult` (``outcome``, ``summary`` — the dict of
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

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from .api import Observation, Robot, StepResult, Task, TaskContext, World
from .contracts import build_robot_params
from .data import DataAccess
from .loader import CompiledMission
from .loader import load_mission as _load
from .runtime import RunResult, run_mission


@dataclass
class ScriptState:
    """What a script's metric function sees each tick."""

    t: float
    state: str  # active leaf path
    time_in_state: float
    items: Mapping[str, Any]
    memory: dict[str, Any]  # the run's mission data, by key name


MetricFn = Callable[[ScriptState], Mapping[str, float]]


@dataclass
class Script:
    """A scripted stand-in for a world and its tasks.

    ``metrics(state)`` returns metric values each tick; ``events`` is a list of ``(time, name)``;
    ``actions`` maps an action name to ``(delay_s, event)`` (or a function of the action's params
    returning that pair) emitted after the action starts.
    """

    metrics: MetricFn = lambda s: {}
    events: Sequence[tuple[float, str]] = ()
    actions: Mapping[str, tuple[float, str] | Callable[[Mapping[str, Any]], tuple[float, str]]] = field(default_factory=dict)


class ScriptedWorld(World):
    """A :class:`World` whose observations come from a :class:`Script` (no simulator)."""

    name = "scripted"

    def __init__(self, robot: Robot, script: Script, mission: CompiledMission) -> None:
        super().__init__(robot, None, 0)  # type: ignore[arg-type]
        self.script = script
        self.mission = mission
        self.ground_truth_keys = ()  # type: ignore[misc]
        self.t = 0.0
        self._tick = 0
        self._dt = 1.0 / mission.spec.rate_hz
        self._events = sorted(script.events)
        self._next_event = 0
        self._pending: list[tuple[float, str]] = []
        self.started: list[tuple[float, str, dict[str, Any]]] = []
        self.cancelled: list[tuple[float, str]] = []
        self.applied: list[dict[str, np.ndarray]] = []
        self.executor: Any = None

    def observe(self) -> Observation:
        t = self.t
        events: list[str] = []
        while self._next_event < len(self._events) and self._events[self._next_event][0] <= t + 1e-9:
            events.append(self._events[self._next_event][1])
            self._next_event += 1
        due = [e for e in self._pending if e[0] <= t + 1e-9]
        for e in due:
            self._pending.remove(e)
            events.append(e[1])
        metrics: dict[str, float] = {}
        ex = self.executor
        if ex is not None and ex.leaf is not None:
            st = ScriptState(t, ex.state, t - ex.entered_at(ex.leaf), ex.items(ex.leaf), ex.memory)
            metrics = {k: float(v) for k, v in self.script.metrics(st).items()}
        return Observation(t=t, events=tuple(events), metrics=metrics)

    def apply(self, command: dict[str, np.ndarray]) -> None:
        self.applied.append(command)

    def advance(self, dt: float) -> None:
        self._tick += 1
        self.t = self._tick * self._dt

    def start_action(self, name: str, params: Mapping[str, Any]) -> None:
        spec = self.script.actions.get(name)
        if spec is None:
            raise KeyError(f"the script has no action {name!r}")
        delay, event = spec(params) if callable(spec) else spec
        self.started.append((self.t, name, dict(params)))
        self._pending.append((self.t + delay, event))

    def cancel_action(self, name: str) -> None:
        self.cancelled.append((self.t, name))
        self._pending.clear()


class _IdleTask(Task):
    """Stands in for every task under a script: holds the robot still, publishes nothing."""

    def __init__(self, ctx: TaskContext) -> None:
        super().__init__(ctx)
        self._stop = ctx.robot.stop_command()

    def step(self, obs: Observation) -> StepResult:
        return StepResult(self._stop)


def drive(mission: CompiledMission, script: Script, *, max_time: float | None = None,
          out_dir: str | Path | None = None,
          on_world: Callable[[ScriptedWorld], None] | None = None, control: Any = None,
          operator: Sequence[Any] | None = None) -> RunResult:
    """Run the mission's machine against ``script`` (tasks replaced; nothing rendered or simulated).

    ``on_world`` receives the :class:`ScriptedWorld` (its ``started``, ``cancelled`` and
    ``applied`` lists record what the machine asked of the hardware); ``control`` and ``operator``
    are :func:`~taskflow.runtime.run_mission`'s (operator endpoint and script, :mod:`taskflow.control`)."""
    robot = mission.build_robot()
    world = ScriptedWorld(robot, script, mission)
    if on_world is not None:
        on_world(world)

    def factory(cls: type[Task], ctx: TaskContext) -> Task:
        return _IdleTask(ctx)

    def attach(executor: Any) -> None:
        world.executor = executor

    return run_mission(mission, world=world, task_factory=factory, max_time=max_time, on_start=attach,
                       out_dir=out_dir, record=out_dir is not None, control=control, operator=operator)


def run_on_world(mission: CompiledMission, *, seed: int | None = None, max_time: float | None = None,
                 out_dir: str | Path | None = None) -> RunResult:
    """Run on the mission's registered (PyBullet) world; records only when ``out_dir`` is given."""
    return run_mission(mission, seed=seed, max_time=max_time, out_dir=out_dir, record=out_dir is not None)


# -- assertions ---------------------------------------------------------------------------------


def task_context(task: type[Task], params: Any, robot: Robot, profiles: dict[str, Any] | None = None, *,
                 t: float = 0.0, memory: dict[str, Any] | None = None, items: dict[str, Any] | None = None,
                 dt: float = 0.0) -> TaskContext:
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
    return sum(v for k, v in spent.items() if k == state or k.startswith(state + "."))


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
