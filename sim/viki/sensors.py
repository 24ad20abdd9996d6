"""``viki_ground``'s sensors: the front and rear RGB-D cameras (+ the LiDAR) with their detector, one camera at a time.

Perception (``perception: geometric | rendered``, :mod:`taskflow_sim.viki.perception_geometric`,
:mod:`taskflow_sim.viki.perception_rendered`) gives a :class:`taskflow.messages.Detection` of the **active
camera** at the camera's rate (frames on a fixed grid from the stream's start, taken at control ticks:
:class:`taskflow_sim.core.stepped.SensorSchedule`; between two frames the latest is seen with ``fresh = False``).
In ``rendered`` mode the frame's colour image (a :class:`taskflow.messages.Image` stamped with its capture
time) travels with its detection, under the same rule.

Per frame (:meth:`VikiCameras.poll`, run by the world's stepping hook, never by ``observe()``): capture and
detect, add the systematic ``box_bias`` (:func:`biased_box`), drop the box when the dropout model
(:class:`taskflow_sim.viki.camera.DropoutModel`) misses the frame, count it; with ``latency > 0`` the frame
waits in a queue and the newest frame captured at least ``latency`` ago is delivered (older ones are
superseded, as a detector's queue of one).  A delivered detection whose outcome differs from the previous
one emits ``target_found`` / ``target_lost`` (a camera's first frame emits ``target_found`` if it sees the
object).  :meth:`VikiCameras.readings` only reads: the observation's ``sensors`` entries.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.racecar import LidarMount
from taskflow_sim.core.stepped import SensorSchedule
from taskflow_sim.viki.camera import CameraModel, DropoutModel
from taskflow_sim.viki.objects import PlacedObject
from taskflow_sim.viki.params import VikiGroundParams
from taskflow_sim.viki.perception_geometric import GeometricPerception
from taskflow_sim.viki.perception_rendered import LidarScanner, RenderedPerception

from taskflow.messages import Detection, Image

Box = tuple[float, float, float, float]


class VikiCameras:
    """The cameras of one run: models, perceptors, the active camera's frame stream and its delivered detection."""

    def __init__(self, wp: VikiGroundParams, cameras: dict[str, CameraModel], client: int, obj: PlacedObject,
                 object_body: int, car_body: int, lidar_mount: LidarMount, seed: int) -> None:
        self.params, self.cameras = wp, cameras
        self.client, self.object, self.object_body, self.car_body = client, obj, object_body, car_body
        self.lidar_mount = lidar_mount
        # one generator for the detector, independent of the odometry noise stream
        self.rng = np.random.default_rng([seed, 0x7A1])
        self.dropout = DropoutModel(self.rng, wp.dropout, wp.dropout_burst, wp.static_motion_m,
                                    wp.static_motion_rad, wp.static_flip)
        self.perceptors: dict[str, GeometricPerception | RenderedPerception] = {}
        self.lidar: LidarScanner | None = None
        self.active: str | None = None if wp.initial_camera == "none" else wp.initial_camera
        # frames of the active camera on a fixed grid from its stream's start, at its rate (restarted on every
        # switch; 15 Hz camera, 20 Hz control: 3 frames in 4 ticks)
        self.schedule = SensorSchedule(self.cameras[self.active or "front"].mount.rate_hz, 0.0)
        self.seq = 0
        self.last: Detection | None = None
        self.image: Image | None = None  # rendered mode: the colour image of the frame of ``last``
        self._last_detected: bool | None = None
        self._pending: list[tuple[Detection, Image | None]] = []  # latency > 0: frames not delivered yet
        self.events: tuple[str, ...] = ()  # emitted by the latest poll
        self.timings: dict[str, float] = {}  # the latest poll's perception wall-clock seconds (when it took a frame)
        self.frames = 0
        self.detections = 0
        self.missed = 0
        self.first_detection_t: float | None = None

    # --- reading ---------------------------------------------------------------------------------
    def readings(self) -> dict[str, Any]:
        """The observation's ``sensors`` entries: the active camera's delivered detection (and image), the camera."""
        out: dict[str, Any] = {}
        if self.active is not None and self.last is not None and self.last.camera == self.active:
            out["detection"] = self.last
            if self.image is not None:
                out["image"] = self.image
        out["camera"] = self.active
        return out

    # --- the stepping hook -----------------------------------------------------------------------
    def poll(self, t: float, T_world_robot: NDArray[np.float64]) -> None:
        """One control tick at time ``t``: a frame of the active camera when due, then delivery (latency)."""
        self._events: list[str] = []
        self.timings = {}
        latency = self.params.latency
        if self.active is not None and self.schedule.due(t):
            self.timings = {"perception": self._new_frame(self.active, t, T_world_robot)}
            if latency > 0.0:
                self._deliver(t)
        elif latency > 0.0:
            self._deliver(t)
        elif self.last is not None and self.last.fresh:
            self.last = self.last.stale()
        self.events = tuple(self._events)

    def select(self, active: str | None, t: float) -> None:
        """Switch the active camera (``None``: none); its stream starts afresh at the next poll."""
        if active == self.active:
            return
        self.active = active
        self.last = None
        self.image = None
        self._pending = []
        self._last_detected = None
        if active is not None:  # first frame of the new camera at the next poll
            self.schedule.restart(t, self.cameras[active].mount.rate_hz)
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

    def _new_frame(self, name: str, t: float, T_world_robot: NDArray[np.float64]) -> float:
        """Capture and detect on camera ``name``; returns the wall-clock seconds perception took."""
        cam, wp = self.cameras[name], self.params
        T_world_camera = cam.pose(T_world_robot)
        t0 = time.perf_counter()
        per = self.perceptor(name)
        if isinstance(per, GeometricPerception):
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera)
        else:
            bbox, depth, depth_at, depth_in = per.detect(T_world_camera, t, T_world_robot)
        perception_s = time.perf_counter() - t0
        image = None
        if isinstance(per, RenderedPerception) and per.last_rgb is not None:  # the detector's image (a view)
            image = Image(stamp=t, frame=f"{name}_camera", pixels=per.last_rgb)
            if wp.latency <= 0.0:
                self.image = image
        if bbox is not None and any(wp.box_bias):
            bbox = biased_box(bbox, wp.box_bias, cam.width, cam.height)
        dropped = self.dropout.frame(T_world_camera)
        self.frames += 1
        if bbox is not None:
            if dropped:
                self.missed += 1
                bbox, depth = None, None
            else:
                self.detections += 1
                if self.first_detection_t is None:
                    self.first_detection_t = t
        self.schedule.fire(t)
        self.seq += 1
        det = Detection(stamp=t, frame=f"{name}_camera", camera=name, seq=self.seq, bbox=bbox, depth=depth,
                        intrinsics=cam.intrinsics, width=cam.width, height=cam.height, depth_at=depth_at,
                        depth_in=depth_in)
        if wp.latency > 0.0:
            self._pending.append((det, image))
        else:
            self._publish(det)
        return perception_s

    def _publish(self, det: Detection) -> None:
        """``det`` becomes the detection the task sees (events on a change of outcome)."""
        self.last = det
        detected = det.detected
        if detected != self._last_detected and (self._last_detected is not None or detected):
            self._events.append("target_found" if detected else "target_lost")
        self._last_detected = detected

    def _deliver(self, t: float) -> None:
        """Latency: publish the newest pending frame captured at least ``latency`` ago (older ones are
        superseded, as a detector's queue of one); otherwise the last delivered one goes stale."""
        due = [i for i, (d, _) in enumerate(self._pending) if d.stamp + self.params.latency <= t + 1e-9]
        if not due:
            if self.last is not None and self.last.fresh:
                self.last = self.last.stale()
            return
        det, image = self._pending[due[-1]]
        del self._pending[:due[-1] + 1]
        self._publish(det)
        if image is not None:
            self.image = image


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
