"""The driven physics floor of each world (issue 24): a mission's own scene stepped with no control law.

Run: ``python benchmarks/physics_floor.py [--repeats N] [--sim-s S] [MISSION ...]`` — default one
mission per world × robot pairing (``FLOOR_MISSIONS``), 3 repeats of 10 simulated seconds each.

The world is built exactly as :func:`taskflow.execution.runtime.run_mission` builds it — the mission's
robot (``mission.build_robot()``), its world parameters drawn from seed 0 (``mission.world_params``), the
registered world class — in the mission's fast perception mode (:func:`fast_overrides`: ``geometric`` or
``pose`` where the world has one).  Then, per control tick of the mission's ``rate_hz``, the loop does what
the runtime's does minus the executor: ``world.apply(FIXED[robot])`` (a constant command, no control law),
``world.advance(1 / rate_hz)`` (the stepping base's whole physics steps at the world's ``physics_hz``) and
``world.observe()`` (the sensors a mission would read).  The wall time runs from ``world.reset()`` (scene
build) to the last tick, the window of the mission's ``timing.json``; RTF = simulated s / wall s.
``physics_rtf`` is the same loop timed without ``observe`` (its time subtracted).

``quad_room`` has no rigid-body physics in any mode: its ``physics_step`` integrates the velocity lag
kinematically and moves the body with ``resetBasePositionAndOrientation``, and each control step ends in
the collision and path-deviation queries; in ``geometric`` mode nothing is rendered.  Its floor is that:
the kinematic integrator at ``physics_hz``, the per-step clearance queries and the landmark projection of
``observe`` — not a PyBullet ``stepSimulation``.

Prints one JSON line per mission (medians over the repeats), then a JSON line with all of them.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import typing
from pathlib import Path
from typing import Any

import taskflow_missions

MISSIONS = Path(taskflow_missions.__file__).resolve().parent

FLOOR_MISSIONS = ("car_waypoints", "husky_waypoints", "viki_forward", "husky_viki_approach", "screw_fastening",
                  "visual_path_oval")
"""One mission per world × robot pairing shipped: flat_ground (racecar, husky), viki_ground (racecar,
husky), screw_conveyor (mobile_iiwa), quad_room (quadcopter)."""

FIXED: dict[str, dict[str, list[float]]] = {
    "racecar": {"v": [0.5], "steer": [0.2]},  # a slow circle
    "husky": {"v": [0.3], "w": [0.2]},
    "mobile_iiwa": {"base_twist": [0.02, 0.0, 0.0], "arm_dq": [0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]},
    "quadcopter": {"nu": [0.1, 0.0, 0.0, 0.05]},
}
"""The constant command each robot is driven by: gentle motion, so the contacts and sensors work as in a
mission (nothing is at rest), and no body leaves the scene in a mission's duration."""

FAST_MODES = ("geometric", "pose")
"""A world's fast perception modes, in order of preference (no rendering)."""


def fast_overrides(stem: str) -> list[str]:
    """The override putting ``stem``'s world in its fast perception mode, or none if it has no
    ``perception`` parameter or the mission's mode already is its only fast one."""
    from taskflow.mission.loader import load_mission

    mission = load_mission(MISSIONS / f"{stem}.yaml")
    field = mission.world_cls.Params.model_fields.get("perception")
    if field is None:
        return []
    modes = [m for m in FAST_MODES if m in typing.get_args(field.annotation)]
    return [f"world.params.perception={modes[0]}"] if modes else []


def load(stem: str, overrides: list[str]) -> Any:
    from taskflow.mission.loader import load_mission

    return load_mission(MISSIONS / f"{stem}.yaml", overrides)


def floor_run(mission: Any, sim_s: float, seed: int = 0) -> dict[str, Any]:
    """One driven run of ``mission``'s world for ``sim_s`` simulated seconds (see the module doc)."""
    robot = mission.build_robot()
    if robot.name not in FIXED:
        raise SystemExit(f"no fixed command for robot {robot.name!r} — valid: {sorted(FIXED)} (add one to FIXED)")
    command = FIXED[robot.name]
    dt = 1.0 / float(mission.spec.rate_hz)
    world = mission.world_cls(robot, mission.world_params(seed), seed, False)
    try:
        wall0 = time.perf_counter()
        world.reset()
        reset_s = time.perf_counter() - wall0
        obs = world.observe()
        observe_s, ticks = 0.0, 0
        while obs.t < sim_s - 1e-9:
            world.apply(command)
            world.advance(dt)
            t0 = time.perf_counter()
            obs = world.observe()
            observe_s += time.perf_counter() - t0
            ticks += 1
        wall = time.perf_counter() - wall0
    finally:
        world.close()
    return {"sim_s": obs.t, "wall_s": wall, "reset_s": reset_s, "observe_s": observe_s, "ticks": ticks,
            "physics_hz": getattr(world, "physics_hz", None), "rtf": obs.t / wall,
            "physics_rtf": obs.t / max(wall - observe_s, 1e-9)}


def floor(stem: str, repeats: int, sim_s: float) -> dict[str, Any]:
    overrides = fast_overrides(stem)
    mission = load(stem, overrides)
    runs = [floor_run(mission, sim_s) for _ in range(repeats)]
    return {"mission": stem, "world": mission.spec.world.name, "robot": mission.build_robot().name,
            "overrides": overrides, "physics_hz": runs[0]["physics_hz"], "rate_hz": float(mission.spec.rate_hz),
            "sim_s": runs[0]["sim_s"], "repeats": repeats,
            "rtf": statistics.median(r["rtf"] for r in runs),
            "physics_rtf": statistics.median(r["physics_rtf"] for r in runs),
            "reset_s": statistics.median(r["reset_s"] for r in runs), "rtfs": [round(r["rtf"], 2) for r in runs]}


def main(argv: list[str] | None = None) -> None:
    from taskflow.execution.provenance import versions

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("missions", nargs="*", default=list(FLOOR_MISSIONS), help="mission stems (missions/STEM.yaml)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sim-s", type=float, default=10.0, help="simulated seconds per run")
    args = ap.parse_args(argv)
    rows = []
    for stem in args.missions:
        row = floor(stem, args.repeats, args.sim_s)
        rows.append(row)
        print(json.dumps(row), flush=True)
    v = versions()
    print(json.dumps({"floors": rows, "versions": {k: v.get(k) for k in ("python", "pybullet", "numpy")}}))


if __name__ == "__main__":
    main()
