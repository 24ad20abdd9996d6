"""The quadcopter description: camera model, eT_c (eq. 5), limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from taskflow_robots.quadcopter import QuadCamera, Quadcopter, QuadcopterParams
from taskflow_tasks.quad.homography import robot_velocity

from taskflow.spatial import R_FLU_OPTICAL, transform, twist_adjoint


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
    assert np.allclose(cam.R_body_camera(), R_FLU_OPTICAL)
    assert np.allclose(rob.T_body_camera(), transform(R_FLU_OPTICAL, cam.t_body_camera()))
    # optical axis = body x: a camera forward velocity is a body forward velocity
    assert np.allclose(robot_velocity([0, 0, 0.3, 0, 0, 0], twist_adjoint(rob.T_body_camera())), [0.3, 0, 0, 0])


def test_pitched_camera_rotation():
    cam = QuadCamera(pitch=math.radians(20))
    z = cam.R_body_camera()[:, 2]  # optical axis in the body frame looks forward and down
    assert z[0] == pytest.approx(math.cos(math.radians(20))) and z[2] == pytest.approx(-math.sin(math.radians(20)))


def test_saturation_per_axis_and_command_layout():
    rob = Quadcopter(QuadcopterParams(v_max=0.5, wz_max=1.0))
    assert np.allclose(rob.saturate([2, -0.2, -3, 5]), [0.5, -0.2, -0.5, 1.0])
    assert rob.command_keys == {"nu": 4}
    assert np.all(rob.stop_command()["nu"] == 0)
    with pytest.raises(TypeError):
        Quadcopter(QuadCamera())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="robot .quadcopter. needs QuadcopterParams parameters, got QuadCamera"):
        Quadcopter(QuadCamera())  # type: ignore[arg-type]
    with pytest.raises(ValidationError):
        QuadcopterParams(tau=-1)


def test_eq5_maps_the_camera_twist_to_the_body_twist_finite_differences():
    """``twist_adjoint(T_body_camera)`` (what visual_path_servo uses as eq. 5's ``eT_c``) maps the camera's
    own twist to the body's: fly the body with a known twist, differentiate the camera pose, map back.
    The opposite map (``twist_adjoint_inverse``, the car paper's direction) does not give the body twist."""
    from taskflow import spatial

    cam = QuadCamera(xyz=(0.12, 0.02, -0.04), pitch=0.3)
    T_body_camera = Quadcopter(QuadcopterParams(camera=cam)).T_body_camera()
    V_body = np.array([0.4, -0.1, 0.2, 0.0, 0.0, 0.7])  # [vx, vy, vz, 0, 0, wz]
    h = 1e-6

    def T_world_camera(s):
        th = V_body[5] * s  # constant body twist: exact flight along a helix
        v_xy = V_body[:2]
        x = (v_xy[0] * math.sin(th) - v_xy[1] * (1 - math.cos(th))) / V_body[5]
        y = (v_xy[1] * math.sin(th) + v_xy[0] * (1 - math.cos(th))) / V_body[5]
        return spatial.transform_xyz_yaw(x, y, V_body[2] * s, th) @ T_body_camera

    X = spatial.inverse(T_world_camera(0.0)) @ (T_world_camera(h) - T_world_camera(-h)) / (2 * h)
    V_camera = np.r_[X[:3, 3], spatial.vee(X[:3, :3])]
    np.testing.assert_allclose(spatial.twist_adjoint(T_body_camera) @ V_camera, V_body, atol=1e-6)
    np.testing.assert_allclose(robot_velocity(V_camera, spatial.twist_adjoint(T_body_camera)), V_body[[0, 1, 2, 5]],
                               atol=1e-6)
    assert not np.allclose(spatial.twist_adjoint_inverse(T_body_camera) @ V_camera, V_body, atol=1e-3)
