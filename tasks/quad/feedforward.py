"""The feed-forward of Alg. 2 (lines 2–15, eq. 32): the velocity ``nu_p`` of each segment ``k → k+1``
of the path, from the correspondences between consecutive keyframes.

Keyframe ``k``'s view plays the current image and ``k+1``'s the target: ``H`` maps ``k`` to ``k+1``,
``e`` is eq. (2), the gain eq. (4), the law eq. (3), scaled by ``γ`` and taken to the body frame.  The
pairs come from either perception pipeline (:meth:`Correspondences.keyframe_pairs
<taskflow_tasks.quad.correspondences.Correspondences.keyframe_pairs>`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.quad.correspondences import Pairs, Pixels
from taskflow_tasks.quad.gains import VisualGains
from taskflow_tasks.quad.homography import (
    adaptive_gain,
    feedforward_velocity,
    gain_matrix,
    normalize_pixels,
    task_error,
)
from taskflow_tasks.quad.perception import estimate_homography
from taskflow_tasks.quad.yaw_decoupling import homography_yaw, yaw_decoupled_error

Array = NDArray[np.float64]

__all__ = ["segment_velocities", "segment_velocity"]


def segment_velocity(cur: Pixels, kf: Pixels, K: Array, Ad_body_camera: Array, gains: VisualGains,
                     gamma: float) -> Array:
    """Eq. (32) for one segment from its correspondences (largest triangle first); 0 when < 8."""
    if len(cur) < 8:
        return np.zeros(4)
    H, _ = estimate_homography(cur, kf, K)
    m_star = normalize_pixels(kf[:3], K).mean(axis=0)
    e = task_error(H, m_star)
    lam = float(adaptive_gain(float(np.linalg.norm(e)), gains.lambda_0, gains.lambda_inf, gains.lambda_0_slope))
    if gains.yaw_decoupling:  # the segment's yaw step would slide nu_p sideways as it does nu_e
        yaw_axis = Ad_body_camera[2, :3]
        e = yaw_decoupled_error(H, m_star, yaw_axis, homography_yaw(H, yaw_axis, normalize_pixels(cur, K)))
    return feedforward_velocity(e, gain_matrix(lam, gains.homography_gains()), gamma, Ad_body_camera)


def segment_velocities(pairs: Pairs, K: Array, Ad_body_camera: Array, gains: VisualGains,
                       gamma: float) -> list[Array]:
    """``nu_p`` (eq. 32) of every segment, from its keyframe pairs; a segment whose views do not match
    (fewer than 8 correspondences) gets ``nu_p = 0``."""
    return [segment_velocity(cur, kf, K, Ad_body_camera, gains, gamma) for cur, kf in pairs]
