"""``viki_ground``: the racecar, a floor and one waste-like object — the world of the ViKi-HyCo missions.

Scene: :class:`taskflow_sim.ground.flat_ground.FlatGround` (racecar on a thin box floor, odometry with optional noise)
plus one static object (:mod:`taskflow_sim.viki_objects`: ``can``, ``bottle`` or ``carton``) placed relative to the
start pose (``object_distance`` / ``object_bearing`` from the rear-axle midpoint, heading-relative) or at
world ``object_xy``.  Missions draw these from distributions (``{uniform: [...]}``, ``{choice: [...]}``),
so a batch is a Monte Carlo campaign.

Perception (``perception: geometric | rendered``, :mod:`taskflow_sim.perception_geometric`,
:mod:`taskflow_sim.perception_rendered`) fills ``obs.sensors["detection"]`` with a
:class:`taskflow.messages.Detection` of the **active camera** at the camera's rate (15 Hz by default; the
control runs at the mission's rate and sees the latest frame with ``fresh = False`` in between).  In
``rendered`` mode ``obs.sensors["image"]`` is that frame's colour image, the one the detector was given (a
:class:`taskflow.messages.Image` stamped with its capture time, frame ``front_camera`` / ``rear_camera``;
no extra rendering), under the same rule as the detection: only the active camera's, none before its first frame.

Active camera: chosen by the running task, which names the mount it reads in its step result
(``StepResult.sensors``, e.g. ``("rear_camera",)``; the runtime passes it to :meth:`VikiGround.select_sensors`);
a task that names none (``None``) or no task keeps the current one (so a task-less "searching" state keeps
looking); ``()`` switches perception off (the kinematic rotation state: nothing is rendered).
``initial_camera`` is the one used before the first task names one.  Only the
active camera is processed: in ``rendered`` mode one ``getCameraImage`` per frame (plus the LiDAR at its
own rate for the front camera).

Events: ``target_found`` / ``target_lost`` when the active camera's detection (after dropout) appears /
disappears from one frame to the next (the first frame of a camera emits ``target_found`` if it sees the
object).

Ground truth (trace columns): robot pose ``x, y, yaw, v`` (rear-axle midpoint), ``obj_x, obj_y`` (the
object's base centre in the robot frame), ``err_x, err_y`` (that minus the manipulation-zone ``goal``),
``detected`` (last frame, after dropout) and ``camera`` (0 none, 1 front, 2 rear).

``summary_metrics()``: ``final_error_x_m``, ``final_error_y_m``, ``final_error_m`` (object in the robot
frame at the end minus ``goal``), detection counts (``frames``, ``detections``, ``detections_missed`` —
frames the dropout model dropped while the object was in view, ``dropout_fraction``), motion statistics
(``v_sign_changes``, ``v_sign_changes_last_5s``, ``path_length_m``), the object's kind and placement,
and from the ground truth at every control tick (:mod:`taskflow_sim.viki_clearance`) ``min_clearance_m``
— the smallest distance over the run between the car's body footprint and the object's footprint, 0
when they touched — and ``contact`` (they ever touched: footprints overlapping or a PyBullet contact).
The wall-clock cost of each frame's perception is reported as the observation's ``timings["perception"]``
(``timing.json``: ``world.perception``), never in the summary.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any, ClassVar, Literal, cast

import numpy as np
import pybullet as p
from pydantic import BaseModel, Field, model_validator
from taskflow_robots.racecar import CameraMount
from taskflow_sim.core.bodies import BodyOptions, make_body
from taskflow_sim.core.odometry_slip import SlipOdometry
from taskflow_sim.core.stepped import SensorSchedule
from taskflow_sim.ground.flat_ground import FlatGround, FlatGroundParams
from taskflow_sim.perception_common import CameraModel, DropoutModel
from taskflow_sim.perception_geometric import GeometricPerception
from taskflow_sim.perception_rendered import LidarScanner, RenderedPerception
from taskflow_sim.viki_clearance import Footprint, footprint_clearance, measure_footprint
from taskflow_sim.viki_objects import SHAPES, PlacedObject, create_body

from taskflow.api import Marker, Observation, ObsSpec, Robot, RobotNeeds, message, text
from taskflow.fidelity import Fidelity, Level, Sourced
from taskflow.messages import Detection, Image
from taskflow.registry import register_world
from taskflow.spatial import rotation_from_unit_quaternion, transform

CAMERA_CODE = {None: 0.0, "front": 1.0, "rear": 2.0}


class VikiGroundParams(Fidelity, FlatGroundParams):
    """Object placement, manipulation-zone goal, perception mode and detector model (see module doc)."""

    object_kind: Literal["can", "bottle", "carton"] = Field(default="can", description="the object to approach")
    object_distance: float = Field(default=2.2, ge=0.5, le=10.0, description="m from the start rear-axle midpoint: "
                                   "0.5 (nearer, the object is under the car's front, below the cameras' view, which "
                                   "starts ~0.45 m ahead) to 10, and within the depth camera's range depth_max")
    object_bearing: float = Field(default=0.0, ge=-2.0 * math.pi, le=2.0 * math.pi,
                                  description="rad, relative to the start heading (pi: behind): one turn either way")
    object_xy: tuple[float, float] | None = Field(default=None, description="world position; overrides distance/bearing")
    object_yaw: float = Field(default=0.0, ge=-2.0 * math.pi, le=2.0 * math.pi, description="rad: one turn either way")
    goal: tuple[float, float] = Field(default=(-0.9, 0.0),
                                      description="manipulation zone: object position in the robot frame (m); "
                                      "within depth_max of the robot (the cameras must measure it there)")
    perception: Literal["geometric", "rendered"] = Field(default="geometric", description="geometric: boxes "
                                                         "projected from the truth with the noise below (fast); "
                                                         "rendered: a colour detector on rendered frames")
    initial_camera: Literal["front", "rear", "none"] = Field(default="front", description="the camera that runs "
                                                             "until a task selects its own")
    image_size: tuple[int, int] | None = Field(default=None, description="(W, H) for every camera; default: the "
                                               "mounts'; each 8-4096 px (TinyRenderer's largest image)")
    camera_rate_hz: float | None = Field(default=None, ge=1.0, le=90.0, description="default: the mounts' rate; 1-90 "
                                         "Hz, what RGB-D cameras deliver (the RealSense D435i: 6 to 90 fps); below 1 Hz "
                                         "the 20 Hz laws act on one frame for 20 ticks and the car covers v_max x 1 s "
                                         "between two detections")
    depth_max: float = Field(default=5.0, gt=0.0, le=10.0, description="depth camera range (m): at most 10, the "
                             "RealSense D435i's")
    pixel_noise: float = Field(default=0.5, ge=0.0, le=20.0, description="std of each box edge (px), geometric mode: "
                               "at most 20 px, a third of the ~60 px box of the object at 2 m in the default 640x360 "
                               "image (the paper's level: 2 px at 1280x720)")
    depth_noise: float = Field(default=0.005, ge=0.0, le=0.2, description="relative std of the depth per frame, "
                               "geometric mode: at most 0.2 (10 times the RealSense's 2 % at 2 m)")
    min_pixels: int = Field(default=4, ge=1, le=10_000, description="fewer visible object pixels: no detection; "
                            "1-10000 (the object at 2 m covers ~3000 px of the default image)")
    dropout: float = Field(default=0.0, ge=0.0, lt=1.0, description="fraction of frames the detector misses: below 1 "
                           "(a detector that misses every frame sees nothing)")
    dropout_burst: float = Field(default=1.0, ge=1.0, le=150.0, description="mean length of a miss burst (frames): "
                                 "1 to 150 (10 s at 15 fps, longer than the tasks' search timeouts: a longer miss is "
                                 "the object gone, not detector noise)")
    static_motion_m: float = Field(default=0.001, ge=0.0, le=0.1, description="camera still below this (m): same "
                                   "image; at most 0.1")
    static_motion_rad: float = Field(default=0.002, ge=0.0, le=0.1, description="camera still below this (rad); at most 0.1")
    static_flip: float = Field(default=0.01, ge=0.0, le=1.0,
                               description="chance per frame that a still image changes outcome (sensor noise)")
    lidar_fusion: bool = Field(default=True, description="rendered front camera: fuse the LiDAR (eq. 11-15)")
    latency: float = Field(default=0.0, ge=0.0, le=1.0,
                           description="s from a frame's capture until its detection is delivered (stamped at capture): "
                           "at most 1 s; the visual-servo loop with the paper's largest gain (lambda = 1.05 /s) and a "
                           "delay tau is stable only while lambda tau < pi/2 (1.5 s)")
    box_bias: tuple[float, float, float, float] = Field(
        default=(0.0, 0.0, 0.0, 0.0), description="px added to every detected box's (u0, v0, u2, v2): a systematic "
        "detector offset (negative u0/v0 and positive u2/v2 make boxes larger); each within ±50 px")
    odom_scale_error: float = Field(default=0.0, ge=-0.5, le=0.5,
                                    description="fraction: odometry distance = true distance x (1 + this); within "
                                    "±0.5 (F-LOAM's is ~0.01; wheel odometry off by more is broken)")
    odom_slip: float = Field(default=0.0, ge=0.0, le=0.5,
                             description="std of the per-tick relative error of the odometry's travel (fraction): at most 0.5")

    FIDELITY: ClassVar[Mapping[str, Level]] = {"paper": {
        "image_size": Sourced((1280, 720), "paper section III-A: both RealSense D435i cameras at 1280x720"),
        "camera_rate_hz": Sourced(15.0, "paper section III-A: both cameras at 15 fps"),
        "latency": Sourced(0.044, "paper Table 1 / section III-G: one iteration takes 44 ms (YOLOv5 detection 12 "
                           "ms + interpolated point cloud and LiDAR-camera fusion 30 ms + control law 2 ms), so a "
                           "frame's box reaches the control law 44 ms after its capture"),
        "pixel_noise": Sourced(2.0, "derived: YOLOv5 boxes of [38] (section II-D) reach mAP@.5:.95 ~0.84, i.e. an "
                               "IoU ~0.9 with the true box; on the paper's 1280x720 images a 60-160 px box at 1-2.6 m "
                               "then has edges off by ~2-3 % of its size: std 2 px per edge"),
        "box_bias": Sourced((-1.0, -1.0, 1.0, 1.0), "assumption (the paper does not evaluate the detector: section "
                            "III-A): YOLO boxes drawn 1 px loose on each side at 1280x720; bounded by [38]'s "
                            "localisation error < 0.25 m (section II-D), which it meets by two orders of magnitude"),
        "depth_noise": Sourced(0.02, "Intel RealSense D435i datasheet: depth RMS error <= 2 % at 2 m (the paper's "
                               "cameras, section III-A)"),
        "odom_scale_error": Sourced(0.01, "paper section II-A: LiDAR odometry by F-LOAM [32]; F-LOAM's KITTI relative "
                                    "translation error 0.51-1.25 % (sequences 00/02/05, the F-LOAM repository's "
                                    "README): 1 % scale error"),
        "odom_slip": Sourced(0.005, "same F-LOAM figures: their spread (0.51-1.25 %) as a random per-tick part"),
    }}

    @model_validator(mode="after")
    def _check(self) -> VikiGroundParams:
        if self.image_size is not None and not (min(self.image_size) >= 8 and max(self.image_size) <= 4096):
            raise ValueError(f"image_size must be 8 to 4096 pixels each way, got {self.image_size}")
        if max(abs(b) for b in self.box_bias) > 50.0:
            raise ValueError(f"box_bias must stay within ±50 px per edge, got {self.box_bias}")
        if math.hypot(*self.goal) > self.depth_max:
            raise ValueError(f"goal {list(self.goal)} is {math.hypot(*self.goal):g} m from the robot, beyond the depth "
                             f"camera's range depth_max ({self.depth_max:g} m)")
        if self.object_xy is None and self.object_distance > self.depth_max:
            raise ValueError(f"object_distance ({self.object_distance:g} m) is beyond the depth camera's range "
                             f"depth_max ({self.depth_max:g} m): the object could never be measured")
        return self


def object_position(wp: VikiGroundParams) -> tuple[float, float]:
    """Where the object is placed: ``object_xy``, or ``object_distance`` / ``object_bearing`` from the start
    pose (heading-relative)."""
    if wp.object_xy is not None:
        return float(wp.object_xy[0]), float(wp.object_xy[1])
    sx, sy, syaw = wp.start
    a = syaw + wp.object_bearing
    return sx + wp.object_distance * math.cos(a), sy + wp.object_distance * math.sin(a)


@register_world("viki_ground")
class VikiGround(FlatGround):
    """Racecar + one object + front/rear RGB-D cameras (+ LiDAR) with a detector."""

    Params: ClassVar[type[VikiGroundParams]] = VikiGroundParams  # type: ignore[assignment]

    @classmethod
    def rate_problem(cls, params: BaseModel, robot_params: BaseModel | None, rate_hz: float) -> tuple[str, str] | None:
        """A camera faster than the control rate: frames are taken at control ticks (:class:`SensorSchedule`,
        one per tick at most), so it would silently run at ``rate_hz`` instead (15 fps with the missions'
        20 Hz is fine: 3 frames in 4 ticks)."""
        wp = cast(VikiGroundParams, params)
        rates = {m: float(wp.camera_rate_hz) if wp.camera_rate_hz is not None else
                 float(getattr(getattr(robot_params, m, None), "rate_hz", 0.0)) for m in ("front_camera", "rear_camera")}
        fast = {m: r for m, r in rates.items() if r > rate_hz * (1.0 + 1e-9)}
        if not fast:
            return None
        which = ", ".join(f"{m} {r:g} Hz" for m, r in fast.items())
        return (f"camera rate above the control rate_hz {rate_hz:g} Hz ({which}): world {cls.name!r} takes at most one "
                f"frame per control tick, so the camera would run at {rate_hz:g} Hz, not its own rate",
                f"a camera rate of at most {rate_hz:g} Hz (world.params.camera_rate_hz or the mounts' rate_hz), "
                "or a control rate_hz at least the camera's")
    events: ClassVar[tuple[str, ...]] = ("target_found", "target_lost")
    ground_truth_keys: ClassVar[tuple[str, ...]] = ("x", "y", "yaw", "v", "obj_x", "obj_y", "err_x", "err_y",
                                                    "detected", "camera")
    needs: ClassVar[RobotNeeds] = RobotNeeds(
        sensors={"front_camera": "rgbd_camera", "rear_camera": "rgbd_camera", "lidar": "lidar"}, body=True)
    observations: ClassVar[dict[str, ObsSpec]] = {"sensors.detection": message(Detection),
                                                  "sensors.camera": text(optional=True),
                                                  "sensors.image": message(Image)}  # rendered mode only

    params: VikiGroundParams

    def __init__(self, robot: Robot, params: VikiGroundParams, seed: int, gui: bool = False) -> None:
        if not isinstance(params, VikiGroundParams):
            raise TypeError(f"viki_ground needs VikiGround.Params, got {type(params).__name__}")
        super().__init__(robot, params, seed, gui)
        self._init_state()

    def _init_state(self) -> None:
        self.object: PlacedObject | None = None
        self.object_body = -1
        self.cameras: dict[str, CameraModel] = {}
        self._perceptors: dict[str, Any] = {}
        self._lidar: LidarScanner | None = None
        self._dropout: DropoutModel | None = None
        self._active: str | None = None
        # frames of the active camera on a fixed grid from its stream's start, at its rate (set in _populate
        # and on every switch; 15 Hz camera, 20 Hz control: 3 frames in 4 ticks)
        self._frame_schedule = SensorSchedule(1.0)
        self._frame = 0
        self._last: Detection | None = None
        self._image: Image | None = None  # rendered mode: the colour image of the frame of ``_last``
        self._last_detected: bool | None = None
        self._events: list[str] = []
        self.frames = 0
        self.first_detection_t: float | None = None
        self.detections = 0
        self.missed = 0
        self._v_trace: list[tuple[float, float]] = []
        self._path = 0.0
        self._last_xy: tuple[float, float] | None = None
        self._footprint: Footprint | None = None
        self._pending: list[tuple[Detection, Image | None]] = []  # latency > 0: frames not delivered yet
        self._slip: SlipOdometry | None = None
        self.min_clearance = math.inf
        self.contact = False

    # --- scene ---------------------------------------------------------------------------------
    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """The start pose and the object (with its footprint radius) as placed."""
        wp = cast(VikiGroundParams, params)
        x, y = object_position(wp)
        return [*super().scene(wp), Marker.point("object", f"object ({wp.object_kind})", x, y,
                                                 radius=SHAPES[wp.object_kind].footprint_radius())]

    def _populate(self) -> None:
        self._init_state()
        wp, rp = self.params, self.robot.params
        ox, oy = object_position(wp)
        self.object = PlacedObject(SHAPES[wp.object_kind], float(ox), float(oy), float(wp.object_yaw))
        scene = self._require_scene()
        self.object_body = create_body(scene.client, self.object)
        self._footprint = measure_footprint(make_body(self.robot, BodyOptions()))
        mounts: dict[str, CameraMount] = {"front": rp.front_camera, "rear": rp.rear_camera}
        for name in ("front", "rear"):
            m = mounts[name]
            if wp.image_size is not None:
                m = m.model_copy(update={"width": int(wp.image_size[0]), "height": int(wp.image_size[1])})
            if wp.camera_rate_hz is not None:
                m = m.model_copy(update={"rate_hz": float(wp.camera_rate_hz)})
            self.cameras[name] = CameraModel(name, m, m.width, m.height, wp.depth_max)
        # one generator for the detector, independent of the odometry noise stream
        det_rng = np.random.default_rng([self.seed, 0x7A1])
        self._det_rng = det_rng
        self._dropout = DropoutModel(det_rng, wp.dropout, wp.dropout_burst, wp.static_motion_m,
                                     wp.static_motion_rad, wp.static_flip)
        self._active = None if wp.initial_camera == "none" else wp.initial_camera
        self._frame_schedule.restart(0.0, self.cameras[self._active or "front"].mount.rate_hz)
        if wp.odom_scale_error != 0.0 or wp.odom_slip > 0.0:  # its own stream: the ideal runs draw nothing
            self._slip = SlipOdometry(np.random.default_rng([self.seed, 0x511]), wp.odom_scale_error, wp.odom_slip)
            self._slip.reset(np.asarray(scene.car.pose(), dtype=float))

    def _perceptor(self, name: str) -> Any:
        per = self._perceptors.get(name)
        if per is None:
            scene = self._require_scene()
            cam = self.cameras[name]
            obj = self._require_object()
            if self.params.perception == "geometric":
                per = GeometricPerception(scene.client, cam, obj, self.object_body, self._det_rng,
                                          self.params.pixel_noise, self.params.depth_noise, self.params.min_pixels)
            else:
                lidar = None
                if name == "front" and self.params.lidar_fusion:
                    if self._lidar is None:
                        self._lidar = LidarScanner(scene.client, self.robot.params.lidar, scene.car.body)
                    lidar = self._lidar
                per = RenderedPerception(scene.client, cam, self.object_body, self.params.min_pixels, lidar)
            self._perceptors[name] = per
        return per

    def _require_object(self) -> PlacedObject:
        if self.object is None:
            raise RuntimeError("viki_ground: call reset() before using the world")
        return self.object

    def T_world_robot(self) -> np.ndarray:
        """World ← robot (rear-axle midpoint) 4x4 from the simulator (full 3-D, ground truth)."""
        pos, q = self._require_scene().car._base_frame()
        return transform(rotation_from_unit_quaternion(q), pos)

    # --- the loop --------------------------------------------------------------------------------
    def observe(self) -> Observation:
        obs = super().observe()
        if self._slip is not None:  # drifting odometry; FlatGround's white noise (if any) stays on top
            true = np.asarray(self._require_scene().car.pose(), dtype=float)
            pose = np.asarray(obs.state["pose"], dtype=float)
            obs.state["pose"] = self._slip.update(true) + (pose - true)
        v = float(obs.state["v"])  # FlatGround's measured speed is the simulator's (no noise on it)
        self._v_trace.append((self.t, v))
        x, y, yaw = self._require_scene().car.pose()
        self._track_clearance((float(x), float(y), float(yaw)))
        if self._last_xy is not None:
            self._path += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
        self._last_xy = (float(x), float(y))
        if self._active is not None and self._frame_schedule.due(self.t):
            obs.timings = {"perception": self._new_frame(self._active)}
            if self.params.latency > 0.0:
                self._deliver()
        elif self.params.latency > 0.0:
            self._deliver()
        elif self._last is not None and self._last.fresh:
            self._last = self._last.stale()
        if self._active is not None and self._last is not None and self._last.camera == self._active:
            obs.sensors["detection"] = self._last
            if self._image is not None:
                obs.sensors["image"] = self._image
        obs.sensors["camera"] = self._active
        obs.events = tuple(self._events)
        self._events = []
        return obs

    def _track_clearance(self, pose: tuple[float, float, float]) -> None:
        """Ground truth, once per control tick: the footprint clearance to the object, and whether the two
        bodies touch (a PyBullet contact point between them counts even where the footprint misses it,
        e.g. a steered front wheel: the clearance is then 0)."""
        scene = self._require_scene()
        assert self._footprint is not None
        d = footprint_clearance(self._footprint, pose, self._require_object())
        if p.getContactPoints(scene.car.body, self.object_body, physicsClientId=scene.client):
            d = 0.0
        self.min_clearance = min(self.min_clearance, d)
        self.contact = self.contact or d == 0.0

    def _new_frame(self, name: str) -> float:
        """Capture and detect on camera ``name``; returns the wall-clock seconds perception took."""
        cam = self.cameras[name]
        T_world_robot = self.T_world_robot()
        T_world_camera = cam.pose(T_world_robot)
        t0 = time.perf_counter()
        per = self._perceptor(name)
        if self.params.perception == "geometric":
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera)
        else:
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera, self.t, T_world_robot)
        perception_s = time.perf_counter() - t0
        image = None
        if self.params.perception == "rendered":  # the image the detector got (a view: nothing copied)
            image = Image(stamp=self.t, frame=f"{name}_camera", pixels=per.last_rgb)
            if self.params.latency <= 0.0:
                self._image = image
        if bbox is not None and any(self.params.box_bias):
            bbox = biased_box(bbox, self.params.box_bias, cam.width, cam.height)
        dropped = self._dropout.frame(T_world_camera) if self._dropout is not None else False
        self.frames += 1
        if bbox is not None:
            if dropped:
                self.missed += 1
                bbox, depth = None, None
            else:
                self.detections += 1
                if self.first_detection_t is None:
                    self.first_detection_t = self.t
        self._frame_schedule.fire(self.t)
        self._frame += 1
        det = Detection(stamp=self.t, frame=f"{name}_camera", camera=name, seq=self._frame, bbox=bbox, depth=depth,
                        intrinsics=cam.intrinsics, width=cam.width, height=cam.height, depth_at=depth_at,
                        depth_in=depth_in)
        if self.params.latency > 0.0:
            self._pending.append((det, image))
        else:
            self._publish(det)
        return perception_s

    def _publish(self, det: Detection) -> None:
        """``det`` becomes the detection the task sees (events on a change of outcome)."""
        self._last = det
        detected = det.detected
        if detected != self._last_detected and (self._last_detected is not None or detected):
            self._events.append("target_found" if detected else "target_lost")
        self._last_detected = detected

    def _deliver(self) -> None:
        """Latency: publish the newest pending frame captured at least ``latency`` ago (older ones are
        superseded, as a detector's queue of one); otherwise the last delivered one goes stale."""
        due = [i for i, (d, _) in enumerate(self._pending) if d.stamp + self.params.latency <= self.t + 1e-9]
        if not due:
            if self._last is not None and self._last.fresh:
                self._last = self._last.stale()
            return
        det, image = self._pending[due[-1]]
        del self._pending[:due[-1] + 1]
        self._publish(det)
        if image is not None:
            self._image = image

    def select_sensors(self, names: tuple[str, ...]) -> None:
        """The active state's task names the camera mount it reads (``("front_camera",)``); ``()``: none.
        Only that camera is processed; the LiDAR goes with the front camera (eq. 11-15)."""
        cams = [n[:-len("_camera")] for n in names if n.endswith("_camera")]
        unknown = [n for n in names if n != "lidar" and not (n.endswith("_camera") and n[:-len("_camera")] in self.cameras)]
        if unknown or len(cams) > 1:
            raise ValueError(f"viki_ground runs one camera at a time of {', '.join(f'{c}_camera' for c in self.cameras)}"
                             f" (and the lidar); a task asked for {', '.join(names)}")
        active = cams[0] if cams else None
        if active != self._active:
            self._active = active
            self._last = None
            self._image = None
            self._pending = []
            self._last_detected = None
            if active is not None:  # first frame of the new camera at the next observation
                self._frame_schedule.restart(self.t, self.cameras[active].mount.rate_hz)
            if self._dropout is not None:
                self._dropout.reset()

    def object_in_robot_frame(self) -> tuple[float, float]:
        """Ground truth: object base centre in the robot frame (m)."""
        obj = self._require_object()
        x, y, yaw = self._require_scene().car.pose()
        dx, dy = obj.x - x, obj.y - y
        c, s = math.cos(yaw), math.sin(yaw)
        return float(c * dx + s * dy), float(-s * dx + c * dy)

    def ground_truth(self) -> dict[str, float]:
        gt = super().ground_truth()
        ox, oy = self.object_in_robot_frame()
        gx, gy = self.params.goal
        gt.update({"obj_x": ox, "obj_y": oy, "err_x": ox - gx, "err_y": oy - gy,
                   "detected": 1.0 if (self._last is not None and self._last.detected) else 0.0,
                   "camera": CAMERA_CODE.get(self._active, 0.0)})
        return gt

    def summary_metrics(self) -> dict[str, Any]:
        out = super().summary_metrics()
        ox, oy = self.object_in_robot_frame()
        gx, gy = self.params.goal
        obj = self._require_object()
        ts = np.array([t for t, _ in self._v_trace]) if self._v_trace else np.zeros(0)
        vs = np.array([v for _, v in self._v_trace]) if self._v_trace else np.zeros(0)
        out.update({
            "final_error_x_m": ox - gx,
            "final_error_y_m": oy - gy,
            "final_error_m": math.hypot(ox - gx, oy - gy),
            "object_x_m": ox,
            "object_y_m": oy,
            "object_kind": obj.shape.kind,
            "object_world_x_m": obj.x,
            "object_world_y_m": obj.y,
            "first_detection_s": self.first_detection_t,
            "frames": self.frames,
            "detections": self.detections,
            "detections_missed": self.missed,
            "dropout_fraction": self.missed / (self.detections + self.missed) if self.detections + self.missed else 0.0,
            "v_sign_changes": _sign_changes(vs),
            "v_sign_changes_last_5s": _sign_changes(vs[ts >= ts[-1] - 5.0]) if ts.size else 0,
            "path_length_m": self._path,
            "min_clearance_m": self.min_clearance if math.isfinite(self.min_clearance) else None,
            "contact": self.contact,
        })
        return out


def biased_box(bbox: tuple[float, float, float, float], bias: tuple[float, float, float, float], width: int,
               height: int) -> tuple[float, float, float, float]:
    """``bbox + bias`` (px, per edge) kept inside the image (edges ``-0.5 .. W - 0.5``) and ordered
    (an edge pushed past its opposite meets it)."""
    u0, v0, u2, v2 = (b + d for b, d in zip(bbox, bias))
    u0, u2 = min(max(u0, -0.5), width - 0.5), min(max(u2, -0.5), width - 0.5)
    v0, v2 = min(max(v0, -0.5), height - 0.5), min(max(v2, -0.5), height - 0.5)
    if u2 < u0:
        u0 = u2 = 0.5 * (u0 + u2)
    if v2 < v0:
        v0 = v2 = 0.5 * (v0 + v2)
    return (u0, v0, u2, v2)


def _sign_changes(v: np.ndarray, deadband: float = 0.01) -> int:
    """Reversals of the direction of travel, ignoring speeds below ``deadband`` (m/s)."""
    s = np.sign(v[np.abs(v) > deadband])
    return int(np.count_nonzero(s[1:] != s[:-1])) if s.size > 1 else 0
