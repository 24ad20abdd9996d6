"""Per-tick overhead of taskflow's machine: guards + dispatch + trace, no sensing, no control law.

Three figures, measured in one process on the same 3-level machine carrying the same guards:

* ``idle_tick_us`` — ``executor.tick`` + ``recorder.tick`` when no transition fires (the leaf and
  its two ancestors carry a metric guard, an event guard and a time guard that all stay false), timed in
  blocks of the recorder's ``flush_every`` ticks so that each figure holds the row's formatting and its
  share of the block write to ``trace.csv``, as a run's ticks do (a median of single ticks would leave
  out the one tick in a block that writes);
* ``fired_transition_us`` — the same when a nested transition fires every tick (leaf ``a.b.c`` ↔
  ``a.d.e``: exit two levels, enter two, new task, profiles, trace);
* ``baseline_trigger_us`` — ``transitions``' HierarchicalMachine ``trigger('tick')`` with the same
  guards as conditions, nothing firing (the approach taskflow avoids);
* ``baseline_fired_us`` — a bare HierarchicalMachine firing the comparable nested transition
  (``a_b_c`` ↔ ``a_d_e`` by ``trigger('tick')``, exit two levels, enter two, no callbacks): what the
  library alone costs for the state change taskflow's fired tick also makes.

* ``idle_check_ns_per_transition`` — ``executor.check`` alone on the idle leaf (no task step, no trace),
  divided by the transitions its table holds (five over three levels: a guard, a guard with dwell, two
  event guards and a time guard): what checking one transition costs.

* ``idle_tick_properties_us`` — (in blocks too) the idle tick plus the property monitor (:mod:`taskflow.execution.monitors`)
  on the same machine declaring four properties (one per pattern: states, an event, metrics), none decided
  early: ``properties_ratio`` is it over ``idle_tick_us`` (a mission without properties runs no monitor).

``fired_ratio`` is ``fired_transition_us / baseline_fired_us`` (the issue's bound: ≤ 1.5).

Usage: ``python benchmarks/tick_overhead.py [--ticks N]``.  The last line is JSON (medians, µs).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from taskflow.api import Observation, Robot, StepResult, Task, TaskContext, World
from taskflow.execution.executor import Executor
from taskflow.execution.records import RunRecorder
from taskflow.mission.loader import load_mission_text
from taskflow.mission.model import CompiledMission, DoneTransition
from taskflow.registry import ROBOTS, TASKS, WORLDS


class BenchRobot(Robot):
    command_keys = {"v": 1, "w": 1}


class BenchWorld(World):
    events = ("ping", "never")
    metrics = {"flag": ""}
    physics_hz = 100.0  # one step per 100 Hz tick (the loader requires whole steps)

    def observe(self) -> Observation:  # pragma: no cover - not used: observations are prebuilt
        raise NotImplementedError


class BenchTask(Task[Any, Any]):
    metrics = {"err": "m", "yaw": "rad"}

    def __init__(self, ctx: TaskContext[Any, Any]) -> None:
        super().__init__(ctx)
        self.result = StepResult({"v": np.zeros(1), "w": np.zeros(1)}, {"err": 1.0, "yaw": 0.5})

    def step(self, obs: Observation) -> StepResult:
        return self.result


MISSION = """
mission: bench
robot: bench_robot
world: bench_world
rate_hz: 100
machine:
  initial: a
  states:
    a:
      initial: b
      task: bench_task
      transitions:
        - {to: fail, on: never}
        - {to: fail, after: 1e9 s}
      states:
        b:
          initial: c
          transitions: [{to: d, when: "err < 1 mm and yaw < 1 deg", for: 0.1 s}]
          states:
            c:
              transitions:
                - {to: a.d.e, when: "err < 0.5 m"}
                - {to: a.d.e, on: never}
        d:
          initial: e
          states:
            e:
              transitions: [{to: a.b.c, when: "err < 0.5 m"}]
    fail: {final: failed}
"""


PROPERTIES = """properties:
  near_in_c: {never: "state(a.b.c) and err > 5 m", while: "yaw > 1 rad"}
  small_yaw: {always: "yaw < 2 rad"}
  ping_reply: {after: "event(ping)", within: 1 s, then: "state(a.d)"}
  d_after_never: {only_after: "event(never)", occurs: "state(fail)"}
