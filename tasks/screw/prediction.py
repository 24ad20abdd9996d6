"""The part-motion predictor of the screw tasks (beyond the paper): the ``prediction`` profile and the
estimator it switches on.

With prediction on, every new marker pose is placed in the odometry frame with the platform pose
interpolated at its capture time; a least-squares line over the last ``window`` seconds gives the
part's planar velocity and yaw rate (once per marker), and each tick the latest pose is propagated
over its age (the latency) and brought back into the current base frame.  The estimated motion is fed
forward into both twists and eq. 35 compensates the platform's motion relative to the target's
(``Prediction.relative``; the paper's ``E − V_be dt`` leaves the tool ``v·dt`` behind a moving bolt) —
the fix the paper names for its irregular-motion failures.  Pure numpy.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field
from taskflow_tasks.core import pbvs

from taskflow.api import StrictModel
from taskflow.messages import MarkerPose
from taskflow.spatial import T_from_planar, planar_inverse, transform_xyz_yaw

ODOM_HISTORY_S = 0.5  # odometry kept to place a marker pose at its capture time (latency ≪ this)
Planar = tuple[float, float, float]
_ZERO3 = np.zeros(3)


class Prediction(StrictModel):
    """Velocity feed-forward (beyond the paper): ``enabled``, fit ``window`` (s), ``gain`` on the
    fed-forward twists, ``max_age`` (s) beyond which a marker pose is not propagated, and ``relative``:
    the compensation of eq. 35 subtracts the platform's motion relative to the target's estimated motion."""

    kind: ClassVar[str] = "prediction"

    enabled: bool = False
    window: float = Field(default=0.4, gt=0.0, le=5.0)
    gain: float = Field(default=1.0, ge=0.0, le=2.0)
    max_age: float = Field(default=0.3, gt=0.0)
    order: Literal[1, 2] = Field(default=1, description="the fit's order: 1 a constant velocity over the window "
                                 "(it lags a changing one by half the window), 2 a constant acceleration (the "
                                 "velocity at the latest pose, noisier)")
    relative: bool = Field(default=True, description="eq. 35 compensates the platform's motion relative to the "
                           "target's estimated motion (false: the paper's E − V_be dt, which leaves the tool v·dt behind)")


def interp_odom(times: list[float], poses: list[Planar], t: float) -> Planar:
    """Platform pose at time ``t`` from the odometry history (linear; clamped to its ends)."""
    i = bisect.bisect_left(times, t)
    if i <= 0:
        return poses[0]
    if i >= len(times):
        return poses[-1]
    t0, t1 = times[i - 1], times[i]
    a, b = poses[i - 1], poses[i]
    w = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
    return (a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * math.remainder(b[2] - a[2], 2 * math.pi))


@dataclass
class PartFit:
    """The part's last fitted motion: the capture time of the marker it was fitted at, the part's pose
    then (``T_world_object``) and its planar velocity ``(v_x, v_y, ω_z)`` in the world (zeros: too few
    poses yet)."""

    stamp: float
    T_world_object: NDArray[np.float64]
    slope: NDArray[np.float64]


@dataclass
class MotionPredictor:
    """The predictor's whole state, kept across states as one mission-data entry: the odometry history
    (``odom_t``, ``odom_p``: times and planar poses), the last marker used (``seq``), the part's planar
    poses ``(t, x, y, yaw)`` in the fit window (``history``) and the last fit."""

    odom_t: list[float] = field(default_factory=list)
    odom_p: list[Planar] = field(default_factory=list)
    seq: int | None = None
    history: list[tuple[float, float, float, float]] = field(default_factory=list)
    fit: PartFit | None = None

    def record_odometry(self, t: float, odom: NDArray[np.float64]) -> None:
        """Log the platform pose of this tick (trimmed in blocks: ``ODOM_HISTORY_S`` kept, at any rate)."""
        times, poses = self.odom_t, self.odom_p
        times.append(t)
        poses.append((float(odom[0]), float(odom[1]), float(odom[2])))
        if times[0] < t - 1.5 * ODOM_HISTORY_S:
            cut = bisect.bisect_left(times, t - ODOM_HISTORY_S)
            del times[:cut], poses[:cut]

    def add_marker(self, marker: MarkerPose, T_body_camera: NDArray[np.float64], window: float,
                   order: int = 1) -> PartFit:
        """The fit (a polynomial of ``order`` over the window, :func:`pbvs.fit_velocity`) with ``marker``
        in it (refitted once per new marker, by its ``seq``)."""
        if marker.seq != self.seq or self.fit is None:
            self.seq = marker.seq
            x, y, th = interp_odom(self.odom_t, self.odom_p, marker.stamp)
            T_world_object = transform_xyz_yaw(x, y, 0.0, th) @ T_body_camera @ marker.T_camera_object
            objs = self.history
            yaw = math.atan2(T_world_object[1, 0], T_world_object[0, 0])
            if objs:
                yaw = objs[-1][3] + math.remainder(yaw - objs[-1][3], 2 * math.pi)  # unwrapped
            objs.append((marker.stamp, T_world_object[0, 3], T_world_object[1, 3], yaw))
            while len(objs) > 2 and objs[0][0] < marker.stamp - window:
                objs.pop(0)
            slope = np.zeros(3)
            if len(objs) >= 3:
                arr = np.array(objs)
                _, slope = pbvs.fit_velocity(arr[:, 0], arr[:, 1:], order)
            self.fit = PartFit(marker.stamp, T_world_object, slope)
        return self.fit


def propagate(fit: PartFit, t: float, odom: NDArray[np.float64], T_camera_body: NDArray[np.float64],
              pred: Prediction, max_age: float | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``(T_camera_object now, v_o, w_o)``: the fitted pose moved over its age (at most ``max_age``, by
    default the profile's) with the fitted motion, seen from the current camera, and the part's velocity
    (times ``gain``) in the current base frame."""
    age = min(pred.max_age if max_age is None else max_age, max(0.0, t - fit.stamp))
    vx, vy, wz = float(fit.slope[0]), float(fit.slope[1]), float(fit.slope[2])
    dyaw = wz * age
    c, s = math.cos(dyaw), math.sin(dyaw)
    T_wo = fit.T_world_object
    T_now = T_wo.copy()  # turned by dyaw about the world z, moved by v·age
    T_now[0, :3] = c * T_wo[0, :3] - s * T_wo[1, :3]
    T_now[1, :3] = s * T_wo[0, :3] + c * T_wo[1, :3]
    T_now[0, 3] += vx * age
    T_now[1, 3] += vy * age
    bth = float(odom[2])
    cb, sb = math.cos(bth), math.sin(bth)
    T_body_world = T_from_planar(planar_inverse((float(odom[0]), float(odom[1]), bth)))
    g = pred.gain
    v_o = np.array([g * (cb * vx + sb * vy), g * (-sb * vx + cb * vy), 0.0])  # the world velocity in the base frame
    return T_camera_body @ (T_body_world @ T_now), v_o, np.array([0.0, 0.0, g * wz])


def no_motion(marker: MarkerPose | None) -> tuple[NDArray[np.float64] | None, NDArray[np.float64], NDArray[np.float64]]:
    """The marker's pose as it is, and no motion (prediction off, or nothing fitted yet)."""
    return (None if marker is None else marker.T_camera_object), _ZERO3, _ZERO3
