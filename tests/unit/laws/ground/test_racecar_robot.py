"""The racecar description: limits, command layout and sensor mounts (pure data, no simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_robots.racecar import CameraMount, Racecar

from taskflow.registry import ROBOTS


def ground_hit(cam: CameraMount) -> np.ndarray:
    """Where the optical axis meets the ground z = 0, in the robot frame."""
    t = cam.T_body_camera()
    origin, axis = t[:3, 3], t[:3, 2]
    return origin + axis * (-origin[2] / axis[2])


def test_registered_with_paper_limits():
    assert ROBOTS.get("racecar") is Racecar
    params = Racecar.Params()
    assert (params.wheelbase, params.track, params.v_max, params.psi_max) == (0.325, 0.2, 0.5, 0.44)
    stop = Racecar(params).stop_command()
    assert set(stop) == {"v", "steer"} and all(a.shape == (1,) for a in stop.values())
    with pytest.raises(ValidationError):
        Racecar.Params(wheelbse=0.3)


def test_cameras_look_down_at_the_ground_ahead_and_behind():
    params = Racecar.Params()
    front, rear = ground_hit(params.front_camera), ground_hit(params.rear_camera)
    assert 0.8 < front[0] < 2.0 and abs(front[1]) < 1e-9
    assert -2.0 < rear[0] < -0.5 and abs(rear[1]) < 1e-9
    for cam in (params.front_camera, params.rear_camera):
        r = cam.T_body_camera()[:3, :3]
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        assert r[2, 1] < 0.0  # image y (down) points down in the robot frame
    # Image x (right) is the robot's -y for the front camera and +y for the rear one.
    assert params.front_camera.T_body_camera()[1, 0] == pytest.approx(-1.0)
    assert params.rear_camera.T_body_camera()[1, 0] == pytest.approx(1.0)


def test_lidar_blind_spot_radius_matches_paper():
    lidar = Racecar.Params().lidar
    assert lidar.xyz[2] / math.tan(-lidar.v_fov[0]) == pytest.approx(4.1052, abs=1e-3)
