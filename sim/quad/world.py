"""``quad_room``: the quadcopter in an indoor room with textured walls and column obstacles.

The world of the visual-path-following paper (Toro-Arcila et al., section 5): a forward camera is the
only sensor.  Each observation carries the latest rendered frame (at the camera's rate) and the
keyframe images of the visual path; no pose ever enters an observation.

* **Dynamics.**  The body ``[x, y, z, yaw]`` tracks the commanded body-frame ``[vx, vy, vz, wz]``
  through a first-order lag (robot ``tau``), integrated at ``physics_hz`` and moved kinematically
  (``resetBasePositionAndOrientation``); no rigid-body dynamics, no gravity.  ``command_response:
  relative_move`` executes each command as the Bebop 2 under ViSP does, a relative move of ``nu·Δt``
  (:mod:`taskflow_sim.quad.response`); ``command_delay_s`` and ``frame_latency_s`` make commands and
  frames late; ``fidelity: paper`` sets these from the paper and ViSP (``docs/missions.md``).
* **Keyframes (teach-by-showing).**  ``keyframes`` lists the taught poses ``{id, pose: [x, y, z,
  yaw]}``; on :meth:`reset` the world renders the camera image at each pose, or loads the images
  :func:`teach` stored in ``keyframe_dir``.  The poses serve only the ground-truth summary.
* **Collisions.**  The iris body's collision shapes against the obstacles and the room's slabs
  (walls, floor, ceiling) with ``getClosestPoints`` after every control step: a ``collision`` event
  when a contact starts, and ``collisions``, ``min_clearance_m`` … in the summary.
* **Path following accuracy.**  After every step the horizontal distance from the drone to the taught
  path (the polyline start → keyframe 0 → … → last keyframe) is measured; the summary has its maximum
  and mean (``path_deviation_max_m``, ``path_deviation_mean_m``) next to the flown ``path_length_m``.
* **Camera faults.**  ``blackout`` intervals return black frames (lost video or occlusion) so missions
  can exercise their lost-features handling.
* **Perception modes.**  ``perception: rendered`` (default, the faithful pipeline) puts the rendered
  frame in ``obs.sensors["image"]`` (an :class:`taskflow.messages.Image`) and the keyframe images in
  ``obs.sensors["keyframes"]`` (a tuple of them).  ``perception: geometric`` (fast, for tests and
  batches) renders nothing: landmarks on the room's surfaces are projected exactly
  (:mod:`taskflow_sim.quad.landmarks`) with ``pixel_noise``, so ``obs.sensors["points"]`` and
  ``obs.sensors["keyframe_points"]`` hold :class:`taskflow.messages.FeatureView`s (landmark ids and
  pixels) and ``obs.sensors["obstacle"]`` the widest column's :class:`taskflow.messages.Silhouette`
  at the middle row, or ``None``.  Current-frame messages are in the frame ``camera`` stamped with
  the capture time; keyframe ``k``'s in ``keyframe_k`` (the camera at its taught pose), stamped 0.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field, field_validator, model_validator
from taskflow_robots.quadcopter import Quadcopter, QuadcopterParams
from taskflow_sim.core.command_delay import CommandDelay
from taskflow_sim.core.faults import FaultIntervals, IntervalFault
from taskflow_sim.core.stepped import SensorSchedule, SteppedWorld, check_command
from taskflow_sim.quad.landmarks import column_silhouette, project, sample_landmarks, visible_landmarks
from taskflow_sim.quad.response import move_target, relative_move_step
from taskflow_sim.quad.scene import Column, QuadScene, Room

from taskflow.api import (
    Command,
    Marker,
    Observation,
    ObsSpec,
    Robot,
    RobotNeeds,
    StrictModel,
    message,
    scalar,
    sequence,
)
from taskflow.fidelity import Fidelity, Sourced
from taskflow.messages import FeatureView, Image, Silhouette
from taskflow.registry import register_world

Pose = tuple[float, float, float, float]


class KeyframeSpec(StrictModel):
    """One keyframe of a visual path: its index and the pose ``[x, y, z, yaw]`` (m, rad) it was
    taught at.  The pose is ground truth for the summary; the task sees only the image."""

    id: int = Field(ge=0, description="its index on the path: 0, 1, 2, ... in order")
    pose: tuple[float, float, float, float] = Field(description="[x, y, z, yaw] it was taught at (m, rad), inside the room")
    sigma: float | None = Field(default=None, gt=0.0, le=2.0, description="the obstacle reference width the "
                                "collision task uses at this keyframe (normalised), as its profile's sigma: 0 < sigma ≤ 2; "
                                "used by the control law, not by the world")


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


def load_keyframe_dir(path: str | Path) -> tuple[list[NDArray[np.uint8]], dict[str, Any]]:
    """Read the images and ``keyframes.json`` that :func:`teach` wrote; clear errors when missing or
    unreadable."""
    d = Path(path)
    meta_file = d / "keyframes.json"
    if not meta_file.is_file():
        raise ValueError(f"keyframe_dir {str(d)!r}: no keyframes.json (run `taskflow teach` first)")
    try:
        meta = json.loads(meta_file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{meta_file}: unreadable ({exc})") from exc
    images = []
    for k in meta.get("keyframes", []):
        f = d / k["image"]
        if not f.is_file():
            raise ValueError(f"keyframe image {str(f)!r} is missing")
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"keyframe image {str(f)!r} is unreadable (not an image OpenCV can decode)")
        images.append(img[:, :, ::-1].copy())
    return images, meta


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


@register_world("quad_room")
class QuadRoom(SteppedWorld[QuadScene]):
    """A textured room, green columns and the quadcopter with its forward camera."""

    Params: ClassVar[type[QuadRoomParams]] = QuadRoomParams
    events: ClassVar[tuple[str, ...]] = ("collision",)
    ground_truth_keys: ClassVar[tuple[str, ...]] = ("x", "y", "z", "yaw", "vx", "vy", "vz", "wz",
                                                    "obstacle_clearance", "wall_clearance")
    poses: ClassVar[dict[str, tuple[str, str, str | None]]] = {"robot": ("x", "y", "yaw")}
    needs: ClassVar[RobotNeeds] = RobotNeeds(interfaces=("body_velocity",), sensors={"camera": "rgb_camera"})
    observations: ClassVar[dict[str, ObsSpec]] = {  # geometric mode: points, obstacle; rendered: image, keyframes
        "sensors.frame_id": scalar(), "sensors.frame_t": scalar(), "sensors.points": message(FeatureView),
        "sensors.obstacle": message(Silhouette), "sensors.keyframe_points": sequence(optional=True, of=FeatureView),
        "sensors.image": message(Image), "sensors.keyframes": sequence(optional=True, of=Image)}

    params: QuadRoomParams

    @classmethod
    def scene(cls, params: BaseModel) -> list[Marker]:
        """The room's walls, the columns, the start pose and every taught keyframe pose."""
        wp = cast(QuadRoomParams, params)
        r = wp.room
        out = [Marker("boundary", "room walls", ((r.x0, r.y0), (r.x1, r.y0), (r.x1, r.y1), (r.x0, r.y1)), closed=True)]
        for i, o in enumerate(wp.obstacles):
            label = f"obstacle {i + 1}"
            out.append(Marker.box("obstacle", label, o.x, o.y, o.width, o.depth, o.yaw) if o.depth > 0.0
                       else Marker.point("obstacle", label, o.x, o.y, radius=o.width / 2))
        out.append(Marker.point("start", "start", wp.start[0], wp.start[1], yaw=wp.start[3]))
        out += [Marker.point("keyframe", f"keyframe {k.id}", k.pose[0], k.pose[1], yaw=k.pose[3]) for k in wp.keyframes]
        return out
    robot: Quadcopter

    def __init__(self, robot: Robot, params: QuadRoomParams, seed: int, gui: bool = False) -> None:
        if not isinstance(robot, Quadcopter):
            raise TypeError(f"world quad_room flies a quadcopter, got {type(robot).__name__}")
        super().__init__(robot, params, seed, gui)
        self.blackout = IntervalFault(params.blackout, "blackout")
        self._rng = np.random.default_rng(seed)
        self.columns: list[Column] = []
        self.landmarks = np.zeros((0, 3))
        self.taught_path = np.array([params.start[:2]] + [k.pose[:2] for k in params.keyframes], dtype=np.float64)
        self._init_state()

    def _init_state(self) -> None:
        self.restart_clock()
        self.camera_schedule = SensorSchedule(self.params.camera_rate_hz or self.robot.params.camera.rate_hz)
        self._lag = 1.0
        self.pose = np.asarray(self.params.start, dtype=np.float64).copy()
        self.vel = np.zeros(4)
        self.cmd = np.zeros(4)
        self._delay = CommandDelay(self.params.command_delay_s, self.cmd) if self.params.command_delay_s > 0.0 else None
        self._move_to: NDArray[np.float64] | None = None  # relative_move: the target of the move in progress
        self._move_dt = 0.0
        self._pose_log: list[tuple[float, NDArray[np.float64]]] = [(0.0, self.pose.copy())]  # frame latency
        self._frame = None
        self._frame_id = -1
        self._frame_t = -math.inf
        self._events: list[str] = []
        self._in_contact = False
        self.collisions = 0
        self.min_obstacle_clearance = math.inf
        self.min_wall_clearance = math.inf
        self._clear = (math.inf, math.inf)
        self.path_length = 0.0
        self._dev_sum, self._dev_n, self.max_path_deviation = 0.0, 0, 0.0
        self.keyframe_images: tuple[NDArray[np.uint8], ...] = ()
        self.keyframe_depths: list[NDArray[np.float64] | None] = []
        self.keyframe_points: tuple[FeatureView, ...] = ()
        self._points: FeatureView | None = None
        self._obstacle: Silhouette | None = None

    # --- lifecycle -----------------------------------------------------------------------------
    def reset(self) -> None:
        self.close()
        wp, rp = self.params, self.robot.params
        room = Room(wp.room.x0, wp.room.x1, wp.room.y0, wp.room.y1, wp.room.height)
        cols = [Column(o.x, o.y, o.width, o.depth, wp.obstacle_height, o.yaw) for o in wp.obstacles]
        self.scene = QuadScene.build(room, cols, seed=wp.texture_seed, camera=rp.camera, scale=rp.scale,
                                     gui=self.gui, texture_px_per_m=wp.texture_px_per_m)
        self._rng = np.random.default_rng(self.seed)
        # OpenCV's RANSAC draws from a process-global RNG: seed it so a seed reproduces a run whatever
        # ran before in the process
        cv2.setRNGSeed(int(self.seed))
        self._init_state()
        self.columns = cols
        self.landmarks = sample_landmarks(room, wp.landmark_density, np.random.default_rng(wp.texture_seed))
        if wp.perception == "geometric":
            self.keyframe_points = tuple(self._point_view(k.pose, 0.0, f"keyframe_{k.id}") for k in wp.keyframes)
        else:
            self._load_or_teach_keyframes()
        self.scene.set_drone_pose(*self.pose)
        self._check_contacts()

    def _load_or_teach_keyframes(self) -> None:
        wp = self.params
        scene = self._require_scene()
        cam = self.robot.params.camera
        if wp.keyframe_dir is not None:
            images, _ = load_keyframe_dir(wp.keyframe_dir)
            for i, img in enumerate(images):
                if img.shape[:2] != (cam.height, cam.width):
                    raise ValueError(f"keyframe {i} is {img.shape[1]}x{img.shape[0]}, the camera is {cam.width}x{cam.height}")
            self.keyframe_images = tuple(images)
            self.keyframe_depths = [self._depth_at(k.pose) for k in wp.keyframes]
        else:
            imgs, depths = [], []
            for k in wp.keyframes:
                rgb, depth = scene.render_with_depth(k.pose)
                imgs.append(rgb)
                depths.append(depth)
            self.keyframe_images = tuple(imgs)
            self.keyframe_depths = depths
        for img in self.keyframe_images:
            img.setflags(write=False)

    def _depth_at(self, pose: Sequence[float]) -> NDArray[np.float64]:
        return self._require_scene().render_with_depth(tuple(pose))[1]

    # --- the loop ------------------------------------------------------------------------------
    def _camera_at(self, pose: Sequence[float]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                                          tuple[int, int]]:
        """World ← optical rotation, camera position, intrinsics and image size at ``pose``."""
        cam = self.robot.params.camera
        R, t = cam.pose_in_world(pose)
        return R, t, cam.K(), (cam.width, cam.height)

    def _point_view(self, pose: Sequence[float], stamp: float, frame: str) -> FeatureView:
        """Landmarks seen from ``pose`` with this frame's pixel noise (geometric mode), as a message
        stamped ``stamp`` in ``frame``."""
        ids, uv = visible_landmarks(self.landmarks, self.columns, *self._camera_at(pose))
        if self.params.pixel_noise > 0.0:
            uv = uv + self._rng.normal(0.0, self.params.pixel_noise, uv.shape)
        uv.setflags(write=False)
        ids.setflags(write=False)
        return FeatureView(stamp=stamp, frame=frame, ids=ids, uv=uv)

    def _widest_column(self, pose: Sequence[float]) -> tuple[float, float, bool] | None:
        view = self._camera_at(pose)
        best = None
        for c in self.columns:
            s = column_silhouette(c, *view)
            if s is not None and (best is None or s[1] - s[0] > best[1] - best[0]):
                best = s
        return best

    def _capture(self) -> None:
        cam = self.robot.params.camera
        t, pose = self._seen()
        dark = self.blackout.active(t)
        self._frame_id += 1
        self._frame_t = t
        if self.params.perception == "geometric":
            empty = FeatureView(stamp=t, frame="camera", ids=np.zeros(0, dtype=np.int64), uv=np.zeros((0, 2)))
            self._points = empty if dark else self._point_view(pose, t, "camera")
            edges = None if dark else self._widest_column(pose)
            self._obstacle = None if edges is None else Silhouette(stamp=t, frame="camera", u_left=edges[0],
                                                                   u_right=edges[1], touches_border=edges[2])
            return
        if dark:
            img = np.zeros((cam.height, cam.width, 3), dtype=np.uint8)
        else:
            img = self._require_scene().render(tuple(pose))
            if self.params.image_noise > 0.0:
                noisy = img.astype(np.float32) + self._rng.normal(0.0, self.params.image_noise, img.shape)
                img = np.clip(noisy, 0, 255).astype(np.uint8)
        img.setflags(write=False)
        self._frame = Image(stamp=t, frame="camera", pixels=img)

    def _seen(self) -> tuple[float, NDArray[np.float64]]:
        """Capture time and pose of the frame taken now: ``frame_latency_s`` ago (the latest logged pose
        at or before then), or now."""
        if self.params.frame_latency_s <= 0.0:
            return self.t, self.pose
        due = self.t - self.params.frame_latency_s + 1e-9
        log = self._pose_log
        while len(log) > 1 and log[1][0] <= due:
            log.pop(0)
        return log[0]

    def observe(self) -> Observation:
        if self.camera_schedule.poll(self.t):
            self._capture()
        events = tuple(self._events)
        self._events.clear()
        sensors: dict[str, Any] = {"frame_id": self._frame_id, "frame_t": self._frame_t}
        if self.params.perception == "geometric":
            sensors.update(points=self._points, obstacle=self._obstacle, keyframe_points=self.keyframe_points)
        else:
            sensors.update(image=self._frame, keyframes=tuple(Image(stamp=0.0, frame=f"keyframe_{k}", pixels=img)
                                                              for k, img in enumerate(self.keyframe_images)))
        return Observation(t=self.t, state={"nu": self.vel.copy()}, sensors=sensors, events=events)

    def apply(self, command: Command) -> None:
        """``nu`` = ``[vx, vy, vz, wz]`` (4 finite values), saturated to the robot's limits."""
        nu = self.robot.saturate(check_command(self.robot, command)["nu"])
        if self._delay is not None:
            self._delay.push(self.t, nu)
        else:
            self.cmd = nu
            if self.params.command_response == "relative_move":
                self._move_to = None  # a new move starts at the next step

    # --- stepping (SteppedWorld hooks) ----------------------------------------------------------
    def begin_steps(self, n: int, h: float) -> None:
        tau = self.robot.params.tau
        self._lag = 1.0 - math.exp(-h / tau) if tau > 0.0 else 1.0
        self._start_xyz = tuple(self.pose[:3])
        if n:
            self._move_dt = n * h  # setVelocity(v, dt): dt is the control period

    def physics_step(self, h: float) -> None:
        """The velocity lag, then the body moved by the new body-frame velocity; or (``relative_move``) a
        step of the position loop toward the move in progress.  Delayed commands act once due."""
        if self._delay is not None:
            self.cmd = self._delay.at(self.t)
            if self._delay.arrived:
                self._move_to = None
        if self.params.command_response == "relative_move":
            self._relative_move_step(h)
            return
        x, y, z, yaw = self.pose
        vel = self.vel
        vel += self._lag * (self.cmd - vel)
        c, s = math.cos(yaw), math.sin(yaw)
        self.pose[:] = (x + h * (c * vel[0] - s * vel[1]), y + h * (s * vel[0] + c * vel[1]), z + h * vel[2],
                        math.remainder(yaw + h * vel[3], 2.0 * math.pi))

    def _relative_move_step(self, h: float) -> None:
        if self._move_to is None:
            self._move_to = move_target(self.pose, self.cmd, self._move_dt)
        before = self.pose.copy()
        self.pose[:] = relative_move_step(self.pose, self._move_to, h, self.params.move_tau)
        d = self.pose - before
        d[3] = math.remainder(d[3], 2.0 * math.pi)
        c, s = math.cos(before[3]), math.sin(before[3])
        self.vel[:] = ((c * d[0] + s * d[1]) / h, (-s * d[0] + c * d[1]) / h, d[2] / h, d[3] / h)  # body frame

    def end_steps(self, n: int, h: float) -> None:
        if self.params.frame_latency_s > 0.0:
            self._pose_log.append((self.t, self.pose.copy()))
        x, y, z, yaw = self.pose
        self.path_length += math.dist(self._start_xyz, (x, y, z))
        self._track_path_deviation()
        self._require_scene().set_drone_pose(x, y, z, yaw)
        self._check_contacts()

    def path_deviation(self, xy: Sequence[float] | None = None) -> float:
        """Horizontal distance (m) from ``xy`` (default: the drone) to the taught path polyline."""
        poly = self.taught_path
        q = np.asarray(self.pose[:2] if xy is None else xy, dtype=np.float64)
        if len(poly) < 2:
            return float(np.linalg.norm(q - poly[0]))
        a, ab = poly[:-1], np.diff(poly, axis=0)
        s = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
        return float(np.min(np.linalg.norm(a + s[:, None] * ab - q, axis=1)))

    def _track_path_deviation(self) -> None:
        if not self.params.keyframes:
            return
        d = self.path_deviation()
        self.max_path_deviation = max(self.max_path_deviation, d)
        self._dev_sum += d
        self._dev_n += 1

    def _check_contacts(self) -> None:
        obst, wall = self._require_scene().clearances()
        self._clear = (obst, wall)
        self.min_obstacle_clearance = min(self.min_obstacle_clearance, obst)
        self.min_wall_clearance = min(self.min_wall_clearance, wall)
        contact = min(obst, wall) <= 0.0
        if contact and not self._in_contact:
            self.collisions += 1
            self._events.append("collision")
        self._in_contact = contact

    def safe_stop(self) -> None:
        """Hover: command zero velocity (the on-board loop brakes with its lag)."""
        self.apply(self.robot.stop_command())

    # --- ground truth --------------------------------------------------------------------------
    def ground_truth(self) -> dict[str, float]:
        x, y, z, yaw = self.pose
        vx, vy, vz, wz = self.vel
        return {"x": float(x), "y": float(y), "z": float(z), "yaw": float(yaw), "vx": float(vx), "vy": float(vy),
                "vz": float(vz), "wz": float(wz), "obstacle_clearance": float(self._clear[0]),
                "wall_clearance": float(self._clear[1])}

    def epsilon_to_keyframe(self, index: int, pose: Sequence[float] | None = None, grid: int = 16) -> float:
        """Ground-truth ``ε`` (eq. 7, px) between the view at ``pose`` (default: now) and keyframe
        ``index``: a grid of keyframe pixels is back-projected with the keyframe's depth buffer and
        projected into the current camera; the mean displacement of those in front of the camera."""
        kf = self.params.keyframes[index]
        cam = self.robot.params.camera
        K = cam.K()
        if self.params.perception == "geometric":  # the landmarks the keyframe sees, exact
            Rk, tk = cam.pose_in_world(kf.pose)
            ids, uv_k = visible_landmarks(self.landmarks, self.columns, Rk, tk, K, (cam.width, cam.height))
            R, t = cam.pose_in_world(self.pose if pose is None else pose)
            z, uv = project(self.landmarks[ids], R, t, K)
            front = z > 0.05
            return float(np.mean(np.linalg.norm(uv[front] - uv_k[front], axis=1))) if np.any(front) else math.nan
        depth = self.keyframe_depths[index] if index < len(self.keyframe_depths) else None
        if depth is None:
            return math.nan
        us = np.linspace(0.05, 0.95, grid) * cam.width
        vs = np.linspace(0.05, 0.95, grid) * cam.height
        uu, vv = np.meshgrid(us, vs)
        uv = np.column_stack((uu.ravel(), vv.ravel()))
        Z = depth[np.clip(uv[:, 1].astype(int), 0, cam.height - 1), np.clip(uv[:, 0].astype(int), 0, cam.width - 1)]
        ok = 0.99 * cam.far > Z
        uv, Z = uv[ok], Z[ok]
        Xc = np.column_stack(((uv[:, 0] - K[0, 2]) / K[0, 0] * Z, (uv[:, 1] - K[1, 2]) / K[1, 1] * Z, Z))
        Rk, tk = cam.pose_in_world(kf.pose)
        Xw = Xc @ Rk.T + tk
        R, t = cam.pose_in_world(self.pose if pose is None else pose)
        Xn = (Xw - t) @ R
        front = Xn[:, 2] > 0.05
        if not np.any(front):
            return math.nan
        proj = Xn[front, :2] / Xn[front, 2:3] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
        return float(np.mean(np.linalg.norm(proj - uv[front], axis=1)))

    teaches: ClassVar[bool] = True

    @classmethod
    def teach(cls, robot: Robot, params: BaseModel, out_dir: str | Path, seed: int, name: str = "") -> list[Path]:
        """Hook for the ``taskflow teach MISSION`` command (which loads the mission and passes its robot,
        world parameters drawn with ``seed``, the output folder and the mission's name): see :func:`teach`."""
        return teach(robot, params, out_dir, seed, name)

    def summary_metrics(self) -> dict[str, Any]:
        """Collisions and clearances over the run; final errors against the last taught pose."""
        x, y, z, yaw = (float(v) for v in self.pose)
        out: dict[str, Any] = {
            "collisions": self.collisions,
            "min_clearance_m": float(min(self.min_obstacle_clearance, self.min_wall_clearance)),
            "min_obstacle_clearance_m": float(self.min_obstacle_clearance) if self.params.obstacles else None,
            "min_wall_clearance_m": float(self.min_wall_clearance),
            "path_length_m": self.path_length,
            "gt_x_m": x, "gt_y_m": y, "gt_z_m": z, "gt_yaw_rad": yaw,
        }
        if self.params.keyframes:
            last = self.params.keyframes[-1].pose
            out["final_position_error_m"] = float(math.dist((x, y, z), last[:3]))
            out["final_yaw_error_deg"] = math.degrees(abs(math.remainder(yaw - last[3], 2.0 * math.pi)))
            out["final_epsilon_px"] = self.epsilon_to_keyframe(len(self.params.keyframes) - 1)
            out["path_deviation_max_m"] = self.max_path_deviation
            out["path_deviation_mean_m"] = self._dev_sum / self._dev_n if self._dev_n else 0.0
        return out


