"""The quadcopter description: camera model, eT_c (eq. 5), limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from taskflow_robots.quadcopter import QuadCamera, Quadcopter, QuadcopterParams
from taskflow_tasks.homography import FLU_R_OPTICAL, robot_velocity, twist_transform


def test_camera_intrinsics_follow_tinyrenderer():
    cam = QuadCamera(width=320, height=240, fovy=math.radians(60))
    K = cam.K()
    assert K[0, 0] == pytest.approx(120 / math.tan(math.radians(30)))
    assert (K[0, 2], K[1, 2]) == (160.0, 119.0)
    with pytest.raises(ValidationError):
        QuadCamera(near=5.0, far=1.0)


def test_eTc_is_eq_5_for_the_forward_camera():
    rob = Quadcopter(QuadcopterParams())
    cam = rob.params.camera
    assert np.allclose(cam.R(), FLU_R_OPTICAL)
    assert np.allclose(rob.eTc(), twist_transform(FLU_R_OPTICAL, cam.t()))
    # optical axis = body x: a camera forward velocity is a body forward velocity
    assert np.allclose(robot_velocity([0, 0, 0.3, 0, 0, 0], rob.eTc()), [0.3, 0, 0, 0])


def test_pitched_camera_rotation():
    cam = QuadCamera(pitch=math.radians(20))
    z = cam.R()[:, 2]  # optical axis in the body frame looks forward and down
    assert z[0] == pytest.approx(math.cos(math.radians(20))) and z[2] == pytest.approx(-math.sin(math.radians(20)))


def test_saturation_per_axis_and_command_layout():
    rob = Quadcopter(QuadcopterParams(v_max=0.5, wz_max=1.0))
    assert np.allclose(rob.saturate([2, -0.2, -3, 5]), [0.5, -0.2, -0.5, 1.0])
    assert rob.command_keys == {"nu": 4}
    assert np.all(rob.stop_command()["nu"] == 0)
    with pytest.raises(TypeError):
        Quadcopter(QuadCamera())  # type: ignore[arg-type]
    with pytest.raises(ValidationError):
        QuadcopterParams(tau=-1)
