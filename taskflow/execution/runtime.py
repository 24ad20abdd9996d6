"""The control loop: world → task → world, on the simulation clock, with a run record.

One tick at the mission's ``rate_hz``::

    obs = world.observe()                 # sensors at their own rates inside the world
    command, metrics, events = executor.tick(obs)   # task step, blend, guards, maybe a transition
    world.apply(command)
    recorder.tick(...)                    # state path, metrics, command, ground truth
    world.advance(1 / rate_hz)            # whole physics steps

A run ends at a final state, at ``max_time`` (outcome ``timeout``), on an exception (``aborted``,
with the error in ``summary.json`` and ``error.txt``) or on Ctrl-C / SIGTERM (``aborted``,
``interrupted``).  Whatever the outcome, the robot is then commanded to a safe stop, so a finished
mission leaves it at rest.

Nothing here reads the wall clock into the run's behaviour: ``trace.csv``, ``transitions.jsonl`` and
``summary.json`` depend only on the mission and the seed.  Wall-clock figures — the loop's real-time
factor and the timings tasks and worlds report (``StepResult.timings``, ``Observation.timings``) — go
to ``timing.json`` only.
"""

from __future__ import annotations

import signal
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from taskflow.api import World
from taskflow.execution.executor import Executor, TaskFactory
from taskflow.execution.frames import DEFAULT_HZ, FrameRecorder
from taskflow.execution.monitors import monitor_for
from taskflow.execution.provenance import versions
from taskflow.execution.records import RunRecorder, TimingRecord, TransitionRecord
from taskflow.execution.summary import RunResult, build_summary, recorded_file
from taskflow.mission.model import CompiledMission
from taskflow.units import parse_max_time

if TYPE_CHECKING:
    from taskflow.execution.control import ControlEndpoint, OperatorAction, OperatorChannel

@dataclass
class Progress:
    """Called about twice a wall-clock second with the active state, sim time and real-time factor."""

    callback: Callable[[str, float, float], None]
    period_s: float = 0.5


class _Terminated(BaseException):
    pass


INTERRUPTED = "interrupted (Ctrl-C)"
TERMINATED = "terminated (SIGTERM)"


class _StopRequest:
    """Signal handler for the run loop: the first Ctrl-C or SIGTERM asks the run to stop at the next tick
    boundary (so the record ends on a whole tick, and the safe stop starts from the clock the summary
    gives); a second one stops at once."""

    def __init__(self) -> None:
        self.reason: str | None = None

    def __call__(self, signum: int, frame: Any) -> None:
        if self.reason is not None:
            raise KeyboardInterrupt() if signum == signal.SIGINT else _Terminated()
        self.reason = INTERRUPTED if signum == signal.SIGINT else TERMINATED

    def install(self) -> list[tuple[int, Any]]:
        """Handle SIGTERM, and SIGINT unless it is ignored (batch workers leave Ctrl-C to their parent);
        returns the handlers to restore.  Off the main thread nothing is installed."""
        old: list[tuple[int, Any]] = []
        try:
            for sig in (signal.SIGTERM, signal.SIGINT):
                current = signal.getsignal(sig)
                if sig == signal.SIGINT and current is signal.SIG_IGN:
                    continue
                old.append((sig, signal.signal(sig, self)))
        except ValueError:  # not the main thread
            pass
        return old


def default_run_dir(mission: CompiledMission, seed: int, root: str | Path = "runs") -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{mission.name}-seed{seed}-{stamp}"
    out, k = base, 1
    while out.exists():
        k += 1
        out = Path(f"{base}-{k}")
    return out


