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
  :meth:`QuadRoom.teach` stored in ``keyframe_dir`` (:mod:`taskflow_sim.quad.teaching`).  The poses
  serve only the ground-truth summary (:mod:`taskflow_sim.quad.scoring`).
* **Collisions.**  The iris body's collision shapes against the obstacles and the room's slabs
  (walls, floor, ceiling) with ``getClosestPoints`` after every control step: a ``collision`` event
  when a contact starts, and ``collisions``, ``min_clearance_m`` … in the summary.
* **Path following accuracy.**  After every step the horizontal distance from the drone to the taught
  path (the polyline start → keyframe 0 → … → last keyframe) is measured; the summary has its maximum
  and mean (``path_deviation_max_m``, ``path_deviation_mean_m``) next to the flown ``path_length_m``, and
  the 3-D distance to the polyline through the taught positions with their heights
  (``path_deviation_3d_max_m``, ``path_deviation_3d_mean_m``: a climb flown below its apex shows there).
* **The camera** is one declared sensor stream (:mod:`taskflow_sim.quad.sensors`): its rate, its
  latency (``frame_latency_s``), its ``blackout`` intervals (black frames: lost video or occlusion, so
  missions can exercise their lost-features handling) and its noise; ``observe()`` only reads it.
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

import math
from pathlib import Path
from typing import Any, ClassVar, cast

import cv2
import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel
from taskflow_robots.quadcopter import Quadcopter
from taskflow_sim.core.command_delay import CommandDelay
from taskflow_sim.core.faults import IntervalFault
from taskflow_sim.core.sensors import SensorStream
from taskflow_sim.core.stepped import SteppedWorld, check_command
from taskflow_sim.quad.landmarks import sample_landmarks
from taskflow_sim.quad.params import QuadRoomParams
from taskflow_sim.quad.response import move_target, relative_move_step
from taskflow_sim.quad.scene import Column, QuadScene, Room
from taskflow_sim.quad.scoring import RoomScore, ground_truth_epsilon
from taskflow_sim.quad.sensors import CameraFrame, RoomCamera, camera_stream
from taskflow_sim.quad.teaching import taught_keyframes, write_keyframes

from taskflow.api import Command, Marker, Observation, ObsSpec, Robot, RobotNeeds, message, scalar, sequence
from taskflow.messages import FeatureView, Image, Silhouette
from taskflow.registry import register_world
from taskflow.spatial import planar_apply_inverse

