"""``flat_ground``: the racecar alone on a flat floor — the world of the car's kinematic states.

Odometry (``obs.state["pose"]``) is ground truth plus optional white Gaussian noise drawn from
``np.random.default_rng(seed)`` (re-seeded by every :meth:`FlatGround.reset`), so a run with a given seed
is bit-for-bit reproducible.  Time is the simulation clock: a count of physics steps.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import pybullet as p
from pydantic import Field

from taskflow_robots.racecar import Racecar
from taskflow_sim.car_scene import CarScene
from taskflow_sim.racecar_body import Actuation
from taskflow.api import Command, Observation, Robot, StrictModel, World
from taskflow.registry import register_world


class FlatGroundParams(StrictModel):
    """Start pose ``[x, y, yaw]`` (m, rad) of the rear-axle midpoint, physics rate, noise and actuators."""

    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    physics_hz: float = Field(default=240.0, ge=100.0, le=10_000.0,
                              description="physics rate (Hz): wheel contact needs ≥ 100 Hz; a whole multiple of rate_hz")
    odom_noise: float = Field(default=0.0, ge=0.0, description="std of odometry x, y noise (m)")
    odom_yaw_noise: float = Field(default=0.0, ge=0.0, description="std of odometry yaw noise (rad)")
    friction: float = Field(default=1.0, gt=0.0, description="floor and tyre lateral friction")
    speed_tau: float = Field(default=0.05, ge=0.0, description="speed response time constant (s)")
    steer_tau: float = Field(default=0.05, ge=0.0, description="steering response time constant (s)")
    floor_half_size: float = Field(default=25.0, gt=0.0)


@register_world("flat_ground")
class FlatGround(World):
    """A floor and the racecar; ``observe`` gives odometry, speed and steering."""

    Params: ClassVar[type[FlatGroundParams]] = FlatGroundParams
    ground_truth_keys: ClassVar[tuple[str, ...]] = ("x", "y", "yaw", "v")
    robots: ClassVar[tuple[str, ...]] = ("racecar",)

    params: FlatGroundParams
    robot: Racecar

    def __init__(self, robot: Robot, params: FlatGroundParams, seed: int, gui: bool = False) -> None:
        if not isinstance(robot, Racecar):
            raise TypeError(f"world flat_ground drives a racecar, got {type(robot).__name__}")
        super().__init__(robot, params, seed, gui)
        self.physics_hz = float(params.physics_hz)
        self.scene: CarScene | None = None
        self._steps = 0
        self._carry = 0.0
        self._rng = np.random.default_rng(seed)

    # --- lifecycle -----------------------------------------------------------------------------
    def reset(self) -> None:
        self.close()
        rp, wp = self.robot.params, self.params
        actuation = Actuation(
            v_max=rp.v_max, psi_max=rp.psi_max, speed_tau=wp.speed_tau, steer_tau=wp.steer_tau
        )
        self.scene = CarScene.build(
            gui=self.gui,
            physics_hz=self.physics_hz,
            start=wp.start,
            actuation=actuation,
            floor_half_size=wp.floor_half_size,
            friction=wp.friction,
        )
        self._steps = 0
        self._carry = 0.0
        self._rng = np.random.default_rng(self.seed)
        self._populate()
        if self.gui:
            x, y, _ = wp.start
            p.resetDebugVisualizerCamera(3.0, 0.0, -45.0, [x, y, 0.0], physicsClientId=self.scene.client)

    def _populate(self) -> None:
        """Hook for subclasses: add bodies and sensors to ``self.scene`` after the car is built."""

    def close(self) -> None:
        if self.scene is not None:
            self.scene.close()
            self.scene = None

    @property
    def t(self) -> float:
        """Simulation time (s): physics steps taken since :meth:`reset` over ``physics_hz``."""
        return self._steps / self.physics_hz

    def _require_scene(self) -> CarScene:
        if self.scene is None:
            raise RuntimeError("flat_ground: call reset() before using the world")
        return self.scene

    # --- the loop ------------------------------------------------------------------------------
    def observe(self) -> Observation:
        car = self._require_scene().car
        pose = car.pose()
        wp = self.params
        if wp.odom_noise > 0.0:
            pose[:2] += self._rng.normal(0.0, wp.odom_noise, 2)
        if wp.odom_yaw_noise > 0.0:
            pose[2] = math.remainder(pose[2] + self._rng.normal(0.0, wp.odom_yaw_noise), 2.0 * math.pi)
        state: dict[str, Any] = {"pose": pose, "v": car.speed(), "steer": car.steering()}
        return Observation(t=self.t, state=state)

    def apply(self, command: Command) -> None:
        keys = set(self.robot.command_keys)
        if set(command) != keys:
            raise ValueError(f"racecar command needs keys {sorted(keys)}, got {sorted(command)}")
        v = np.asarray(command["v"], dtype=np.float64).reshape(-1)
        steer = np.asarray(command["steer"], dtype=np.float64).reshape(-1)
        if v.shape != (1,) or steer.shape != (1,):
            raise ValueError(f"racecar command arrays must have length 1, got v{v.shape} steer{steer.shape}")
        self._require_scene().car.apply(float(v[0]), float(steer[0]))

    def advance(self, dt: float) -> None:
        """Step ``dt * physics_hz`` whole physics steps (a fractional remainder carries to the next call)."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"advance(dt) needs a finite dt >= 0, got {dt!r}")
        scene = self._require_scene()
        self._carry += dt * self.physics_hz
        n = round(self._carry)
        self._carry -= n
        h = 1.0 / self.physics_hz
        for _ in range(n):
            scene.step(h)
        self._steps += n

    def ground_truth(self) -> dict[str, float]:
        car = self._require_scene().car
        x, y, yaw = car.pose()
        return {"x": float(x), "y": float(y), "yaw": float(yaw), "v": car.speed()}

    def summary_metrics(self) -> dict[str, Any]:
        """Final ground-truth pose and speed of the rear-axle midpoint."""
        gt = self.ground_truth()
        return {"gt_x_m": gt["x"], "gt_y_m": gt["y"], "gt_yaw_rad": gt["yaw"], "gt_speed_mps": abs(gt["v"])}
