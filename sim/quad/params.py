"""The parameters of the ``quad_room`` world: the room, its columns, the start pose, the taught path,
the camera's faults and noise, and the drone's command response and latencies (fidelity ``paper``:
the Bebop 2 of Toro-Arcila et al.)."""

from __future__ import annotations

import math
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator
from taskflow_sim.core.faults import FaultIntervals
from taskflow_sim.quad.teaching import load_keyframe_dir

from taskflow.api import StrictModel
from taskflow.fidelity import Fidelity, Sourced

__all__ = ["MOVE_TAU_PAPER", "KeyframeSpec", "ObstacleSpec", "Pose", "QuadRoomParams", "RoomSpec"]

Pose = tuple[float, float, float, float]


class KeyframeSpec(StrictModel):
    """One keyframe of a visual path: its index and the pose ``[x, y, z, yaw]`` (m, rad) it was
    taught at.  The pose places the camera that renders the keyframe image and is ground truth for the
    summary; the tasks see only the image (their path lists the ids, ``visual_path_servo``'s ``path``)."""

    id: int = Field(ge=0, description="its index on the path: 0, 1, 2, ... in order")
    pose: tuple[float, float, float, float] = Field(description="[x, y, z, yaw] it was taught at (m, rad), inside the room")


class RoomSpec(StrictModel):
    """The room's walls (m): ``x0 < x1``, ``y0 < y1``, each side 1-100 m, and its height."""

    x0: float = Field(default=-1.5, description="m: the wall behind the start")
    x1: float = Field(default=6.0, description="m: beyond x0 by 1-100 m")
    y0: float = Field(default=-3.0, description="m: the right wall")
    y1: float = Field(default=3.0, description="m: beyond y0 by 1-100 m")
    height: float = Field(default=3.0, gt=0.5, le=20.0, description="m: above 0.5 (the drone and its camera fit), at most 20")

    @model_validator(mode="after")
    def _ordered(self) -> RoomSpec:
        if not (self.x1 - self.x0 > 1.0 and self.y1 - self.y0 > 1.0):
            raise ValueError("room must be at least 1 m in x and y (x0 < x1, y0 < y1)")
        if not (self.x1 - self.x0 <= 100.0 and self.y1 - self.y0 <= 100.0):
            raise ValueError("room must be at most 100 m in x and y (a room the textured walls can cover)")
        return self


class ObstacleSpec(StrictModel):
    """A column: a box ``width`` x ``depth`` (m), or a cylinder of diameter ``width`` if ``depth`` = 0."""

    x: float = Field(description="m, world frame")
    y: float = Field(description="m, world frame")
    width: float = Field(gt=0.0, le=2.0, description="m: a column at most 2 m wide")
    depth: float = Field(default=0.0, ge=0.0, le=2.0, description="m: 0 (a cylinder) to 2")
    yaw: float = Field(default=0.0, ge=-2.0 * math.pi, le=2.0 * math.pi, description="rad: one turn either way")


MOVE_TAU_PAPER = 0.11
MOVE_TAU_SOURCE = ("fitted to the paper's §5.3 'about 205 s' for the oval without feed-forward (Parrot publishes no "
                   "figure for the Bebop 2's position loop): taskflow run "
                   "missions/visual_path_oval.yaml --set world.params.perception=geometric --set world.params.fidelity=paper "
                   "gives 204.2 s with 0.11 s (0.10: 192.5 s, 0.12: 218.3 s)")


