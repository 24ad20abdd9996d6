"""``viki_ground``'s sensors: the front and rear RGB-D cameras (+ the LiDAR) with their detector, one camera at a time.

Each camera is a declared :class:`taskflow_sim.core.sensors.SensorStream` (``front_camera``, ``rear_camera``),
polled once per control tick (``poll="advance"``; frames on a fixed grid from the stream's start, at the
camera's rate: 15 Hz camera, 20 Hz control, 3 frames in 4 ticks), enabled only while it is the **active
camera**.  Per frame, in this order (also the order of the detector's random draws, all from one seeded
generator):

1. **read** (:meth:`VikiCameras.read`): capture and detect — ``perception: geometric | rendered``
   (:mod:`taskflow_sim.viki.perception_geometric`, :mod:`taskflow_sim.viki.perception_rendered`); a
   :class:`taskflow.messages.Detection` always (``bbox = None``: nothing seen) and, in ``rendered`` mode,
   the frame's colour image (:class:`taskflow.messages.Image`, stamped with its capture time);
2. **corrupt** (:meth:`VikiCameras.corrupt`): the detector's error model — the systematic ``box_bias``
   (:func:`biased_box`) and the dropout (:class:`taskflow_sim.viki.camera.DropoutModel`: a Gilbert–Elliott
   chain with bursts and the still-camera repeat, one draw per frame), counted (``frames``, ``detections``,
   ``missed``, ``first_detection_t``);
3. **latency** ``latency`` s, ``delivery="newest"``: the newest frame captured at least ``latency`` ago is
   delivered, older ones are superseded (a detector's queue of one); between deliveries the task sees the
   last one with ``fresh = False``;
4. **events** ``target_found`` / ``target_lost`` (change mode): a delivered detection whose outcome differs
   from the previous one's (a camera's first frame emits ``target_found`` if it sees the object).

:meth:`VikiCameras.readings` only reads (the observation's ``sensors`` entries); switching the camera
(:meth:`VikiCameras.select`) restarts the new camera's stream at the switch time and forgets the old one.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.racecar import LidarMount
from taskflow_sim.core.sensors import SensorStream
from taskflow_sim.viki.camera import CameraModel, DropoutModel
from taskflow_sim.viki.objects import PlacedObject
from taskflow_sim.viki.params import VikiGroundParams
from taskflow_sim.viki.perception_geometric import GeometricPerception
from taskflow_sim.viki.perception_rendered import LidarScanner, RenderedPerception

from taskflow.messages import Detection, Image

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class Frame:
    """One camera frame as the detector gives it: the detection, the colour image (rendered mode) and the
    camera pose it was taken from (the dropout model's still-camera rule reads it)."""

    detection: Detection
    image: Image | None
    T_world_camera: NDArray[np.float64]


def _seen(frame: Frame) -> bool:
    return frame.detection.detected


class VikiCameras:
    """The cameras of one run: models, perceptors and one sensor stream per camera (module doc)."""

    def __init__(self, wp: VikiGroundParams, cameras: dict[str, CameraModel], client: int, obj: PlacedObject,
                 object_body: int, car_body: int, lidar_mount: LidarMount, seed: int,
                 robot_pose: Callable[[], NDArray[np.float64]]) -> None:
        self.params, self.cameras = wp, cameras
        self.client, self.object, self.object_body, self.car_body = client, obj, object_body, car_body
        self.lidar_mount = lidar_mount
        self._robot_pose = robot_pose  # T_world_robot (4x4) now, from the simulator
        # one generator for the detector, independent of the odometry noise stream
        self.rng = np.random.default_rng([seed, 0x7A1])
        self.dropout = DropoutModel(self.rng, wp.dropout, wp.dropout_burst, wp.static_motion_m,
                                    wp.static_motion_rad, wp.static_flip)
        self.perceptors: dict[str, GeometricPerception | RenderedPerception] = {}
        self.lidar: LidarScanner | None = None
        self.active: str | None = None if wp.initial_camera == "none" else wp.initial_camera
        self.streams: dict[str, SensorStream[Frame]] = {
            name: SensorStream(self._reader(name), cam.mount.rate_hz, latency=wp.latency, delivery="newest",
                               corrupt=self.corrupt, rng=self.rng, events=("target_found", "target_lost"),
                               present=_seen, poll="advance", enabled=name == self.active)
            for name, cam in cameras.items()}
        self.seq = 0
        self.timings: dict[str, float] = {}  # perception wall-clock seconds of the frame taken this tick
        self.frames = 0
        self.detections = 0
        self.missed = 0
        self.first_detection_t: float | None = None
        self._stale: tuple[Detection | None, Detection | None] = (None, None)  # (delivered, its stale view)

    # --- reading ---------------------------------------------------------------------------------
    def stream(self) -> SensorStream[Frame] | None:
        """The active camera's stream (``None``: perception off)."""
        return self.streams[self.active] if self.active is not None else None

    def detection(self) -> Detection | None:
        """The detection the task sees: the active camera's last delivered one (``fresh`` only on the tick it
        was delivered)."""
        s = self.stream()
        if s is None or s.latest is None or s.latest.value is None:
            return None
        det = s.latest.value.detection
        if s.new:
            return det
        src, view = self._stale
        return view if src is det else det.stale()

    def readings(self) -> dict[str, Any]:
        """The observation's ``sensors`` entries: the active camera's detection (and image), the camera."""
        out: dict[str, Any] = {}
        det = self.detection()
        if det is not None:
            out["detection"] = det
            s = self.stream()
            image = s.latest.value.image if s is not None and s.latest is not None and s.latest.value else None
            if image is not None:
                out["image"] = image
        out["camera"] = self.active
        return out

    def events(self) -> tuple[str, ...]:
        """The found/lost events of the latest poll."""
        s = self.stream()
        return tuple(s.events) if s is not None else ()

    # --- the stepping hook -----------------------------------------------------------------------
    def begin_tick(self) -> None:
        """Before the streams' poll of a control tick: no frame taken yet; the current detection's stale
        view is made once (the one every observation until the next delivery sees)."""
        self.timings = {}
        s = self.stream()
        det = s.latest.value.detection if s is not None and s.latest is not None and s.latest.value else None
        if det is not None and self._stale[0] is not det:
            self._stale = (det, det.stale())

    def select(self, active: str | None, t: float) -> None:
        """Switch the active camera (``None``: none); its stream starts afresh at ``t`` (first frame at the
        next poll), the old one stops and forgets what it delivered."""
        if active == self.active:
            return
        if self.active is not None:
            old = self.streams[self.active]
            old.restart(t)
            old.enabled = False
        self.active = active
        if active is not None:
            new = self.streams[active]
            new.restart(t)
            new.enabled = True
        self.dropout.reset()

    def perceptor(self, name: str) -> GeometricPerception | RenderedPerception:
        """Camera ``name``'s perception pipeline (built on first use; the LiDAR goes with the front camera)."""
        per = self.perceptors.get(name)
        if per is None:
            cam, wp = self.cameras[name], self.params
            if wp.perception == "geometric":
                per = GeometricPerception(self.client, cam, self.object, self.object_body, self.rng,
                                          wp.pixel_noise, wp.depth_noise, wp.min_pixels)
            else:
                lidar = None
                if name == "front" and wp.lidar_fusion:
                    if self.lidar is None:
                        self.lidar = LidarScanner(self.client, self.lidar_mount, self.car_body)
                    lidar = self.lidar
                per = RenderedPerception(self.client, cam, self.object_body, wp.min_pixels, lidar)
            self.perceptors[name] = per
        return per

    def _reader(self, name: str) -> Callable[[float, Any], Frame]:
        def read(stamp: float, _state: Any) -> Frame:
            return self.read(name, stamp)
        return read

    def read(self, name: str, t: float) -> Frame:
        """Capture and detect on camera ``name`` at ``t`` (the wall-clock cost goes to ``timings``)."""
        cam = self.cameras[name]
        T_world_robot = self._robot_pose()
        T_world_camera = cam.pose(T_world_robot)
        t0 = time.perf_counter()
        per = self.perceptor(name)
        if isinstance(per, GeometricPerception):
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera)
        else:
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera, t, T_world_robot)
        self.timings = {"perception": time.perf_counter() - t0}
        image = None
        if isinstance(per, RenderedPerception) and per.last_rgb is not None:  # the detector's image (a view)
            image = Image(stamp=t, frame=f"{name}_camera", pixels=per.last_rgb)
        self.seq += 1
        det = Detection(stamp=t, frame=f"{name}_camera", camera=name, seq=self.seq, bbox=bbox, depth=depth,
                        intrinsics=cam.intrinsics, width=cam.width, height=cam.height, depth_at=depth_at,
                        depth_in=depth_in)
        return Frame(det, image, T_world_camera)

    def corrupt(self, frame: Frame, t: float, rng: np.random.Generator) -> Frame:
        """The detector's error model: ``box_bias``, then the dropout (one draw per frame from ``rng``,
        the dropout model's generator); counts the frame."""
        det, wp = frame.detection, self.params
        bbox, depth = det.bbox, det.depth
        if bbox is not None and any(wp.box_bias):
            bbox = biased_box(bbox, wp.box_bias, det.width, det.height)
        dropped = self.dropout.frame(frame.T_world_camera)
        self.frames += 1
        if bbox is not None:
            if dropped:
                self.missed += 1
                bbox, depth = None, None
            else:
                self.detections += 1
                if self.first_detection_t is None:
                    self.first_detection_t = t
        if bbox is det.bbox and depth is det.depth:
            return frame
        return Frame(dataclasses.replace(det, bbox=bbox, depth=depth), frame.image, frame.T_world_camera)


def biased_box(bbox: Box, bias: Box, width: int, height: int) -> Box:
    """``bbox + bias`` (px, per edge) kept inside the image (edges ``-0.5 .. W - 0.5``) and ordered
    (an edge pushed past its opposite meets it)."""
    u0, v0, u2, v2 = (b + d for b, d in zip(bbox, bias, strict=True))
    u0, u2 = min(max(u0, -0.5), width - 0.5), min(max(u2, -0.5), width - 0.5)
    v0, v2 = min(max(v0, -0.5), height - 0.5), min(max(v2, -0.5), height - 0.5)
    if u2 < u0:
        u0 = u2 = 0.5 * (u0 + u2)
    if v2 < v0:
        v0 = v2 = 0.5 * (v0 + v2)
    return (u0, v0, u2, v2)
