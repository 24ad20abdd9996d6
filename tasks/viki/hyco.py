"""``viki_hyco``: the ViKi-HyCo positioning task (paper section II-F, eq. 19–26) and its two baselines.

One task, three ``mode`` s:

* ``hybrid`` — ViKi-HyCo, eq. 25 as meant: the visual servo law of eq. 24 on the four box corners with
  the desired box of eq. 19 while the camera detects the object, the kinematic controller of eq. 4–5
  toward the kinematic target otherwise;
* ``vs_only`` — the paper's VS-only baseline (section III-B): no fallback, zero velocity without a
  detection (the robot stops; Fig. 12);
* ``mgbm`` — the MGBM-YOLO baseline (section III-D): static desired box of a known object size
  (``object_size``), depth from box areas, no fallback.

Eq. 26 (as meant, never amplifying) smooths the output in every mode; eq. 5 and the robot's limits turn
it into ``(v, steer)``.

Camera: ``camera: front | rear`` picks the mount ``(R_body_camera, t_body_camera)`` of eq. 22 and is named in every step
result (``StepResult.sensors = ("front_camera",)``), so the world processes only that camera.  A camera name the robot does not have is a load-time error.

Desired features: ``desired: [x, y]`` is the object's desired position in the robot frame (e.g. the
manipulation zone); the desired box centre follows from it and the measured object (see
:mod:`taskflow_tasks.viki.laws`), or is given directly in pixels with ``desired_centre`` (the paper's way).  ``Z_d``
is read every frame in the depth image at the desired centre (eq. 19).  ``zd: pixel`` reads the single pixel
(as printed; the world's ``depth_at``); ``zd: window`` (default) applies eq. 17's rule — mean depth of the
40 %-shrunk box — to the current box moved to the desired centre (``depth_in``).  Away from the goal both
read the floor there; at the goal the window gives exactly ``Z_d = Z_o`` (``k = 1``) whereas a single
pixel on a slanted face (a carton seen corner-on) differs from the box mean by a few per cent, which
leaves the corners 2–3 px off on a 100 px box — outside the paper's ±2 px band, so the state never ends.
If ``Z_d`` cannot be read (desired centre outside the image) the tick falls back as if undetected.

Kinematic target (eq. 25's fallback, eq. 4's ``h_d``): the object's position in the odometry frame
(eq. 18 + base-centre estimate) is stored in the mission data (key ``viki.object``) so later states —
the rotation, the backward positioning — use it.  With ``target_update: latest`` (the default) every
*whole* detection re-anchors it — one whose box is not within ``border_px`` of the image border
(:func:`taskflow_tasks.viki.evidence.box_cut_by_border`: a cut box's centre and width are the visible
part's, and trusting it drove the car onto the object at large bearings); a cut box still drives the
visual servo, and fixes the object (at its floor point, below) only while no whole box has.  A target frozen at the first detection
(``target_update: first``, the paper's rule) lies 5–9 cm from where the visual servo converges, so
each burst of missed detections dragged the car off by 20–30 cm.  With ``target_update: evidence`` (what
``viki_hyco.yaml`` sets) a whole detection re-anchors the object at the mean of the stored whole detections within
``evidence_window`` of the current view — the estimate ``goal_error`` reads: at the paper-like level (2 px box
jitter at 1280x720) one detection places the object 1–2 cm off, and a long burst of misses right after one drove the
car that far from a goal it had reached (issue 25: the backward state's timeout with the object ~1 cm from the goal).  A state turns the object into its
control-point target on entry (if the memory has it) and after every re-anchoring: the pose with the
object at ``desired`` and the heading of :func:`taskflow_tasks.viki.laws.goal_heading` (stored as
``viki.target``).  For a goal behind the robot
(``desired[0] < 0``, the rear camera) the fallback is the paper's *backward* kinematic controller: eq. 4 on
the car seen backwards, servoing the point ``d`` behind the rear axle (:func:`taskflow_tasks.viki.laws.reverse_control`;
plain eq. 4 while reversing jack-knifes the car); ``fallback: forward | reverse`` forces either.

No detection yet and no object in memory: the robot holds still and, after ``search_timeout``, the task
raises ``no_target`` every tick (declare ``on: no_target`` to an error state).

A cut box's position is not eq. 18's (its eq. 17 depth averages floor beyond a sliver of object: 0.35–0.42 m
too far at the edge of the view, issue 25) but the floor point under its inner column
(:func:`taskflow_tasks.viki.evidence.cut_box_near_point`), no farther than the object; a box cut by the bottom
border gives none.  While the object is fixed only by cut boxes, each new one re-anchors it.

Keep-out (:mod:`taskflow_tasks.core.keep_out`), on in every state and every mode: a command moving the body
``keep_out_body`` (the car's footprint in the robot frame; default the racecar's, measured by
``taskflow_sim.viki.clearance.measure_footprint``) toward the object (memory: the last good estimate, also
while nothing is detected) once within ``keep_out_margin`` is turned around; ``keep_out_margin: 0`` turns it off.

Evidence for the settle rule (a completion a car can meet, docs/missions.md): ``goal_error`` (m) is the
distance from ``desired`` to the mean object position of the last ``evidence_frames`` whole detections
taken within ``evidence_window`` of view shift of the current pose (:func:`taskflow_tasks.viki.evidence.view_shifts`),
seen from the current odometry pose; ``view_shift`` (m) is how far the goal point has moved in odometry
since the last whole detection (a still camera gives the same image: that detection still holds).

Metrics: ``feature_error`` (px, max |f - f_d| of the latest detection, absent before the first),
``pos_error`` (m, control point to the kinematic target, from odometry), ``detected`` (``c`` of eq. 25),
``detection_age`` (s), ``object_x`` / ``object_y`` (m, object in the robot frame from odometry and the
memory), ``v_cmd`` (m/s, signed command), ``speed`` (m/s, measured), ``goal_error`` and ``view_shift``
(m, above; absent before the first whole detection, ``goal_error`` also once the view has moved more than
``evidence_window``).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, ClassVar, Literal, cast

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field, field_validator, model_validator
from taskflow_robots.racecar import CameraMount
from taskflow_tasks.core import keys
from taskflow_tasks.core.gains import positive_gains
from taskflow_tasks.core.keep_out import RACECAR_BODY, keep_out_speed
from taskflow_tasks.ground.car_goto import CarGains, CarGeometry
from taskflow_tasks.viki.car_visual_servo import car_jacobian_r
from taskflow_tasks.viki.evidence import box_cut_by_border, cut_box_near_point, goal_offset, view_shifts
from taskflow_tasks.viki.laws import (
    ServoInputs,
    desired_centre,
    goal_heading,
    kinematic_target,
    object_base,
    viki_velocity,
)

from taskflow.api import (
    AGE,
    DISTANCE,
    FLAG,
    SPEED,
    ControlPoint,
    MemoryKey,
    Metric,
    Observation,
    ObsKey,
    StepResult,
    StrictModel,
    Task,
    TaskContext,
    TaskScene,
    array,
    mapping,
)
from taskflow.messages import Detection
from taskflow.registry import register_task
from taskflow.spatial import planar_apply, planar_apply_inverse, twist_adjoint_inverse
from taskflow.specs import Requires

# the observations the ViKi-HyCo tasks read (declared in their ``requires``, called to read: one thing);
# the odometry pose and speed are the shared keys of :mod:`taskflow_tasks.core.keys`
DETECTION = ObsKey("sensors.detection", Detection, optional=True)

# the mission data the ViKi-HyCo tasks keep across states (one definition each)
MEM_OBJECT: MemoryKey[NDArray[np.float64]] = MemoryKey(
    "viki.object", array(2), unit="m",
    doc="odometry (x, y) of the object's base centre, from the latest whole detection (or the first)")
MEM_TARGET: MemoryKey[NDArray[np.float64]] = MemoryKey(
    "viki.target", array(2), unit="m", doc="the active state's control-point target (x, y) in odometry")
MEM_FIRST: MemoryKey[dict[str, Any]] = MemoryKey(
    "viki.first_detection", mapping(), doc='{"t": s, "camera": front|rear} of the detection that fixed the object')


class ViKiGains(CarGains):
    """Gains of one positioning direction (profile kind ``viki_gains``).

    ``lam``: the paper's five numbers (section III-A: front ``[0.85, 0.3, 1, 1, 1]``, rear
    ``[0.85, 1.05, 1, 1, 1]``); ``diag(lam[0], lam[1])`` acts on ``[v, w]`` in eq. 24 and the other three
    have no counterpart in the 2-DoF law (:func:`taskflow_tasks.viki.car_visual_servo.car_gains`).  ``k1``: eq. 4's
    ``[k_x, k_y]`` (forward ``[2, 1]``, backward ``[1, 2]``).  ``d``: control-point distance of eq. 1
    (``None``: the wheelbase, as in the paper).
    """

    kind: ClassVar[str] = "viki_gains"

    lam: tuple[float, ...]

    @field_validator("lam")
    @classmethod
    def _lam(cls, lam: tuple[float, ...]) -> tuple[float, ...]:
        if len(lam) != 5:
            raise ValueError(
                f"lam needs the paper's 5 gains [lambda_v, lambda_w, l3, l4, l5] (only the first two act in the "
                f"2-DoF law), got {len(lam)}: {list(lam)}")
        return positive_gains("lam", lam)


class CameraCar(CarGeometry):
    """The robot parameters ViKi-HyCo reads: the car's geometry and its two camera mounts."""

    front_camera: CameraMount
    rear_camera: CameraMount


