"""The parameters of the visual-path tasks: the keyframe to servo to, its path, the switching
thresholds and the perception settings, and the robot parameter they read (the forward camera)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator
from taskflow_robots.quadcopter import QuadCamera

from taskflow.api import StrictModel


class KeyframeRef(StrictModel):
    """A keyframe of the path as the robot knows it: its index into the taught keyframe images (the
    observation's ``sensors.keyframes`` / ``sensors.keyframe_points``) and its settings.  The pose it
    was taught at is the world's (``world.params.keyframes``, ground truth for the summary): a robot has
    the images, not the poses."""

    id: int = Field(ge=0)
    sigma: float | None = Field(default=None, gt=0.0, le=2.0,
                                description="collision reference σ while servoing to this keyframe (§5.2 changes it per obstacle)")


class VisualPathParams(StrictModel):
    """One keyframe to servo to, the path it belongs to, the switching thresholds and the perception."""

    keyframe: KeyframeRef
    path: list[KeyframeRef] = Field(default_factory=list)
    t_eps_px: float = Field(default=12.0, gt=0.0, le=1000.0, description="T_ε of intermediate keyframes (px)")
    t_eps_final_px: float = Field(default=7.0, gt=0.0, le=1000.0, description="T_ε of the last keyframe (px)")
    feedforward: bool = False
    progress_window_s: float = Field(default=1.0, gt=0.0, le=60.0,
                                     description="window of the epsilon_progress metric (s)")
    transition: bool | None = Field(default=None, description="apply h_t (eq. 28); default: when the path has > 1 keyframe")
    features: Literal["orb", "sift"] = "orb"
    n_features: int = Field(default=1000, ge=50, le=20000)
    min_points: int = Field(default=16, ge=8, le=10000)
    homography: Literal["ransac", "virtual_plane"] = "ransac"
    plane_px: float = Field(default=3.0, gt=0.0, le=100.0,
                            description="transfer error beyond which a tracked point leaves the plane of H (px)")
    anchor: bool = Field(default=True, description="re-anchor the tracked points on their keyframe patches every frame "
                                                   "(through the homography of the tracked plane)")
    retry_scale: int = Field(default=4, ge=1, le=20,
                             description="when matching finds fewer than min_points, detect again with retry_scale x "
                                         "n_features keypoints (a view sharing only part of the keyframe); 1: no retry")
    refresh_fraction: float = Field(default=0.5, ge=0.0, lt=1.0,
                                    description="match the keyframe again (adding the new matches) when the tracked set "
                                                "has shrunk below this fraction of the last matching; 0: only below min_points")

    @model_validator(mode="after")
    def _consistent(self) -> VisualPathParams:
        n = len(self.path)
        if n and (self.keyframe.id >= n or self.path[self.keyframe.id] != self.keyframe):
            raise ValueError(f"keyframe {self.keyframe.id} is not entry {self.keyframe.id} of the path")
        if self.feedforward and n < 2:
            raise ValueError(f"feed-forward (eq. 32) needs a path of at least two keyframes, this one has {n}")
        return self

    @property
    def n_keyframes(self) -> int:
        return max(len(self.path), self.keyframe.id + 1)

    @property
    def is_last(self) -> bool:
        return self.keyframe.id == self.n_keyframes - 1


class RematchParams(StrictModel):
    """Keyframe to re-match while hovering, and the matcher settings."""

    keyframe: KeyframeRef
    path: list[KeyframeRef] = Field(default_factory=list)
    features: Literal["orb", "sift"] = "orb"
    n_features: int = Field(default=1000, ge=50, le=20000)
    min_points: int = Field(default=16, ge=8, le=10000)
    retry_scale: int = Field(default=4, ge=1, le=20,
                             description="when matching finds fewer than min_points, detect again with retry_scale x "
                                         "n_features keypoints; 1: no retry")


class ForwardCamera(StrictModel):
    """The robot parameter the visual-path laws read: its forward camera (intrinsics and mount ``eT_c``)."""

    camera: QuadCamera


