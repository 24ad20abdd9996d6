"""``viki_rotate``: ViKi-HyCo state 2 — turn the car around with the kinematic controller (eq. 1–5).

Section III-E: after forward positioning (object in front), "a kinematic controller is used for robot
rotation" since no camera sees the object, until the rear camera can do the backward positioning.  The
paper gives no path; a car cannot turn on the spot, and eq. 4 only servoes a point (the control point
``d`` ahead of the rear axle), not a heading — toward a single target straight behind it would just
reverse.  So the rotation is a **K-turn** (two arcs of radius ``radius``), tracked with eq. 4:

1. reverse along an arc turning the heading by 90 deg (toward ``turn``), then
2. forward along an arc turning it by another 90 deg,

which ends ``2 radius`` behind the start on the line to the object, facing away from it: the object is
then straight behind, ``|object| + 2 radius`` from the rear axle, in the rear camera's view.  The path is
laid out at entry in the frame whose x axis points from the rear axle to the object (the object's
odometry position fixed by the first detection, mission data ``viki.object``, which it reads), so the end pose faces exactly
away from the object even if the forward positioning ended a few degrees off.

Tracking: eq. 4 ``V = J_b^-1 k1 tanh(h_d - h)`` toward a carrot ``lookahead`` metres further along the
leg than the point of the leg nearest to the control point.  Forward legs use the control point ``d``
ahead of the rear axle (eq. 1); **reverse** legs use eq. 4 on the car seen backwards (heading + pi,
speed negated), i.e. a control point ``d`` behind the rear axle — the leading point when reversing, for
which the heading dynamics are stable (a point ahead of the axle while reversing jack-knifes).  Eq. 5
and the limits then give ``(v, steer)`` (:func:`taskflow_tasks.ground.car_kinematics.car_command`).  A leg ends when its
carrot is the leg's end and the control point is within ``leg_tolerance`` of it; the last leg's end is
the final target, approached by eq. 4 alone.

Keep-out (:mod:`taskflow_tasks.core.keep_out`), on by default as in ``viki_hyco``: a command that would drive
the body ``keep_out_body`` toward the object (mission data ``viki.object``, the last good estimate — no
camera sees it here) once within ``keep_out_margin`` is turned around (``keep_out_margin: 0`` turns it off).
The object's width is unknown here: its estimate counts as a point, the margin covers the width.

Metrics: ``pos_error`` (m) — distance from the control point (``d`` ahead) to the final target, the
paper's ``-0.01 < h < 0.01`` m test; ``leg`` (0, 1); ``heading_error`` (rad) to the final heading;
``speed`` (m/s).  No object in the mission data: the task holds still and raises ``no_target``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar, Literal, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field
from taskflow_tasks.core import keys
from taskflow_tasks.core.keep_out import RACECAR_BODY, keep_out_speed
from taskflow_tasks.ground.car_goto import CarGains, CarGeometry, car_control_point
from taskflow_tasks.ground.car_kinematics import car_command, control_point, kinematic_control, wrap_angle
from taskflow_tasks.viki.hyco import MEM_OBJECT
from taskflow_tasks.viki.laws import reverse_control

from taskflow.api import (
    COUNT,
    DISTANCE,
    SPEED,
    WRAPPED_ANGLE,
    MemoryKey,
    Observation,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
    TaskScene,
    array,
)
from taskflow.registry import register_task
from taskflow.spatial import planar_apply_inverse
from taskflow.specs import Requires

FloatArray = NDArray[np.float64]
MEM_ROTATION: MemoryKey[NDArray[np.float64]] = MemoryKey(
    "viki.rotation_target", array(2), unit="m", doc="the K-turn's end point (x, y) in odometry")


def k_turn_legs(start: tuple[float, float], heading: float, radius: float, turn: int, d: float,
                samples: int = 40) -> list[tuple[FloatArray, float]]:
    """The two legs of the K-turn as ``(points, direction)``: control-point polylines (N x 2, odometry).

    ``start``/``heading``: rear-axle position and the path frame's x axis; ``turn`` = +1 (heading
    increases, counter-clockwise) or -1.  Leg 1 reverses (direction -1) with the rear axle on the circle
    of centre ``(0, -s r)`` (path frame), its tracked point ``d`` behind the axle; leg 2 drives forward
    (+1) on the circle of centre ``(-2 r, -s r)``, tracked point ``d`` ahead.  End: rear axle at
    ``(-2 r, 0)``, heading ``heading + pi``.
    """
    if turn not in (1, -1):
        raise ValueError(f"turn must be +1 or -1, got {turn}")
    if not radius > 0.0:
        raise ValueError(f"radius must be > 0, got {radius}")
    s = float(turn)
    c0, s0 = math.cos(heading), math.sin(heading)
    rot = np.array([[c0, -s0], [s0, c0]])
    p0 = np.asarray(start, dtype=float)
    legs = []
    phi1 = np.linspace(0.0, s * math.pi / 2, samples)
    rear1 = np.stack([-s * radius * np.sin(phi1), -s * radius + s * radius * np.cos(phi1)], axis=1)
    pts1 = rear1 - d * np.stack([np.cos(phi1), np.sin(phi1)], axis=1)
    legs.append((pts1 @ rot.T + p0, -1.0))
    phi2 = np.linspace(s * math.pi / 2, s * math.pi, samples)
    rear2 = np.stack([-2 * radius + s * radius * np.sin(phi2), -s * radius - s * radius * np.cos(phi2)], axis=1)
    pts2 = rear2 + d * np.stack([np.cos(phi2), np.sin(phi2)], axis=1)
    legs.append((pts2 @ rot.T + p0, 1.0))
    return legs


def carrot(points: FloatArray, h: FloatArray, start_index: int, lookahead: float) -> tuple[FloatArray, int, bool]:
    """Carrot on a polyline: the point ``lookahead`` (arc length) beyond the nearest vertex at or after
    ``start_index``.  Returns ``(carrot, nearest_index, at_end)``."""
    seg = np.diff(points, axis=0)
    dist = np.hypot(points[start_index:, 0] - h[0], points[start_index:, 1] - h[1])
    i = start_index + int(np.argmin(dist))
    acc = 0.0
    j = i
    while j < len(points) - 1 and acc < lookahead:
        acc += float(np.hypot(*seg[j]))
        j += 1
    return points[j].copy(), i, j == len(points) - 1


class ViKiRotateParams(StrictModel):
    """K-turn geometry (module docstring)."""

    radius: float = Field(default=0.8, gt=0.0, description="arc radius of the rear axle (m), above the car's minimum")
    turn: Literal["left", "right"] = "left"
    lookahead: float = Field(default=0.25, gt=0.0, description="carrot distance along the leg (m)")
    leg_tolerance: float = Field(default=0.06, gt=0.0, description="control point to a leg's end to switch (m)")
    camera: Literal["none", "front", "rear"] = "none"
    keep_out_body: tuple[float, float, float, float] = Field(
        default=RACECAR_BODY, description="m: the car's body (x_min, x_max, y_min, y_max) in the robot frame (default: "
        "the racecar's footprint); never driven toward the object once within keep_out_margin")
    keep_out_margin: float = Field(default=0.3, ge=0.0, description="m: body-object gap that triggers the keep-out "
                                   "(0: off)")


@register_task("viki_rotate")
class ViKiRotate(Task[ViKiRotateParams, CarGeometry]):
    """Kinematic K-turn from the forward-positioned pose to the backward-positioning start."""

    Params: ClassVar[type[ViKiRotateParams]] = ViKiRotateParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"gains": CarGains}
    metrics: ClassVar[dict[str, str]] = {"pos_error": DISTANCE, "leg": COUNT, "heading_error": WRAPPED_ANGLE,
                                         "speed": SPEED}
    events: ClassVar[tuple[str, ...]] = ("no_target",)
    command_interface: ClassVar[str] = "ackermann"
    requires: ClassVar[Requires] = (keys.POSE, keys.SPEED)
    robot_params: ClassVar[type[BaseModel]] = CarGeometry
    reads: ClassVar[tuple[MemoryKey[NDArray[np.float64]], ...]] = (MEM_OBJECT,)
    writes: ClassVar[tuple[MemoryKey[NDArray[np.float64]], ...]] = (MEM_ROTATION,)

    def __init__(self, ctx: TaskContext[ViKiRotateParams, CarGeometry]) -> None:
        super().__init__(ctx)
        params, gains, rp = ctx.params, ctx.profile("gains", CarGains), ctx.robot_params
        self.p = params
        self.k1 = np.asarray(gains.k1, dtype=float)
        self.d = float(gains.d) if gains.d is not None else rp.wheelbase
        self.wheelbase, self.v_max, self.psi_max = rp.wheelbase, rp.v_max, rp.psi_max
        r_min = rp.wheelbase / math.tan(rp.psi_max)
        if params.radius < r_min:
            raise ValueError(f"radius {params.radius} m is below the car's minimum turning radius {r_min:.3f} m")
        self.memory = ctx.memory
        self.legs: list[tuple[FloatArray, float]] | None = None
        self.leg = 0
        self.index = 0
        self.final: FloatArray | None = None
        self.final_heading = 0.0
        self._sensors: tuple[str, ...] = () if params.camera == "none" else (f"{params.camera}_camera",)

    @classmethod
    def scene(cls, params: BaseModel, profiles: Mapping[str, BaseModel], robot_params: BaseModel | None) -> TaskScene:
        """The control point ``d`` ahead of the rear axle, where ``pos_error`` (to the K-turn's end) is
        measured; the K-turn's legs are known only at run time (from the first detection)."""
        return TaskScene(control_point=car_control_point(profiles.get("gains"), cast(CarGeometry, robot_params)))

    def _plan(self, pose: FloatArray) -> None:
        O = np.asarray(MEM_OBJECT(self.memory), dtype=float)
        heading = math.atan2(O[1] - pose[1], O[0] - pose[0])
        turn = 1 if self.p.turn == "left" else -1
        self.legs = k_turn_legs((float(pose[0]), float(pose[1])), heading, self.p.radius, turn, self.d)
        self.final = self.legs[-1][0][-1].copy()
        self.final_heading = wrap_angle(heading + math.pi)
        MEM_ROTATION.set(self.memory, self.final.copy())

    def step(self, obs: Observation) -> StepResult:
        pose = np.asarray(keys.POSE(obs), dtype=float)
        speed = abs(float(keys.SPEED(obs)))
        if self.legs is None:
            if not MEM_OBJECT.present(self.memory):
                stop = {"v": np.zeros(1), "steer": np.zeros(1)}
                return StepResult(stop, {"speed": speed}, ("no_target",), sensors=self._sensors)
            self._plan(pose)
        legs, final = self.legs, self.final
        if legs is None or final is None:
            raise RuntimeError("viki_rotate: the K-turn was not planned")
        pts, direction = legs[self.leg]
        tracked = control_point(pose, self.d) if direction > 0 else control_point(
            np.array([pose[0], pose[1], pose[2] + math.pi]), self.d)
        goal, self.index, at_end = carrot(pts, tracked, self.index, self.p.lookahead)
        last = self.leg == len(legs) - 1
        if (not last and at_end and float(np.hypot(*(pts[-1] - tracked))) < self.p.leg_tolerance):
            self.leg += 1
            self.index = 0
            pts, direction = legs[self.leg]
            tracked = control_point(pose, self.d) if direction > 0 else control_point(
                np.array([pose[0], pose[1], pose[2] + math.pi]), self.d)
            goal, self.index, at_end = carrot(pts, tracked, self.index, self.p.lookahead)
        if direction > 0:
            v, w = kinematic_control(pose, goal, self.k1, self.d)  # eq. 4
        else:
            v, w = reverse_control(pose, goal, self.k1, self.d)  # eq. 4, car seen backwards
        v_cmd, psi = car_command(v, w, self.wheelbase, self.v_max, self.psi_max, direction)  # eq. 5
        object_robot = planar_apply_inverse(pose, MEM_OBJECT(self.memory))
        v_cmd = keep_out_speed(v_cmd, self.p.keep_out_body, object_robot, 0.0, self.p.keep_out_margin)
        h = control_point(pose, self.d)
        metrics = {
            "pos_error": float(np.hypot(*(final - h))),
            "leg": float(self.leg),
            "heading_error": wrap_angle(self.final_heading - float(pose[2])),
            "speed": speed,
        }
        return StepResult({"v": np.array([v_cmd]), "steer": np.array([psi])}, metrics, sensors=self._sensors)