class ViKiHyCoParams(StrictModel):
    """See the module docstring."""

    camera: Literal["front", "rear"]
    desired: tuple[float, float] = Field(description="object position in the robot frame at the goal (m)")
    desired_centre: tuple[float, float] | None = Field(default=None, description="desired box centre (px)")
    mode: Literal["hybrid", "vs_only", "mgbm"] = "hybrid"
    object_size: tuple[float, float] | None = Field(default=None, description="mgbm: known (W, H) of the object (m)")
    search_timeout: float = Field(default=2.0, gt=0.0, description="s without any detection → event no_target")
    max_age: float = Field(default=0.2, gt=0.0, description="s: an older frame counts as no detection")
    target_update: Literal["first", "latest", "evidence"] = Field(
        default="latest", description="the fallback target follows every usable detection (latest), the mean of the "
        "whole detections goal_error reads (evidence: the same estimate as the settle rule) or the first one only "
        "(first: the paper's rule)")
    evidence_frames: int = Field(default=15, ge=1, description="goal_error averages the object positions of up to "
                                 "this many latest whole detections (15: 1 s of frames)...")
    evidence_window: float = Field(default=0.02, gt=0.0, description="m: ...taken while the view has shifted less "
                                   "than this since (view_shift)")
    keep_out_body: tuple[float, float, float, float] = Field(
        default=RACECAR_BODY, description="m: the car's body (x_min, x_max, y_min, y_max) in the robot frame (default: "
        "the racecar's footprint); the car never drives it toward the object once within keep_out_margin "
        "(taskflow_tasks.core.keep_out)")
    keep_out_margin: float = Field(default=0.3, ge=0.0, description="m: body-object gap that triggers the keep-out "
                                   "(0: off)")
    border_px: float = Field(default=2.0, ge=0.0, description="px: a box this close to the image border is cut by "
                             "it: no evidence (goal_error), and it places the object only while no whole box has (cut_box_near_point)")
    zd: Literal["window", "pixel"] = "window"
    fallback: Literal["auto", "forward", "reverse"] = "auto"
    smoothing: bool = True

    @model_validator(mode="after")
    def _check(self) -> ViKiHyCoParams:
        if self.mode == "mgbm" and self.object_size is None:
            raise ValueError("mode 'mgbm' needs object_size: [W, H] (m), the object's known size")
        if self.object_size is not None and min(self.object_size) <= 0.0:
            raise ValueError(f"object_size must be positive, got {self.object_size}")
        return self