def run_mission(mission: CompiledMission, *, seed: int | None = None, out_dir: str | Path | None = None,
                gui: bool = False, max_time: float | None = None, progress: Progress | None = None,
                world: World | None = None, task_factory: TaskFactory | None = None,
                record: bool = True, on_start: Callable[[Executor], None] | None = None,
                safe_stop_s: float = 1.0, control: ControlEndpoint | None = None,
                operator: Sequence[OperatorAction | dict[str, Any]] | None = None,
                frames_hz: float | None = DEFAULT_HZ) -> RunResult:
    """Run ``mission`` to its end and return the outcome and summary.

    Whatever the outcome, the world is then told to stop the robot every tick for ``safe_stop_s``
    simulated seconds (recorded in the trace with the event ``safe_stop``; ``sim_time_s`` in the
    summary stays the time the outcome was decided, ``stopped_at_s`` is when the stop ended).
    ``max_time`` overrides the mission's (seconds, or a string with a unit).

    ``out_dir=None`` with ``record=True`` writes under ``runs/``; ``record=False`` writes nothing
    (tests and batches that only need the summary).  ``world`` replaces the registered world (the
    scripted backend of :mod:`taskflow.testing` uses it).

    ``control`` is the operator endpoint to serve the run from (a
    :class:`~taskflow.execution.control.ControlEndpoint`: :class:`taskflow.operate.control_http.ControlServer`,
    bound by the caller, e.g. ``ControlServer("127.0.0.1:0")``); ``operator`` is an operator script (a list of
    :class:`~taskflow.execution.control.OperatorAction` or their mappings) applied at its sim times.  A bad script, an
    unknown state or event in it, raises :class:`~taskflow.execution.control.ControlError` before the run starts.

    ``frames_hz`` is the rate (frames per simulated second) at which the camera images the world puts in
    its observations are recorded into the run directory (:mod:`taskflow.execution.frames`); 0 or None records none.
    """
    seed = mission.spec.seed if seed is None else int(seed)
    max_time = float(mission.spec.max_time) if max_time is None else parse_max_time(max_time)
    channel, server = _operator(mission, control, operator)
    robot = mission.build_robot()
    dt = 1.0 / float(mission.spec.rate_hz)  # a number once validated (schema.Rate)
    recorder: RunRecorder | None = None
    if record:
        run_dir = Path(out_dir) if out_dir is not None else default_run_dir(mission, seed)
        gt_keys = world.ground_truth_keys if world is not None else mission.world_cls.ground_truth_keys
        recorder = RunRecorder(run_dir, sorted(mission.metric_units), robot.command_keys, gt_keys)
    frames = FrameRecorder(recorder.dir, frames_hz) if recorder is not None and frames_hz else None
    summary: dict[str, Any] = {"mission": mission.name, "file": recorded_file(mission.file), "seed": seed,
                               "outcome": "aborted",
                               "reason": "run did not finish", "versions": versions()}
    resolved = dict(mission.raw)
    resolved["seed"] = seed
    try:
        world_params = mission.world_params(seed)
        if isinstance(resolved.get("world"), dict):
            resolved["world"] = {**resolved["world"], "params": world_params.model_dump(mode="json")}
        if world is None:
            world = mission.world_cls(robot, world_params, seed, gui)
    except Exception as exc:
        summary.update(reason=f"the world could not be built: {type(exc).__name__}: {exc}", final_state="",
                       states_visited=[], sim_time_s=0.0, ticks=0, time_in_state_s={}, iterations=[], items={},
                       transitions=0, metrics={}, stopped_at_s=0.0)
        if recorder is not None:
            recorder.write_mission(resolved, seed)
            (recorder.dir / "error.txt").write_text(traceback.format_exc())
            recorder.summary(summary)
            recorder.close()
        if server is not None:
            server.stop()
        return RunResult("aborted", summary, recorder.dir if recorder else None, None, {})
    if recorder is not None:
        recorder.write_mission(resolved, seed)

    def on_transition(rec: TransitionRecord) -> None:
        if recorder is not None:
            recorder.transition(rec.as_dict())

    executor = Executor(mission, world, robot, task_factory=task_factory, on_transition=on_transition)
    monitor = monitor_for(mission.properties, mission.states, recorder.transition if recorder is not None else None)
    if channel is not None:
        channel.on_record = recorder.transition if recorder is not None else None
        channel.on_wait = recorder.flush if recorder is not None else None
        channel.executor = executor
        if server is not None:
            server.start(channel, recorder.dir if recorder is not None else None)
    if on_start is not None:
        on_start(executor)
    if recorder is not None:
        recorder.summary(summary)
    timing = TimingRecord()
    wall0 = time.perf_counter()
    last_report = wall0
    t = 0.0
    metrics: dict[str, float] = {}
    outcome = "aborted"
    reason = ""
    k = 0
    t_end = 0.0
    selected: tuple[str, ...] | None = None  # the sensors last handed to world.select_sensors
    stop = _StopRequest()
    old_handlers = stop.install()
    try:
        world.reset()
        executor.start(0.0)  # a world's clock starts at 0 on reset; the machine is entered first, so the
        obs = world.observe()  # first observation (and its events) is seen by the first tick
        while True:
            t = obs.t
            if stop.reason is not None:
                break
            if executor.outcome is not None:
                break
            if t >= max_time - 1e-9:
                executor.outcome, executor.reason = "timeout", f"max_time {max_time:g} s reached"
                break
            if channel is not None:  # operator actions, at this tick boundary only (taskflow/execution/control.py)
                obs = channel.begin_tick(k, obs, executor, lambda: stop.reason is not None)
                if stop.reason is not None or executor.outcome is not None:
                    break
                if channel.held:
                    world.safe_stop()
                    if recorder is not None:
                        recorder.tick(t, executor.state, ("hold", *obs.events), {}, robot.stop_command(),
                                      world.ground_truth())
                    k += 1
                    world.advance(dt)
                    obs = world.observe()
                    executor.hold_for(obs.t - t)  # held time does not count toward `after` and `for`
                    continue
            leaf = executor.state
            command, metrics, events = executor.tick(obs)
            if monitor is not None:  # the declared properties, on the configuration this tick ran in
                monitor.tick(t, leaf, metrics, events, executor.memory)
            sensors = executor.step_sensors
            if sensors is not None and sensors != selected:  # the world hears of a change only
                world.select_sensors(sensors)
                selected = sensors
            world.apply(command)
            if frames is not None:
                frames.offer(t, k, obs.sensors)
            if recorder is not None:
                recorder.tick(t, leaf, events, metrics, command, world.ground_truth())
            k += 1
            timing.add("world", obs.timings)
            timing.add("task", executor.step_timings)
            now = time.perf_counter()
            timing.tick(now)
            if progress is not None and now - last_report >= progress.period_s:
                last_report = now
                progress.callback(executor.state, t, t / max(now - wall0, 1e-9))
            if executor.outcome is None:
                world.advance(dt)
            obs = world.observe()
        if stop.reason is not None:
            outcome, reason = "aborted", stop.reason
        else:
            outcome, reason = executor.outcome or "aborted", executor.reason
    except KeyboardInterrupt:
        outcome, reason = "aborted", INTERRUPTED
    except _Terminated:
        outcome, reason = "aborted", TERMINATED
    except Exception as exc:  # the run record must survive any failure of a task or world
        outcome, reason = "aborted", f"{type(exc).__name__}: {exc}"
        if recorder is not None:
            (recorder.dir / "error.txt").write_text(traceback.format_exc())
    finally:
        for sig, handler in reversed(old_handlers):
            signal.signal(sig, handler)
    executor.outcome, executor.reason = outcome, reason
    t_end = t
    if monitor is not None:
        monitor.finish(t, executor.state, outcome)
    if channel is not None:
        channel.finish(executor, t_end)
    wall_run = time.perf_counter() - wall0
    timing_summary: dict[str, Any] = {}
    try:
        executor.close(t)
        t = _safe_stop(world, executor, recorder, t, dt, safe_stop_s)
        final_metrics: dict[str, Any] = dict(metrics)
        try:
            final_metrics.update(world.summary_metrics())
        except Exception as exc:
            final_metrics["summary_error"] = f"{type(exc).__name__}: {exc}"
        summary = build_summary(mission, seed, executor, t_end, final_metrics, k)
        summary["stopped_at_s"] = t
        if monitor is not None:
            summary["properties"] = monitor.verdicts()
        timing_summary = timing.summary(t_end, wall_run, k)
        if recorder is not None:
            recorder.summary(summary)
            recorder.timing(timing_summary)
    finally:
        if recorder is not None:
            recorder.close()
        if frames is not None:
            frames.close()
        world.close()
        if server is not None:
            server.stop()
    return RunResult(outcome, summary, recorder.dir if recorder else None, executor, timing_summary)