"""


def build(properties: bool = False) -> CompiledMission:
    for reg, name, cls in ((ROBOTS, "bench_robot", BenchRobot), (WORLDS, "bench_world", BenchWorld),
                           (TASKS, "bench_task", BenchTask)):
        if name not in reg:
            reg.add(name, cls)
    text = MISSION.replace("machine:\n", PROPERTIES + "machine:\n", 1) if properties else MISSION
    return load_mission_text(text, "bench.yaml")


def measure(fn: Any, n: int) -> list[float]:
    out = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t0 = clock()
        fn()
        out.append((clock() - t0) / 1000.0)
    return out


def measure_blocks(fn: Any, n: int, block: int) -> list[float]:
    """Per-tick µs of ``n`` calls timed in blocks of ``block``: the recorder's block write (every
    ``flush_every`` ticks) falls in every block, so a median of these includes its share of it, as a run's
    ticks do (a median of single ticks would leave out the one tick in ``block`` that writes)."""
    out = []
    clock = time.perf_counter_ns
    for _ in range(max(1, n // block)):
        t0 = clock()
        for _ in range(block):
            fn()
        out.append((clock() - t0) / 1000.0 / block)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ticks", type=int, default=20000)
    args = ap.parse_args()
    n = args.ticks
    mission = build()
    robot = mission.build_robot()
    world = BenchWorld(robot, mission.world_params(0), 0)
    tmp = Path(tempfile.mkdtemp())
    rec = RunRecorder(tmp, sorted(mission.metric_units), robot.command_keys, ())
    ex = Executor(mission, world, robot, on_transition=lambda r: rec.transition(r.as_dict()))
    ex.start(0.0)
    obs = Observation(0.0, metrics={"flag": 0.0})
    k = [0]

    # -- idle: err stays 1.0, so no guard holds ------------------------------------------------------
    def idle() -> None:
        k[0] += 1
        obs.t = k[0] * 0.01
        command, metrics, events = ex.tick(obs)
        rec.tick(obs.t, ex.state, events, metrics, command, {})

    for _ in range(1000):
        idle()
    idle_us = measure_blocks(idle, n, rec.flush_every)
    assert ex.state == "a.b.c", ex.state

    # -- idle with the property monitor: four properties, each evaluated every tick -------------------------
    from taskflow.execution.monitors import PropertyMonitor

    with_props = build(properties=True)
    monitor = PropertyMonitor(with_props.properties, with_props.states, rec.transition)

    def idle_monitored() -> None:
        k[0] += 1
        obs.t = k[0] * 0.01
        leaf = ex.state
        command, metrics, events = ex.tick(obs)
        monitor.tick(obs.t, leaf, metrics, events, ex.memory)
        rec.tick(obs.t, leaf, events, metrics, command, {})

    for _ in range(1000):
        idle_monitored()
    idle_props_us = measure_blocks(idle_monitored, n, rec.flush_every)
    assert all(c.verdict == "held" and c.open for c in monitor.checks)

    # -- the guards alone: the idle leaf's table checked, nothing firing ------------------------------------
    checked = sum(1 for a in mission.states["a.b.c"].ancestors() for tr in a.transitions
                  if not isinstance(tr, DoneTransition))
    idle_metrics = {"flag": 0.0, "err": 1.0, "yaw": 0.5}
    no_events: tuple[str, ...] = ()

    def check() -> None:
        k[0] += 1
        assert ex.check(k[0] * 0.01, idle_metrics, no_events) is None

    for _ in range(1000):
        check()
    check_us = measure(check, n)

    # -- fired: err = 0.1 < 0.5 m → c → e → c ... every tick ---------------------------------------------
    class Firing(BenchTask):
        def __init__(self, ctx: TaskContext[Any, Any]) -> None:
            super().__init__(ctx)
            self.result = StepResult({"v": np.zeros(1), "w": np.zeros(1)}, {"err": 0.1, "yaw": 0.5})

    ex.task_factory = lambda cls, ctx: Firing(ctx)
    assert ex.task is not None
    ex.task = Firing(ex.task.ctx)
    before = len(ex.transitions_fired)
    fired_us = measure(idle, n // 4)  # per tick, as the library's fired baseline is per call
    fired = len(ex.transitions_fired) - before
    assert fired == n // 4, (fired, n // 4)
    rec.close()

    # -- baseline: HierarchicalMachine trigger('tick') with the same guards as conditions ----------------------
    from transitions.extensions.nesting import HierarchicalMachine

    class Model:
        pass

    model = Model()
    m = {"err": 1.0, "yaw": 0.5}
    ev: set[str] = set()
    t_in = [0.0]
    hm = HierarchicalMachine(model=model, states=[
        {"name": "a", "initial": "b", "children": [
            {"name": "b", "initial": "c", "children": ["c"]}, {"name": "d", "initial": "e", "children": ["e"]}]},
        "fail"], initial="a", auto_transitions=False)
    hm.add_transition("tick", "a_b_c", "a_d_e", conditions=[lambda: m["err"] < 0.5])
    hm.add_transition("tick", "a_b_c", "a_d_e", conditions=[lambda: "never" in ev])
    hm.add_transition("tick", "a_b", "a_d", conditions=[lambda: m["err"] < 0.001 and m["yaw"] < 0.0175])
    hm.add_transition("tick", "a", "fail", conditions=[lambda: "never" in ev])
    hm.add_transition("tick", "a", "fail", conditions=[lambda: t_in[0] > 1e9])

    def baseline() -> None:
        model.trigger("tick")  # type: ignore[attr-defined]  # the library adds trigger() to the model

    for _ in range(500):
        baseline()
    base_us = measure(baseline, n // 4)
    assert model.state == "a_b_c"  # type: ignore[attr-defined]  # the library sets the model's state

    # -- baseline fired: the bare library's nested transition, every tick ---------------------------------------
    fmodel = Model()
    fm = HierarchicalMachine(model=fmodel, states=[
        {"name": "a", "initial": "b", "children": [
            {"name": "b", "initial": "c", "children": ["c"]}, {"name": "d", "initial": "e", "children": ["e"]}]},
        "fail"], initial="a", auto_transitions=False)
    fm.add_transition("tick", "a_b_c", "a_d_e", conditions=[lambda: m["err"] < 1.5])
    fm.add_transition("tick", "a_d_e", "a_b_c", conditions=[lambda: m["err"] < 1.5])

    def baseline_fired() -> None:
        fmodel.trigger("tick")  # type: ignore[attr-defined]  # the library adds trigger() to the model  # the library adds trigger() to the model

    for _ in range(500):
        baseline_fired()
    base_fired_us = measure(baseline_fired, n // 4)
    assert fmodel.state in ("a_b_c", "a_d_e")  # type: ignore[attr-defined]  # the library sets the model's state

    res = {
        "idle_tick_us": statistics.median(idle_us),
        "idle_tick_mean_us": statistics.fmean(idle_us),
        "fired_transition_us": statistics.median(fired_us),
        "fired_transition_mean_us": statistics.fmean(fired_us),
        "idle_tick_properties_us": statistics.median(idle_props_us),
        "properties_ratio": statistics.median(idle_props_us) / statistics.median(idle_us),
        "idle_check_us": statistics.median(check_us),
        "idle_check_ns_per_transition": 1000.0 * statistics.median(check_us) / checked,
        "baseline_trigger_us": statistics.median(base_us),
        "baseline_fired_us": statistics.median(base_fired_us),
        "speedup": statistics.median(base_us) / statistics.median(idle_us),
        "fired_ratio": statistics.median(fired_us) / statistics.median(base_fired_us),
        "ticks": n,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    print(f"idle tick (guards + dispatch + trace): median {res['idle_tick_us']:.2f} µs, mean {res['idle_tick_mean_us']:.2f} µs")
    print(f"idle tick + 4 properties monitored:   median {res['idle_tick_properties_us']:.2f} µs "
          f"({res['properties_ratio']:.2f}x the idle tick)")
    print(f"fired nested transition:              median {res['fired_transition_us']:.1f} µs, mean {res['fired_transition_mean_us']:.1f} µs")
    print(f"guards alone ({checked} transitions):       median {res['idle_check_us']:.2f} µs, "
          f"{res['idle_check_ns_per_transition']:.0f} ns per transition")
    print(f"HierarchicalMachine trigger('tick'):  median {res['baseline_trigger_us']:.1f} µs")
    print(f"bare HierarchicalMachine fired nested: median {res['baseline_fired_us']:.1f} µs")
    print(f"speedup (baseline / idle tick):       {res['speedup']:.1f}x")
    print(f"fired ratio (taskflow / bare fired):  {res['fired_ratio']:.2f}")
    print(json.dumps(res))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