class QuadRoomParams(Fidelity):
    """Room, obstacles, start pose, visual path, sensor faults, and the drone's response and latencies
    (fidelity ``paper``: the Bebop 2 of the paper) of the ``quad_room`` world."""

    room: RoomSpec = Field(default=RoomSpec(), description="the walls and height (m)")
    obstacles: list[ObstacleSpec] = Field(default_factory=list, description="the columns")
    start: tuple[float, float, float, float] = Field(default=(0.0, 0.0, 1.0, 0.0),
                                                     description="[x, y, z, yaw] (m, rad): inside the room")
    keyframes: list[KeyframeSpec] = Field(default_factory=list, description="the taught path, ids 0, 1, 2, ...")
    keyframe_dir: str | None = Field(default=None, description="images written by teach(); None: render on reset")
    texture_seed: int = Field(default=0, ge=0, description="seed of the generated textures (fixed by the taught path)")
    texture_px_per_m: float = Field(default=160.0, gt=10.0, le=1000.0, description="texture resolution (px/m): "
                                    "above 10 (coarser, the walls have no features to track), at most 1000")
    physics_hz: float = Field(default=250.0, ge=25.0, le=10_000.0,
                              description="integration rate of the velocity lag (Hz); a whole multiple of rate_hz")
    image_noise: float = Field(default=0.0, ge=0.0, le=50.0, description="std of Gaussian pixel noise (grey levels): "
                               "at most 50, a fifth of the 8-bit range")
    blackout: FaultIntervals = Field(default=[], description="[t0, t1] intervals of black frames (s)")
    obstacle_height: float = Field(default=3.0, gt=0.0, le=20.0, description="m: at most 20 (the highest room)")
    perception: Literal["rendered", "geometric"] = Field(
        default="rendered", description="rendered frames (faithful) or projected landmarks (fast)")
    landmark_density: float = Field(default=20.0, gt=0.0, le=1000.0,
                                    description="landmarks per m² of wall, floor and ceiling (geometric mode)")
    pixel_noise: float = Field(default=0.5, ge=0.0, le=20.0, description="std of each landmark pixel coordinate "
                               "(geometric mode): at most 20 px, a twelfth of the default 240 px image height")
    command_response: Literal["velocity", "relative_move"] = Field(
        default="velocity", description="velocity: the body velocity tracks each command with the robot's lag tau; "
        "relative_move: each command is a move of nu * control period from where the drone is (ViSP's Bebop 2 "
        "setVelocity), executed by a position loop of time constant move_tau until the next one replaces it")
    move_tau: float = Field(default=0.1, gt=0.0, le=10.0,
                            description="time constant of the position loop executing a relative move (s)")
    command_delay_s: float = Field(default=0.0, ge=0.0, le=0.5, description="transport delay of each command (s): "
                                   "with frame_latency_s at most 0.5 s; the visual-servo loop with the laws' largest "
                                   "default gain (lambda_0 = 2.8 /s) and a delay tau is stable only while lambda tau < "
                                   "pi/2 (0.56 s)")
    frame_latency_s: float = Field(default=0.0, ge=0.0, le=0.5,
                                   description="age of the frame an observation carries (s): the view of the pose then; "
                                   "with command_delay_s at most 0.5 s: the visual-servo loop with the laws' largest "
                                   "default gain (lambda_0 = 2.8 /s) and a delay tau is stable only while lambda tau < "
                                   "pi/2 (0.56 s)")
    camera_rate_hz: float | None = Field(default=None, ge=1.0, le=120.0,
                                         description="frame rate (Hz); None: the robot camera's rate_hz; 1-120 (the "
                                         "Bebop 2 streams 30 fps)")

    FIDELITY: ClassVar[dict[str, dict[str, Sourced]]] = {"paper": {
        "command_response": Sourced("relative_move", "Toro-Arcila et al. §5: commands are sent with ViSP's "
                                    "vpRobotBebop2::setVelocity(v, dt), which sends setPosition(exp(v dt)), the ARSDK "
                                    "relative move moveBy, non-blocking (ViSP modules/robot/src/real-robot/bebop2/"
                                    "vpRobotBebop2.cpp)"),
        "move_tau": Sourced(MOVE_TAU_PAPER, MOVE_TAU_SOURCE),
        "camera_rate_hz": Sourced(30.0, "§5.2: the Bebop 2 camera in video mode works at 30 fps"),
        "frame_latency_s": Sourced(0.04, "§5.1, Fig. 8: 40 ms cycle time in 96 % of the iterations, so each command "
                                   "acts on a frame one cycle old"),
    }}

    @field_validator("keyframes")
    @classmethod
    def _ids(cls, v: list[KeyframeSpec]) -> list[KeyframeSpec]:
        if [k.id for k in v] != list(range(len(v))):
            raise ValueError(f"keyframe ids must be 0, 1, 2, ... in order, got {[k.id for k in v]}")
        return v

    @model_validator(mode="after")
    def _delays(self) -> QuadRoomParams:
        if self.command_delay_s + self.frame_latency_s > 0.5:
            raise ValueError(f"command_delay_s + frame_latency_s = {self.command_delay_s + self.frame_latency_s:g} s: "
                             "the visual-servo loop sees both, and with lambda_0 = 2.8 /s it is stable only while "
                             "lambda x delay < pi/2 — keep the sum at most 0.5 s")
        return self

    @model_validator(mode="after")
    def _inside_the_room(self) -> QuadRoomParams:
        r = self.room
        for what, (x, y, z, _) in [("start", self.start), *((f"keyframe {k.id}", k.pose) for k in self.keyframes)]:
            if not (r.x0 < x < r.x1 and r.y0 < y < r.y1 and 0.0 < z < r.height):
                raise ValueError(f"{what} pose ({x:g}, {y:g}, {z:g}) is outside the room: x in ({r.x0:g}, {r.x1:g}), "
                                 f"y in ({r.y0:g}, {r.y1:g}), z in (0, {r.height:g}) m")
        return self

    @model_validator(mode="after")
    def _keyframe_files(self) -> QuadRoomParams:
        if self.keyframe_dir is not None and self.perception == "geometric":
            raise ValueError("keyframe_dir holds images for perception: rendered; perception: geometric projects "
                             "landmarks at the taught poses — drop one of the two")
        if self.keyframe_dir is not None:
            _, meta = load_keyframe_dir(self.keyframe_dir)
            poses = [tuple(k["pose"]) for k in meta.get("keyframes", [])]
            if self.keyframes and len(poses) != len(self.keyframes):
                raise ValueError(f"keyframe_dir holds {len(poses)} keyframes but the path has {len(self.keyframes)}")
            for k, q in zip(self.keyframes, poses):
                if not np.allclose(k.pose, q, atol=1e-6):
                    raise ValueError(f"keyframe {k.id}: taught pose {list(q)} in keyframe_dir differs from {list(k.pose)}")
        return self