_CAM_KEYS = ("cam_vx", "cam_vy", "cam_vz", "cam_wx", "cam_wy", "cam_wz")


@register_task("viki_hyco")
class ViKiHyCo(Task[ViKiHyCoParams, CameraCar]):
    """ViKi-HyCo visual/kinematic positioning with the front or rear camera (module docstring)."""

    Params: ClassVar[type[ViKiHyCoParams]] = ViKiHyCoParams
    slots: ClassVar[dict[str, type[BaseModel]]] = {"gains": ViKiGains}
    metrics: ClassVar[dict[str, str]] = {
        "feature_error": Metric("px", low=0.0, reason="the largest |feature error| component"), "pos_error": DISTANCE,
        "detected": FLAG, "detection_age": AGE, "object_x": "m", "object_y": "m", "v_cmd": "m/s", "speed": SPEED,
        "goal_error": DISTANCE, "view_shift": DISTANCE,
        "cam_vx": "m/s", "cam_vy": "m/s", "cam_vz": "m/s", "cam_wx": "rad/s", "cam_wy": "rad/s", "cam_wz": "rad/s",
    }
    events: ClassVar[tuple[str, ...]] = ("no_target",)
    command_interface: ClassVar[str] = "ackermann"
    robot_params: ClassVar[type[BaseModel]] = CameraCar
    requires: ClassVar[Requires] = (keys.POSE, DETECTION, keys.SPEED)
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (MEM_OBJECT, MEM_TARGET, MEM_FIRST)

    def __init__(self, ctx: TaskContext[ViKiHyCoParams, CameraCar]) -> None:
        super().__init__(ctx)
        params, gains, rp = ctx.params, ctx.profile("gains", ViKiGains), ctx.robot_params
        self.p = params
        self.camera = params.camera
        mount = rp.front_camera if params.camera == "front" else rp.rear_camera
        self.T_body_camera = mount.T_body_camera()
        # camera twist of a robot velocity [v, w] (eq. 20-22): V_c = T_r^c J_r V_r, for the figures
        self._cam_twist = twist_adjoint_inverse(self.T_body_camera) @ car_jacobian_r()
        self.lam = np.asarray(gains.lam, dtype=float)
        self.k1 = np.asarray(gains.k1, dtype=float)
        self.d = float(gains.d) if gains.d is not None else rp.wheelbase
        self.wheelbase, self.v_max, self.psi_max = rp.wheelbase, rp.v_max, rp.psi_max
        self.goal = np.asarray(params.desired, dtype=float)
        # eq. 4's fallback drives toward the goal pose: backwards (point d behind) for a goal behind
        self.reverse = params.fallback == "reverse" or (params.fallback == "auto" and self.goal[0] < 0.0)
        self.d_point = -self.d if self.reverse else self.d  # signed offset of the controlled point
        self.memory = ctx.memory
        self.t0 = ctx.t
        self.v_prev = np.zeros(2)
        self.direction = 0.0
        self.last_feature_error: float | None = None
        self.last_detection_t: float | None = None
        # the whole detections' evidence, newest last: (odometry pose at the detection, object (x, y) in odometry)
        self.evidence: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=params.evidence_frames)
        self.object_radius = 0.0  # m, the object's half-width by the last whole detection (keep-out)
        self.anchored_by_cut = False  # the object (memory) was fixed by this state from cut boxes only
        self.target: np.ndarray | None = None
        self.theta_f: float | None = None
        self._sensors = (f"{self.camera}_camera",)
        self.last: Any = None  # last ServoOutput, for inspection

    @classmethod
    def scene(cls, params: BaseModel, profiles: Mapping[str, BaseModel], robot_params: BaseModel | None) -> TaskScene:
        """The point of the robot frame where the object should end up (``desired``): the state has
        reached its goal when this point lies on the object (the guards read the image error it implies)."""
        x, y = cast(ViKiHyCoParams, params).desired
        return TaskScene(control_point=ControlPoint((x, y), f"goal point of the object in the robot frame ({x:g}, {y:g}) m"))

    # -- the kinematic target --------------------------------------------------------------------
    def _set_target(self, pose: np.ndarray) -> None:
        O = MEM_OBJECT(self.memory)
        if self.theta_f is None:
            self.theta_f = goal_heading(pose, O, self.goal)
        self.target = kinematic_target(O, self.goal, self.theta_f, self.d_point)
        MEM_TARGET.set(self.memory, self.target.copy())

    def _object_from(self, det: Detection, pose: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Object base centre in odometry, half-width and height (eq. 18 + base estimate)."""
        if det.bbox is None or det.depth is None:
            raise ValueError("object position needs a detection with a box and a depth")
        B, r, z_c = object_base(det.bbox, det.depth, det.intrinsics, self.T_body_camera)
        return planar_apply(pose, B[:2]), r, z_c  # T_odom_body applied to the base centre

    # -- one tick ------------------------------------------------------------------------------------
    def step(self, obs: Observation) -> StepResult:
        pose = np.asarray(keys.POSE(obs), dtype=float)
        det = DETECTION(obs)
        if det is not None and det.camera != self.camera:
            det = None
        usable = det is not None and det.detected and obs.t - det.stamp <= self.p.max_age + 1e-9
        # a box cut by the image border still steers the visual servo (toward bringing the object into view)
        # but is no evidence of where the object is: it anchors the target only when nothing else has
        whole = usable and det is not None and det.bbox is not None and not box_cut_by_border(det.bbox, det.width, det.height, self.p.border_px)
        events: tuple[str, ...] = ()
        bbox = Z_o = Z_d = centre = None
        evidence: tuple[float, np.ndarray | None] | None = None  # (view_shift, mean of the near ones): once a tick
        if det is not None and usable:
            O_box, r, z_c = self._object_from(det, pose)
            O: np.ndarray | None = O_box
            if whole:
                self.evidence.append((pose.copy(), O_box))
                self.object_radius = r
            else:  # the visible part's floor point, not eq. 18 (module docstring)
                N = cut_box_near_point(cast(Any, det.bbox), det.width, det.height, self.p.border_px, det.intrinsics,
                                       self.T_body_camera)
                O = planar_apply(pose, N) if N is not None else None
            follows = self.p.target_update != "first"
            anchor = not MEM_OBJECT.present(self.memory) or (follows and (whole or self.anchored_by_cut))
            if O is not None and whole and self.p.target_update == "evidence":
                evidence = self._evidence_at(pose)
                O = evidence[1]  # the detection just stored is among the near ones: never None here
            if O is not None and anchor:
                if not MEM_OBJECT.present(self.memory):
                    MEM_FIRST.set(self.memory, {"t": obs.t, "camera": self.camera})
                self.anchored_by_cut = not whole
                MEM_OBJECT.set(self.memory, O)
                if follows:
                    self.theta_f = None
                self.target = None
            bbox = np.asarray(det.bbox, dtype=float)
            Z_o = float(det.depth) if det.depth is not None else None
            if self.p.mode == "mgbm" and self.p.object_size is not None:
                # MGBM-YOLO knows the object: half-width and centre height from its size
                r, z_c = 0.5 * self.p.object_size[0], 0.5 * self.p.object_size[1]
            if self.p.desired_centre is not None:
                centre = np.asarray(self.p.desired_centre, dtype=float)
            else:
                try:
                    centre = desired_centre(self.goal, r, z_c, det.intrinsics, self.T_body_camera)
                except ValueError:
                    centre = None
            if centre is not None:
                if self.p.mode == "mgbm":
                    Z_d = self._goal_depth(r, z_c)
                elif self.p.zd == "pixel":
                    Z_d = det.depth_at(float(centre[0]), float(centre[1]))  # eq. 19 as printed: (O_du, O_dv)
                else:  # eq. 19 with eq. 17's rule: the current box moved to the desired centre
                    hw, hh = 0.5 * (bbox[2] - bbox[0]), 0.5 * (bbox[3] - bbox[1])
                    Z_d = det.depth_in((centre[0] - hw, centre[1] - hh, centre[0] + hw, centre[1] + hh))
            self.last_detection_t = det.stamp
        if self.target is None and MEM_OBJECT.present(self.memory):
            self._set_target(pose)
        out = viki_velocity(
            ServoInputs(pose=pose, detected=bool(usable), bbox=bbox, Z_o=Z_o, Z_d=Z_d, centre=centre,
                        target=self.target, reverse=self.reverse, v_prev=self.v_prev),
            intrinsics=det.intrinsics if det is not None else (1.0, 1.0, 0.0, 0.0),
            T_body_camera=self.T_body_camera, lam=self.lam, k1=self.k1, d=self.d, wheelbase=self.wheelbase, v_max=self.v_max,
            psi_max=self.psi_max, mode=self.p.mode, object_size=self.p.object_size, smoothing=self.p.smoothing,
            direction=self.direction)
        # the object (memory) in the robot frame, once per tick: for the keep-out and the object_x/y metrics
        object_robot = planar_apply_inverse(pose, MEM_OBJECT(self.memory)) if MEM_OBJECT.present(self.memory) else None
        if object_robot is not None:
            v_safe = keep_out_speed(out.v_cmd, self.p.keep_out_body, object_robot, self.object_radius,
                                    self.p.keep_out_margin)
            if v_safe != out.v_cmd:  # backing away: the applied twist is the reversed one (eq. 26's memory)
                out = replace(out, v_cmd=v_safe, V=-out.V)
        self.last = out
        self.v_prev = out.V
        if out.v_cmd != 0.0:
            self.direction = math.copysign(1.0, out.v_cmd)
        if out.feature_error is not None:
            self.last_feature_error = out.feature_error
        metrics: dict[str, float] = {"detected": 1.0 if out.used_vs else 0.0, "v_cmd": out.v_cmd,
                                     "speed": abs(float(keys.SPEED(obs)))}
        metrics.update(zip(_CAM_KEYS, (self._cam_twist @ out.V).tolist()))
        if self.last_feature_error is not None:
            metrics["feature_error"] = self.last_feature_error
        if self.last_detection_t is not None:
            metrics["detection_age"] = obs.t - self.last_detection_t
        if self.target is not None:
            h = planar_apply(pose, (self.d_point, 0.0))  # the controlled point, eq. 1
            metrics["pos_error"] = float(np.hypot(*(self.target - h)))
        if self.evidence:
            shift, mean = evidence if evidence is not None else self._evidence_at(pose)
            metrics["view_shift"] = shift
            if mean is not None:
                metrics["goal_error"] = float(np.hypot(*goal_offset(pose, mean, self.goal)))
        if object_robot is not None:
            metrics["object_x"], metrics["object_y"] = object_robot.tolist()
        elif obs.t - self.t0 >= self.p.search_timeout - 1e-9:
            events = ("no_target",)
        command = {"v": np.array([out.v_cmd]), "steer": np.array([out.psi])}
        return StepResult(command=command, metrics=metrics, events=events, sensors=self._sensors)

    def _evidence_at(self, pose: np.ndarray) -> tuple[float, np.ndarray | None]:
        """The settle rule's evidence at ``pose``: the view shift since the latest stored whole detection, and the
        mean object position (odometry frame) of those taken within ``evidence_window`` of view shift of ``pose``
        (None: none is) — what ``goal_error`` reads and ``target_update: evidence`` anchors the object on."""
        shifts = view_shifts([P for P, _ in self.evidence], pose, self.goal)
        near = [O for (_, O), shift in zip(self.evidence, shifts) if shift < self.p.evidence_window]
        return float(shifts[-1]), (np.asarray(np.mean(near, axis=0), dtype=float) if near else None)

    def _goal_depth(self, r: float, z_c: float) -> float:
        """MGBM's desired depth: camera Z of the object's box-centre point at the goal."""
        G = self.goal
        cam = self.T_body_camera[:2, 3]
        u = G - cam
        u = u / max(float(np.hypot(*u)), 1e-9)
        P = np.array([*(G - r * u), z_c])
        return float((self.T_body_camera[:3, :3].T @ (P - self.T_body_camera[:3, 3]))[2])
