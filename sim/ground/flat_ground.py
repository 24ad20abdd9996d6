"""``flat_ground``: a wheeled robot alone on a flat floor — the world of the kinematic states.

Any robot with a registered ground body (:mod:`taskflow_sim.core.bodies`, entry point group
``taskflow.bodies``) drives here: the world builds the body by the robot's name and never names a robot.
The observation's ``state`` is the body's proprioception (``pose``, ``v`` and what the robot adds, e.g.
the racecar's ``steer``).

Odometry (``obs.state["pose"]``) is the sensor stream ``odometry`` (:mod:`taskflow_sim.core.sensors`):
ground truth read at every control tick (the end of each ``advance``, and at reset) plus optional white
Gaussian noise drawn from ``np.random.default_rng(seed)`` (re-seeded by every :meth:`FlatGround.reset`)
when the reading is captured, so :meth:`FlatGround.observe` is pure and a run with a given seed is
bit-for-bit reproducible.  A subclass adds a sensor by declaring another stream in ``_populate``.  Time is
the simulation clock: a count of physics steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, cast

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from pydantic import BaseModel, Field, model_validator
from taskflow_sim.core.bodies import BodyOptions, GroundBody, make_body
from taskflow_sim.core.sensors import SensorStream
from taskflow_sim.core.stepped import PhysicsHz, SteppedWorld, check_command
from taskflow_sim.ground.ground_plane import add_floor, connect

from taskflow.api import Command, Marker, Observation, Robot, RobotNeeds, StrictModel
from taskflow.registry import register_world


@dataclass
class GroundScene:
    """A floor and one robot body in a fresh client (``car`` is the body, by its historical name)."""

    client: int
    floor: int
    car: GroundBody

    def step(self, h: float) -> None:
        """One physics step of ``h`` seconds (actuator response, then the solver)."""
        self.car.update(h)
        p.stepSimulation(physicsClientId=self.client)

    def close(self) -> None:
        if p.isConnected(physicsClientId=self.client):
            p.disconnect(physicsClientId=self.client)


class FlatGroundParams(StrictModel):
    """Start pose ``[x, y, yaw]`` (m, rad) of the robot frame (the racecar's rear-axle midpoint), physics
    rate, noise and actuators."""

    start: tuple[float, float, float] = Field(default=(0.0, 0.0, 0.0), description="[x, y, yaw] (m, m, rad); "
                                              "x and y on the floor (|x|, |y| < floor_half_size)")
    physics_hz: PhysicsHz = Field(default=240.0,
                                  description="physics rate (Hz): wheel contact needs ≥ 100 Hz; a whole multiple of rate_hz")
    odom_noise: float = Field(default=0.0, ge=0.0, le=0.1, description="std of odometry x, y noise (m): at most 0.1, "
                              "beyond the missions' waypoint tolerances (3-25 cm) ten times over")
    odom_yaw_noise: float = Field(default=0.0, ge=0.0, le=0.2, description="std of odometry yaw noise (rad): at most "
                                  "0.2 (11 deg)")
    friction: float = Field(default=1.0, gt=0.0, le=2.0, description="floor and tyre lateral friction: at most 2 "
                            "(rubber on dry concrete is 0.6-1.0)")
    speed_tau: float = Field(default=0.05, ge=0.0, le=2.0, description="speed response time constant (s): at most 2; "
                             "the kinematic laws (gains ~1 /s) take the command for the speed, which a lag longer than "
                             "their own time constant makes them overshoot and oscillate")
    steer_tau: float = Field(default=0.05, ge=0.0, le=2.0, description="steering response time constant (s): at most 2, "
                             "as speed_tau")
    floor_half_size: float = Field(default=25.0, gt=0.0, le=1000.0, description="m: at most 1 km")

    @model_validator(mode="after")
    def _start_on_the_floor(self) -> FlatGroundParams:
        if not max(abs(self.start[0]), abs(self.start[1])) < self.floor_half_size:
            raise ValueError(f"start ({self.start[0]:g}, {self.start[1]:g}) m is off the floor: |x|, |y| must be "
                             f"below floor_half_size = {self.floor_half_size:g} m")
        return self


@register_world("flat_ground")
class FlatGround(SteppedWorld[GroundScene]):
    """A floor and one wheeled robot; ``observe`` gives its odometry and proprioception."""

    Params: ClassVar[type[FlatGroundParams]] = FlatGroundParams
    ground_truth_keys: ClassVar[tuple[str, ...]] = ("x", "y", "yaw", "v")
    poses: ClassVar[dict[str, tuple[str, str, str | None]]] = {"robot": ("x", "y", "yaw")}
    needs: ClassVar[RobotNeeds] = RobotNeeds(body=True)

    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """The start pose of the robot frame."""
        x, y, yaw = cast(FlatGroundParams, params).start
        return [Marker.point("start", "start", x, y, yaw=yaw)]

    params: FlatGroundParams

    def __init__(self, robot: Robot, params: FlatGroundParams, seed: int, gui: bool = False) -> None:
        super().__init__(robot, params, seed, gui)
        self._rng = np.random.default_rng(seed)

    # --- lifecycle -----------------------------------------------------------------------------
    def reset(self) -> None:
        self.close()
        wp = self.params
        body = make_body(self.robot, BodyOptions(friction=wp.friction, speed_tau=wp.speed_tau, steer_tau=wp.steer_tau))
        client = connect(self.gui, self.physics_hz)
        floor = add_floor(client, wp.floor_half_size, wp.friction)
        body.spawn(client, wp.start)
        self.sim = GroundScene(client, floor, body)
        self.restart_clock()
        self._rng = np.random.default_rng(self.seed)
        noisy = wp.odom_noise > 0.0 or wp.odom_yaw_noise > 0.0
        self.streams.clear()
        self.odometry = self.add_stream("odometry", SensorStream(
            self._read_odometry, None, poll="advance", corrupt=self._odometry_noise if noisy else None, rng=self._rng))
        self._populate()
        self.start_streams()
        if self.gui:
            x, y, _ = wp.start
            p.resetDebugVisualizerCamera(3.0, 0.0, -45.0, [x, y, 0.0], physicsClientId=client)

    def _populate(self) -> None:
        """Hook for subclasses: add bodies to ``self.sim`` and sensor streams (:meth:`add_stream`) after
        the robot and its odometry are built."""

    # --- sensors ---------------------------------------------------------------------------------
    def _read_odometry(self, t: float, _state: object) -> NDArray[np.float64]:
        return np.array(self._require_sim().car.pose(), dtype=np.float64)

    def _odometry_noise(self, pose: NDArray[np.float64], t: float, rng: np.random.Generator) -> NDArray[np.float64]:
        wp = self.params
        if wp.odom_noise > 0.0:
            pose[:2] += rng.normal(0.0, wp.odom_noise, 2)
        if wp.odom_yaw_noise > 0.0:
            pose[2] = math.remainder(pose[2] + rng.normal(0.0, wp.odom_yaw_noise), 2.0 * math.pi)
        return pose

    # --- the loop ------------------------------------------------------------------------------
    def observe(self) -> Observation:
        car = self._require_sim().car
        reading = self.odometry.latest
        assert reading is not None and reading.value is not None  # captured at reset and every advance
        state: dict[str, Any] = {**car.proprioception(), "pose": reading.value.copy()}
        return Observation(t=self.t, state=state)

    def apply(self, command: Command) -> None:
        self._require_sim().car.apply(check_command(self.robot, command))

    def _before_steps(self) -> None:
        self._require_sim()

    def physics_step(self, h: float) -> None:
        self._require_sim().step(h)

    def ground_truth(self) -> dict[str, float]:
        car = self._require_sim().car
        x, y, yaw = car.pose()
        return {"x": float(x), "y": float(y), "yaw": float(yaw), "v": float(car.twist()[0])}

    def summary_metrics(self) -> dict[str, Any]:
        """Final ground-truth pose and speed of the rear-axle midpoint."""
        gt = self.ground_truth()
        return {"gt_x_m": gt["x"], "gt_y_m": gt["y"], "gt_yaw_rad": gt["yaw"], "gt_speed_mps": abs(gt["v"])}