__all__ = ["QuadRoom"]


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
    robot: Quadcopter

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

    def __init__(self, robot: Robot, params: QuadRoomParams, seed: int, gui: bool = False) -> None:
        if not isinstance(robot, Quadcopter):
            raise TypeError(f"world quad_room flies a quadcopter, got {type(robot).__name__}")
        super().__init__(robot, params, seed, gui)
        self.blackout = IntervalFault(params.blackout, "blackout")
        self._rng = np.random.default_rng(seed)
        self.columns: list[Column] = []
        self.landmarks = np.zeros((0, 3))
        self.score = RoomScore(params.start, [k.pose for k in params.keyframes])
        self.camera: RoomCamera | None = None
        self._init_state()

    def _init_state(self) -> None:
        self.restart_clock()
        self._lag = 1.0
        self.pose = np.asarray(self.params.start, dtype=np.float64).copy()
        self.vel = np.zeros(4)
        self.cmd = np.zeros(4)
        self._delay = CommandDelay(self.params.command_delay_s, self.cmd) if self.params.command_delay_s > 0.0 else None
        self._move_to: NDArray[np.float64] | None = None  # relative_move: the target of the move in progress
        self._move_dt = 0.0
        self._start_xyz: tuple[float, ...] = tuple(self.pose[:3])
        self._events: list[str] = []
        self.score.restart()
        self.keyframe_images: tuple[NDArray[np.uint8], ...] = ()
        self.keyframe_depths: list[NDArray[np.float64] | None] = []
        self.keyframe_points: tuple[FeatureView, ...] = ()

    # --- lifecycle -----------------------------------------------------------------------------
    def reset(self) -> None:
        self.close()
        wp, rp = self.params, self.robot.params
        room = Room(wp.room.x0, wp.room.x1, wp.room.y0, wp.room.y1, wp.room.height)
        cols = [Column(o.x, o.y, o.width, o.depth, wp.obstacle_height, o.yaw) for o in wp.obstacles]
        scene = QuadScene.build(room, cols, seed=wp.texture_seed, camera=rp.camera, scale=rp.scale,
                                gui=self.gui, texture_px_per_m=wp.texture_px_per_m)
        self.sim = scene
        self._rng = np.random.default_rng(self.seed)
        # OpenCV's RANSAC draws from a process-global RNG: seed it so a seed reproduces a run whatever
        # ran before in the process
        cv2.setRNGSeed(int(self.seed))
        self._init_state()
        self.columns = cols
        self.landmarks = sample_landmarks(room, wp.landmark_density, np.random.default_rng(wp.texture_seed))
        camera = RoomCamera(rp.camera, wp.perception, scene, self.landmarks, cols, wp.image_noise, wp.pixel_noise)
        self.camera = camera
        if wp.perception == "geometric":
            self.keyframe_points = tuple(camera.landmark_view(k.pose, 0.0, f"keyframe_{k.id}", self._rng)
                                         for k in wp.keyframes)
        else:
            self.keyframe_images, self.keyframe_depths = taught_keyframes(scene, [k.pose for k in wp.keyframes],
                                                                          rp.camera, wp.keyframe_dir)
        scene.set_drone_pose(*self.pose)
        self._check_contacts()
        self.frames: SensorStream[CameraFrame] = camera_stream(camera, wp.camera_rate_hz or rp.camera.rate_hz,
                                                               wp.frame_latency_s, self.blackout, self._rng,
                                                               lambda: self.pose.copy())
        self.add_stream("camera", self.frames)
        self.start_streams()

    # --- the loop ------------------------------------------------------------------------------
    def observe(self) -> Observation:
        """The latest frame the camera stream delivered (and the keyframes' messages), the measured body
        velocity and the events since the last ``advance`` began; reads only."""
        stream, camera = self.frames, self.camera
        latest = stream.latest
        sensors: dict[str, Any] = {"frame_id": stream.captured - 1, "frame_t": -math.inf if latest is None else latest.stamp}
        frame = CameraFrame() if latest is None or camera is None else camera.frame_of(latest)
        if self.params.perception == "geometric":
            sensors.update(points=frame.points, obstacle=frame.obstacle, keyframe_points=self.keyframe_points)
        else:
            sensors.update(image=frame.image, keyframes=tuple(Image(stamp=0.0, frame=f"keyframe_{k}", pixels=img)
                                                              for k, img in enumerate(self.keyframe_images)))
        return Observation(t=self.t, state={"nu": self.vel.copy()}, sensors=sensors, events=tuple(self._events))

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
        self._events.clear()  # the events of the last advance have been observed
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
        self.vel[:2] = planar_apply_inverse((0.0, 0.0, before[3]), d[:2]) / h  # body frame
        self.vel[2:] = d[2] / h, d[3] / h

    def end_steps(self, n: int, h: float) -> None:
        self.score.moved(self._start_xyz, self.pose)
        self._require_sim().set_drone_pose(*self.pose)
        self._check_contacts()

    def _check_contacts(self) -> None:
        if self.score.contacts(*self._require_sim().clearances()):
            self._events.append("collision")

    def safe_stop(self) -> None:
        """Hover: command zero velocity (the on-board loop brakes with its lag)."""
        self.apply(self.robot.stop_command())

    # --- ground truth --------------------------------------------------------------------------
    def ground_truth(self) -> dict[str, float]:
        x, y, z, yaw = self.pose
        vx, vy, vz, wz = self.vel
        obstacle, wall = self.score.clearance
        return {"x": float(x), "y": float(y), "z": float(z), "yaw": float(yaw), "vx": float(vx), "vy": float(vy),
                "vz": float(vz), "wz": float(wz), "obstacle_clearance": float(obstacle), "wall_clearance": float(wall)}

    def epsilon_to_keyframe(self, index: int, pose: NDArray[np.float64] | tuple[float, ...] | None = None,
                            grid: int = 16) -> float:
        """Ground-truth ``ε`` (eq. 7, px) between the view at ``pose`` (default: now) and keyframe ``index``
        (:func:`~taskflow_sim.quad.scoring.ground_truth_epsilon`)."""
        geometric = self.params.perception == "geometric"
        depth = self.keyframe_depths[index] if not geometric and index < len(self.keyframe_depths) else None
        return ground_truth_epsilon(self.robot.params.camera, self.params.keyframes[index].pose,
                                    list(self.pose if pose is None else pose), self.landmarks if geometric else None,
                                    self.columns, depth, grid)

    def summary_metrics(self) -> dict[str, Any]:
        """Collisions and clearances over the run; final errors against the last taught pose."""
        n = len(self.params.keyframes)
        return self.score.summary(self.pose, bool(self.params.obstacles), self.epsilon_to_keyframe(n - 1) if n else None)

    teaches: ClassVar[bool] = True

    @classmethod
    def teach(cls, robot: Robot, params: BaseModel, out_dir: str | Path, seed: int, name: str = "") -> list[Path]:
        """Teach-by-showing, the hook of ``taskflow teach MISSION`` (which passes the mission's robot, its
        world parameters drawn with ``seed``, the output folder and the mission's name): render the
        keyframes at their taught poses, seen by ``robot``'s camera, and store them in ``out_dir`` as PNG
        files plus ``keyframes.json`` (:func:`~taskflow_sim.quad.teaching.write_keyframes`).  Returns the
        written paths (images first, then the JSON); point the mission at them with ``--set
        world.params.keyframe_dir=DIR``."""
        if not isinstance(params, QuadRoomParams):
            raise ValueError(f"teach needs quad_room world parameters, got {type(params).__name__}")
        if not params.keyframes:
            raise ValueError(f"mission {name!r} has no keyframes to teach")
        params = params.model_copy(update={"keyframe_dir": None, "perception": "rendered"})  # teaching renders
        world = cls(robot, params, seed)
        try:
            world.reset()
            return write_keyframes(out_dir, [(k.id, k.pose) for k in params.keyframes], world.keyframe_images,
                                   world.robot.params.camera, params.texture_seed, name)
        finally:
            world.close()