def _operator(mission: CompiledMission, control: ControlEndpoint | None,
              operator: Sequence[OperatorAction | dict[str, Any]] | None,
              ) -> tuple[OperatorChannel | None, ControlEndpoint | None]:
    """The operator channel and endpoint a run asked for (none by default: nothing is checked per tick)."""
    if control is None and not operator:
        return None, None
    from taskflow.execution.control import OperatorChannel

    return OperatorChannel(mission, operator or (), live=control is not None), control


def _safe_stop(world: World, executor: Executor, recorder: RunRecorder | None, t: float, dt: float,
               duration: float) -> float:
    """Command the robot to stop and let the world settle for ``duration`` s, recording the ticks.
    A second Ctrl-C cuts the stop short; the summary is still written."""
    try:
        for _ in range(round(duration / dt)):
            world.safe_stop()
            world.advance(dt)
            obs = world.observe()
            t = obs.t
            if recorder is not None:
                recorder.tick(t, executor.state, ("safe_stop",), {}, executor.robot.stop_command(), world.ground_truth())
    except (Exception, KeyboardInterrupt, _Terminated):
        pass
    return t


def print_progress(state: str, t: float, rtf: float) -> None:
    sys.stderr.write(f"\r  t = {t:7.2f} s  RTF {rtf:6.1f}x  {state[:60]:<60}")
    sys.stderr.flush()
