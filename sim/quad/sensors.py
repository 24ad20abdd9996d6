"""The quadcopter's forward camera in ``quad_room``, as a declared sensor stream.

:func:`camera_stream` builds the world's one :class:`~taskflow_sim.core.sensors.SensorStream`: at the
camera's rate, a frame of the view ``frame_latency_s`` ago (``delivery="past"``: the drone's pose is
logged at every poll), black during the ``blackout`` intervals, with the image noise (rendered) or the
pixel noise (geometric) as its corruptor.  :class:`RoomCamera` is what the camera sees from a pose:

* ``perception: rendered`` — the frame PyBullet renders (:class:`~taskflow.messages.Image`);
* ``perception: geometric`` — the room's landmarks projected exactly (:mod:`taskflow_sim.quad.landmarks`),
  a :class:`~taskflow.messages.FeatureView`, with the widest column's
  :class:`~taskflow.messages.Silhouette` at the middle row (or ``None``).

Current-frame messages are in the frame ``camera`` stamped with the capture time; keyframe ``k``'s in
``keyframe_k`` (the camera at its taught pose), stamped 0.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from taskflow_robots.quadcopter import QuadCamera
from taskflow_sim.core.faults import IntervalFault
from taskflow_sim.core.sensors import Reading, SensorStream
from taskflow_sim.quad.landmarks import column_silhouette, visible_landmarks
from taskflow_sim.quad.scene import Column, QuadScene

from taskflow.messages import FeatureView, Image, Silhouette

Array = NDArray[np.float64]
CameraView = tuple[Array, Array, Array, tuple[int, int]]

__all__ = ["CameraFrame", "RoomCamera", "camera_stream"]


@dataclass(frozen=True)
class CameraFrame:
    """One frame of the camera: the rendered image, or the landmark view and the column's silhouette."""

    image: Image | None = None
    points: FeatureView | None = None
    obstacle: Silhouette | None = None


class RoomCamera:
    """What the forward camera sees from a body pose ``[x, y, z, yaw]`` in the room."""

    def __init__(self, camera: QuadCamera, perception: Literal["rendered", "geometric"], scene: QuadScene,
                 landmarks: Array, columns: Sequence[Column], image_noise: float, pixel_noise: float) -> None:
        self.camera, self.perception, self.scene = camera, perception, scene
        self.landmarks, self.columns = landmarks, list(columns)
        self.image_noise, self.pixel_noise = image_noise, pixel_noise

    def at(self, pose: Sequence[float] | Array) -> CameraView:
        """World ← optical rotation, camera position, intrinsics and image size at ``pose``."""
        cam = self.camera
        R, t = cam.pose_in_world(list(pose))
        return R, t, cam.K(), (cam.width, cam.height)

    def landmark_view(self, pose: Sequence[float] | Array, stamp: float, frame: str,
                      rng: np.random.Generator | None = None) -> FeatureView:
        """The landmarks seen from ``pose`` (exact pixels; with ``rng``, the pixel noise added), as a
        message stamped ``stamp`` in ``frame``."""
        ids, uv = visible_landmarks(self.landmarks, self.columns, *self.at(pose))
        if rng is not None and self.pixel_noise > 0.0:
            uv = uv + rng.normal(0.0, self.pixel_noise, uv.shape)
        uv.setflags(write=False)
        ids.setflags(write=False)
        return FeatureView(stamp=stamp, frame=frame, ids=ids, uv=uv)

    def widest_column(self, pose: Sequence[float] | Array) -> tuple[float, float, bool] | None:
        """The widest column's left and right image columns (px) and whether it touches the border."""
        view = self.at(pose)
        best = None
        for c in self.columns:
            s = column_silhouette(c, *view)
            if s is not None and (best is None or s[1] - s[0] > best[1] - best[0]):
                best = s
        return best

    def read(self, stamp: float, pose: Array) -> CameraFrame:
        """The true frame of the camera at ``pose`` (captured at ``stamp``)."""
        if self.perception == "geometric":
            edges = self.widest_column(pose)
            obstacle = None if edges is None else Silhouette(stamp=stamp, frame="camera", u_left=edges[0],
                                                             u_right=edges[1], touches_border=edges[2])
            return CameraFrame(points=self.landmark_view(pose, stamp, "camera"), obstacle=obstacle)
        img = self.scene.render((float(pose[0]), float(pose[1]), float(pose[2]), float(pose[3])))
        img.setflags(write=False)
        return CameraFrame(image=Image(stamp=stamp, frame="camera", pixels=img))

    def corrupt(self, frame: CameraFrame, stamp: float, rng: np.random.Generator) -> CameraFrame:
        """The frame with its noise: Gaussian grey levels on the image, or on each landmark pixel."""
        if frame.points is not None:
            p = frame.points
            uv = p.uv + rng.normal(0.0, self.pixel_noise, p.uv.shape)
            uv.setflags(write=False)
            return CameraFrame(points=FeatureView(stamp=p.stamp, frame=p.frame, ids=p.ids, uv=uv), obstacle=frame.obstacle)
        if frame.image is None:
            return frame
        img = frame.image.pixels
        noisy = img.astype(np.float32) + rng.normal(0.0, self.image_noise, img.shape)
        out = np.clip(noisy, 0, 255).astype(np.uint8)
        out.setflags(write=False)
        return CameraFrame(image=Image(stamp=stamp, frame="camera", pixels=out))

    def noisy(self) -> bool:
        return (self.pixel_noise if self.perception == "geometric" else self.image_noise) > 0.0

    def dark(self, stamp: float) -> CameraFrame:
        """A frame lost to a blackout: a black image, or no landmark and no column."""
        if self.perception == "geometric":
            empty = FeatureView(stamp=stamp, frame="camera", ids=np.zeros(0, dtype=np.int64), uv=np.zeros((0, 2)))
            return CameraFrame(points=empty)
        cam = self.camera
        img = np.zeros((cam.height, cam.width, 3), dtype=np.uint8)
        img.setflags(write=False)
        return CameraFrame(image=Image(stamp=stamp, frame="camera", pixels=img))

    def frame_of(self, reading: Reading[CameraFrame]) -> CameraFrame:
        """The message a delivered reading carries (an empty reading: the blackout's dark frame)."""
        if reading.value is not None:
            return reading.value
        return self.dark(reading.stamp)


def camera_stream(camera: RoomCamera, rate_hz: float, latency: float, blackout: IntervalFault,
                  rng: np.random.Generator, pose: Callable[[], Array]) -> SensorStream[CameraFrame]:
    """The camera as a stream polled once per ``advance``: ``rate_hz``, the view ``latency`` seconds old
    (``pose()`` is logged at each poll), empty (dark) frames during ``blackout``, the noise drawn from
    ``rng`` (the world's stream, in capture order)."""
    return SensorStream(camera.read, rate_hz, latency=latency, delivery="past", snapshot=pose, faults=blackout,
                        corrupt=camera.corrupt if camera.noisy() else None, rng=rng, poll="advance")
