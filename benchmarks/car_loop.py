"""Costs of the car loop: physics step, car_goto control tick, real-time factor at 20 Hz / 240 Hz.

Run: ``python benchmarks/car_loop.py`` (prints medians of a few repeats; last line JSON).
"""

from __future__ import annotations

import json
import math
import statistics
import time

import numpy as np
import pybullet as p
from taskflow_robots.racecar import Racecar
from taskflow_sim.ground.flat_ground import FlatGround
from taskflow_tasks.ground.car_goto import CarGains, CarGoto

from taskflow.api import TaskContext

ROBOT = Racecar(Racecar.Params())


def step_us(n: int = 2400) -> float:
    world = FlatGround(ROBOT, FlatGround.Params(), seed=0)
    world.reset()
    world.apply({"v": np.array([0.4]), "steer": np.array([0.2])})
    client = world.sim.client
    t0 = time.perf_counter()
    for _ in range(n):
        p.stepSimulation(physicsClientId=client)
    dt = time.perf_counter() - t0
    world.close()
    return dt / n * 1e6


def loop(seconds: float = 10.0) -> tuple[float, float]:
    """(µs per car_goto step, real-time factor of observe/step/apply/advance at 20 Hz)."""
    world = FlatGround(ROBOT, FlatGround.Params(), seed=0)
    world.reset()
    ctx = TaskContext(
        t=0.0,
        params=CarGoto.Params(target=[0.325 + 2.0 * math.cos(1.0), 2.0 * math.sin(1.0)]),
        profiles={"gains": CarGains()},
        memory={},
        robot=ROBOT,
    )
    task = CarGoto(ctx)
    ticks, ctl = round(seconds * 20), 0.0
    t0 = time.perf_counter()
    for _ in range(ticks):
        obs = world.observe()
        a = time.perf_counter()
        r = task.step(obs)
        ctl += time.perf_counter() - a
        world.apply(r.command)
        world.advance(1.0 / 20.0)
    wall = time.perf_counter() - t0
    world.close()
    return ctl / ticks * 1e6, world.t / wall


def main() -> None:
    steps = [step_us() for _ in range(5)]
    loops = [loop() for _ in range(3)]
    print(
        f"stepSimulation with the racecar: {statistics.median(steps):.0f} us (runs: {[round(s) for s in steps]})"
    )
    print(f"car_goto control tick: {statistics.median(c for c, _ in loops):.1f} us")
    print(f"real-time factor, 20 Hz control / 240 Hz physics: {statistics.median(r for _, r in loops):.1f}x")
    print(json.dumps({
        "step_simulation_us": statistics.median(steps),
        "car_goto_tick_us": statistics.median(c for c, _ in loops),
        "real_time_factor": statistics.median(r for _, r in loops),
    }))


if __name__ == "__main__":
    main()
