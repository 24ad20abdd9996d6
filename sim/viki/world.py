"""``viki_ground``: the racecar, a floor and one waste-like object — the world of the ViKi-HyCo missions.

Scene: :class:`taskflow_sim.ground.flat_ground.FlatGround` (racecar on a thin box floor, odometry with optional noise)
plus one static object (:mod:`taskflow_sim.viki.scene`, :mod:`taskflow_sim.viki.objects`: ``can``, ``bottle``
or ``carton``) placed relative to the start pose or at world ``object_xy`` (parameters:
:mod:`taskflow_sim.viki.params`).  Missions draw these from distributions (``{uniform: [...]}``,
``{choice: [...]}``), so a batch is a Monte Carlo campaign.

Sensors (:mod:`taskflow_sim.viki.sensors`): ``obs.sensors["detection"]`` is the active camera's
:class:`taskflow.messages.Detection` at the camera's rate (15 Hz by default; the control runs at the mission's
rate and sees the latest frame with ``fresh = False`` in between); in ``rendered`` mode ``obs.sensors["image"]``
is that frame's colour image (frame ``front_camera`` / ``rear_camera``; no extra rendering), under the same
rule: only the active camera's, none before its first frame.

Active camera: chosen by the running task, which names the mount it reads in its step result
(``StepResult.sensors``, e.g. ``("rear_camera",)``; the runtime passes it to :meth:`VikiGround.select_sensors`);
a task that names none (``None``) or no task keeps the current one (so a task-less "searching" state keeps
looking); ``()`` switches perception off (the kinematic rotation state: nothing is rendered).
``initial_camera`` is the one used before the first task names one.  Only the
active camera is processed: in ``rendered`` mode one ``getCameraImage`` per frame (plus the LiDAR at its
own rate for the front camera).

Events: ``target_found`` / ``target_lost`` when the active camera's detection (after dropout) appears /
disappears from one frame to the next (the first frame of a camera emits ``target_found`` if it sees the
object); ``contact`` (ground truth, whatever the cameras see) in the control tick the car starts touching the
object — its footprint overlapping the object's or a PyBullet contact point between the two bodies, as
``contact`` in the summary — for a mission's property (``never: event(contact)``) or a transition.

Stepping and observing: the frames, their delivery, the odometry's drift and the ground-truth scoring
happen once per control tick in the stepping hook (:meth:`VikiGround.end_steps`, and once at ``reset`` for
t = 0); ``observe()`` only reads, so two calls in a row return equal observations.

Ground truth (trace columns): robot pose ``x, y, yaw, v`` (rear-axle midpoint), ``obj_x, obj_y`` (the
object's base centre in the robot frame), ``err_x, err_y`` (that minus the manipulation-zone ``goal``),
``detected`` (last frame, after dropout) and ``camera`` (0 none, 1 front, 2 rear).

``summary_metrics()`` (:mod:`taskflow_sim.viki.scoring`): ``final_error_x_m``, ``final_error_y_m``,
``final_error_m`` (object in the robot frame at the end minus ``goal``), detection counts (``frames``,
``detections``, ``detections_missed`` — frames the dropout model dropped while the object was in view,
``dropout_fraction``), motion statistics (``v_sign_changes``, ``v_sign_changes_last_5s``, ``path_length_m``),
the object's kind and placement, ``min_clearance_m`` and ``contact``.
The wall-clock cost of each frame's perception is reported as the observation's ``timings["perception"]``
(``timing.json``: ``world.perception``), never in the summary.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, cast

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from pydantic import BaseModel
from taskflow_robots.racecar import CameraMount, LidarMount
from taskflow_sim.core.bodies import BodyOptions, make_body
from taskflow_sim.core.odometry_slip import SlipOdometry
from taskflow_sim.ground.flat_ground import FlatGround
from taskflow_sim.viki.clearance import measure_footprint
from taskflow_sim.viki.objects import PlacedObject
from taskflow_sim.viki.params import VikiGroundParams
from taskflow_sim.viki.scene import camera_models, object_in_robot_frame, object_marker, place_object
from taskflow_sim.viki.scoring import CAMERA_CODE, ViKiScore, summary
from taskflow_sim.viki.sensors import VikiCameras

from taskflow.api import Marker, Observation, ObsSpec, Robot, RobotNeeds, message, text
from taskflow.messages import Detection, Image
from taskflow.registry import register_world
from taskflow.spatial import rotation_from_unit_quaternion, transform


class CameraRig(Protocol):
    """What ``viki_ground`` needs of a robot's parameters (the racecar's and the husky's have it)."""

    @property
    def front_camera(self) -> CameraMount: ...
    @property
    def rear_camera(self) -> CameraMount: ...
    @property
    def lidar(self) -> LidarMount: ...


class BaseFramed(Protocol):
    """A ground body that gives its robot frame's PyBullet pose (the racecar's and the husky's bodies)."""

    def _base_frame(self) -> tuple[tuple[float, ...], tuple[float, ...]]: ...


