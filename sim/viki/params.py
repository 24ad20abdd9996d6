"""``viki_ground``'s parameters: object placement, manipulation-zone goal, perception mode, detector model.

:class:`VikiGroundParams` extends the flat-ground parameters (:class:`taskflow_sim.ground.flat_ground.FlatGroundParams`:
start pose, floor, odometry noise) with the object (``object_kind``, ``object_distance`` / ``object_bearing``
or ``object_xy``, ``object_yaw``), the manipulation-zone ``goal``, the cameras (``perception``,
``initial_camera``, ``image_size``, ``camera_rate_hz``, ``depth_max``, ``latency``), the detector's noise
and dropout, and the odometry's drift; its ``paper`` fidelity level holds the paper's values with sources.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar, Literal

from pydantic import Field, model_validator
from taskflow_sim.core.sensors import DropoutFraction
from taskflow_sim.ground.flat_ground import FlatGroundParams

from taskflow.fidelity import Fidelity, Level, Sourced


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
    dropout: DropoutFraction = Field(default=0.0, description="fraction of frames the detector misses: below 1 "
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