def teach(robot: Robot, params: StrictModel, out_dir: str | Path, seed: int, name: str = "") -> list[Path]:
    """Teach-by-showing: render the keyframes of ``params`` (a quad_room world's parameters, their
    distributions already drawn with ``seed``) at their taught poses, seen by ``robot``'s camera, and store
    them in ``out_dir`` as PNG files plus ``keyframes.json`` (poses, camera, texture seed; ``name`` is the
    mission's name, recorded there).

    Returns the written paths (images first, then the JSON).  ``taskflow teach MISSION`` loads the mission
    and passes these (default ``out_dir``: ``<mission dir>/keyframes/<mission name>``).  Point the mission
    at them with ``--set world.params.keyframe_dir=DIR``.
    """
    if not isinstance(params, QuadRoomParams):
        raise ValueError(f"teach needs quad_room world parameters, got {type(params).__name__}")
    if not params.keyframes:
        raise ValueError(f"mission {name!r} has no keyframes to teach")
    params = params.model_copy(update={"keyframe_dir": None, "perception": "rendered"})  # teaching renders
    world = QuadRoom(robot, params, seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        world.reset()
        entries = []
        for k, img in zip(params.keyframes, world.keyframe_images):
            f = out / f"kf_{k.id:03d}.png"
            if not cv2.imwrite(str(f), np.ascontiguousarray(img[:, :, ::-1])):
                raise OSError(f"could not write {f}")
            written.append(f)
            entries.append({"id": k.id, "pose": list(k.pose), "image": f.name})
        cam = world.robot.params.camera
        meta = {"mission": name, "texture_seed": params.texture_seed, "keyframes": entries,
                "camera": {"width": cam.width, "height": cam.height, "fovy": cam.fovy, "K": cam.K().tolist()}}
        jf = out / "keyframes.json"
        jf.write_text(json.dumps(meta, indent=1))
        written.append(jf)
    finally:
        world.close()
    return written


__all__ = ["KeyframeSpec", "QuadRoom", "QuadRoomParams", "QuadcopterParams", "load_keyframe_dir", "teach"]