@register_world("viki_ground")
class VikiGround(FlatGround):
    """Racecar + one object + front/rear RGB-D cameras (+ LiDAR) with a detector."""

    Params: ClassVar[type[VikiGroundParams]] = VikiGroundParams

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

    events: ClassVar[tuple[str, ...]] = ("target_found", "target_lost", "contact")
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
        self.object: PlacedObject | None = None
        self.object_body = -1
        self._sensors: VikiCameras | None = None
        self._score: ViKiScore | None = None
        self._touch_started = False  # the car started touching the object in this control tick
        self._slip: SlipOdometry | None = None
        self._odometry: NDArray[np.float64] | None = None  # the drifting odometry's pose of the latest poll

    # --- scene ---------------------------------------------------------------------------------
    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """The start pose and the object (with its footprint radius) as placed."""
        wp = cast(VikiGroundParams, params)
        return [*super().scene(wp), object_marker(wp)]

    def _populate(self) -> None:
        wp, rp = self.params, self.robot.params
        scene = self._require_sim()
        self.object, self.object_body = place_object(scene.client, wp)
        footprint = measure_footprint(make_body(self.robot, BodyOptions()))
        rig = cast(CameraRig, rp)
        mounts: dict[str, CameraMount] = {"front": rig.front_camera, "rear": rig.rear_camera}
        self._sensors = VikiCameras(wp, camera_models(wp, mounts), scene.client, self.object, self.object_body,
                                    scene.car.body, rig.lidar, self.seed, self.T_world_robot)
        for name, stream in self._sensors.streams.items():  # declared: polled by the stepping base
            self.add_stream(f"{name}_camera", stream)
        self._score = ViKiScore(footprint, self.object)
        self._touch_started = False
        self._slip = None
        self._odometry = None
        if wp.odom_scale_error != 0.0 or wp.odom_slip > 0.0:  # its own stream: the ideal runs draw nothing
            self._slip = SlipOdometry(np.random.default_rng([self.seed, 0x511]), wp.odom_scale_error, wp.odom_slip)
            self._slip.reset(np.asarray(scene.car.pose(), dtype=float))
        # the ground truth and the readings at t = 0, seen by the first observation; FlatGround.reset then
        # starts the declared streams (the cameras' first frame)
        self._poll()

    @property
    def sensors(self) -> VikiCameras:
        """The cameras and their detector (after :meth:`reset`)."""
        if self._sensors is None:
            raise RuntimeError("viki_ground: call reset() before using the world")
        return self._sensors

    def _require_object(self) -> PlacedObject:
        if self.object is None:
            raise RuntimeError("viki_ground: call reset() before using the world")
        return self.object

    def T_world_robot(self) -> NDArray[np.float64]:
        """World ← robot (rear-axle midpoint) 4x4 from the simulator (full 3-D, ground truth)."""
        pos, q = cast(BaseFramed, self._require_sim().car)._base_frame()
        return transform(rotation_from_unit_quaternion(q), pos)

    # --- the loop --------------------------------------------------------------------------------
    def end_steps(self, n: int, h: float) -> None:
        super().end_steps(n, h)
        self._poll()  # then the stepping base polls the camera streams

    def _poll(self) -> None:
        """Once per control tick, before the camera streams' poll: the odometry's drift, the ground-truth
        scoring, the cameras' tick start."""
        scene = self._require_sim()
        car = scene.car
        true = np.asarray(car.pose(), dtype=float)
        if self._slip is not None:
            self._odometry = self._slip.update(true)
        v = float(car.proprioception()["v"])  # the measured speed is the simulator's (no noise on it)
        x, y, yaw = car.pose()
        touching = bool(p.getContactPoints(car.body, self.object_body, physicsClientId=scene.client))
        score = self._score
        assert score is not None
        touched_before = score.touching
        score.track(self.t, v, (float(x), float(y), float(yaw)), touching)
        self._touch_started = score.touching and not touched_before
        self.sensors.begin_tick()

    def observe(self) -> Observation:
        obs = super().observe()
        if self._odometry is not None:  # drifting odometry; FlatGround's white noise (if any) stays on top
            true = np.asarray(self._require_sim().car.pose(), dtype=float)
            pose = np.asarray(obs.state["pose"], dtype=float)
            obs.state["pose"] = self._odometry + (pose - true)
        sensors = self.sensors
        if sensors.timings:
            obs.timings = dict(sensors.timings)
        obs.sensors.update(sensors.readings())
        obs.events = sensors.events() + (("contact",) if self._touch_started else ())
        return obs

    def select_sensors(self, names: tuple[str, ...]) -> None:
        """The active state's task names the camera mount it reads (``("front_camera",)``); ``()``: none.
        Only that camera is processed; the LiDAR goes with the front camera (eq. 11-15)."""
        cameras = self.sensors.cameras
        cams = [n[:-len("_camera")] for n in names if n.endswith("_camera")]
        unknown = [n for n in names if n != "lidar" and not (n.endswith("_camera") and n[:-len("_camera")] in cameras)]
        if unknown or len(cams) > 1:
            raise ValueError(f"viki_ground runs one camera at a time of {', '.join(f'{c}_camera' for c in cameras)}"
                             f" (and the lidar); a task asked for {', '.join(names)}")
        self.sensors.select(cams[0] if cams else None, self.t)

    def object_in_robot_frame(self) -> tuple[float, float]:
        """Ground truth: object base centre in the robot frame (m)."""
        x, y, yaw = self._require_sim().car.pose()
        return object_in_robot_frame(self._require_object(), (x, y, yaw))

    def ground_truth(self) -> dict[str, float]:
        gt = super().ground_truth()
        ox, oy = self.object_in_robot_frame()
        gx, gy = self.params.goal
        stream = self.sensors.stream()
        last = stream.latest.value.detection if stream is not None and stream.latest and stream.latest.value else None
        gt.update({"obj_x": ox, "obj_y": oy, "err_x": ox - gx, "err_y": oy - gy,
                   "detected": 1.0 if (last is not None and last.detected) else 0.0,
                   "camera": CAMERA_CODE.get(self.sensors.active, 0.0)})
        return gt

    def summary_metrics(self) -> dict[str, Any]:
        out = super().summary_metrics()
        assert self._score is not None
        s = self.sensors
        out.update(summary(self._score, self.object_in_robot_frame(), self.params.goal, s.first_detection_t,
                           s.frames, s.detections, s.missed))
        return out
