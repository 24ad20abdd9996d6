"""The mobile iiwa: one run-time URDF for Pinocchio and PyBullet, Jacobian vs finite differences."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation
from taskflow_robots.iiwa_urdf import ARM_JOINTS, installed_iiwa_urdf
from taskflow_robots.mobile_iiwa import MobileIiwa, Pose
from taskflow_tasks.core import pbvs

from taskflow import spatial
from taskflow.registry import ROBOTS


@pytest.fixture(scope="module")
def robot():
    return MobileIiwa(MobileIiwa.Params())


def random_q(k, rng):
    return rng.uniform(0.9 * k.lower, 0.9 * k.upper)


def test_registered_and_urdf_has_absolute_meshes_and_tool_frames(robot):
    assert ROBOTS.get("mobile_iiwa") is MobileIiwa
    root = ET.fromstring(robot.urdf_text)
    meshes = [m.get("filename") for m in root.iter("mesh")]
    assert meshes and all(m.startswith("/") for m in meshes)
    links = {l.get("name") for l in root.iter("link")}
    assert {"platform", "lbr_iiwa_link_0", "screwdriver", "tool_tip", "camera_optical"} <= links
    assert root.find("link").get("name") == "platform"  # the root link
    assert installed_iiwa_urdf().name == "model.urdf"
    stop = robot.stop_command()
    assert set(stop) == {"base_twist", "arm_dq"} and not any(v.any() for v in stop.values())


def test_pose_forms_and_errors():
    a = Pose.model_validate({"xyz": [1, 2, 3], "rpy_deg": [180, 0, -90]})
    b = Pose.model_validate([1, 2, 3, math.pi, 0, -math.pi / 2])
    np.testing.assert_allclose(a.matrix(), b.matrix(), atol=1e-12)
    np.testing.assert_allclose(Pose.from_matrix(a.matrix()).matrix(), a.matrix(), atol=1e-12)
    for bad in ([1, 2, 3], {"xyz": [1, 2]}, "pose", {"xyz": [0, 0, 0], "rpy": [0, 0, 0], "rpy_deg": [0, 0, 0]},
                {"xyz": [0, 0, float("nan")]}):
        with pytest.raises(ValidationError):
            Pose.model_validate(bad)


def test_jacobian_matches_finite_differences_of_pinocchio_fk(robot):
    k = robot.kinematics
    rng = np.random.default_rng(0)
    h = 1e-6
    for _ in range(20):
        q = random_q(k, rng)
        H, J = k.fk_jacobian(q)
        np.testing.assert_allclose(k.jacobian(q), J, atol=1e-12)
        np.testing.assert_allclose(k.fk(q), H, atol=1e-12)
        for i in range(7):
            dq = np.zeros(7)
            dq[i] = h
            Hp, Hm = k.fk(q + dq), k.fk(q - dq)
            v = (Hp[:3, 3] - Hm[:3, 3]) / (2 * h)
            w = Rotation.from_matrix(Hp[:3, :3] @ Hm[:3, :3].T).as_rotvec() / (2 * h)
            np.testing.assert_allclose(J[:3, i], w, atol=1e-6)   # [ω; v] order, base frame
            np.testing.assert_allclose(J[3:, i], v, atol=1e-6)


def test_arm_twist_step_moves_the_tool_by_the_twist(robot):
    """Eq. 37 to first order: the tool's displacement is V dt."""
    k = robot.kinematics
    q = np.array(robot.params.q_home)
    V = np.array([0.1, -0.2, 0.05, 0.05, 0.02, -0.03])
    dt = 1e-4
    H0, J = k.fk_jacobian(q)
    q1 = pbvs.arm_twist_step(q, J, V, dt, 1e-6)
    L = pbvs.ee_error_vector(H0, k.fk(q1)) / dt
    np.testing.assert_allclose(L, V, atol=1e-4)


def test_robot_params_reject_bad_values():
    with pytest.raises(ValidationError):
        MobileIiwa.Params(v_max=1.5)  # the paper's platform tops out at 1.0 m/s
    with pytest.raises(ValidationError):
        MobileIiwa.Params(q_home=(0, 0, 0))
    with pytest.raises(ValidationError):
        MobileIiwa.Params(tool={"length": 0.02, "bit_length": 0.03})


@pytest.mark.sim
def test_pybullet_and_pinocchio_tool_frames_agree_within_0_1_mm(robot):
    import pybullet as p
    from taskflow_sim.screw.body import MobileIiwaBody

    client = p.connect(p.DIRECT)
    try:
        body = MobileIiwaBody(client, robot, (0.3, -0.7, 0.4), np.array(robot.params.q_home))
        k = robot.kinematics
        # the joints PyBullet found by name are the ones Pinocchio orders
        names = [p.getJointInfo(body.id, j, physicsClientId=client)[1].decode() for j in body.arm]
        assert tuple(names) == ARM_JOINTS
        rng = np.random.default_rng(1)
        worst = 0.0
        for _ in range(50):
            q = random_q(k, rng)
            pose = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-math.pi, math.pi))
            body.set_joints(q)
            body.set_platform(pose)
            H_wb = body.base_pose()
            for frame, link in (("tool_tip", body.tip_link), ("camera_optical", body.camera_link)):
                pb = body.link_pose(link)
                pn = H_wb @ k.frame_pose(q, frame)
                worst = max(worst, float(np.linalg.norm(pb[:3, 3] - pn[:3, 3])))
                assert spatial.rotation_angle(pb[:3, :3] @ pn[:3, :3].T) < 1e-5
        assert worst < 1e-4, f"worst tool-frame disagreement {worst * 1e3:.4f} mm"
        np.testing.assert_allclose(k.frame_pose(np.zeros(7), "camera_optical"), robot.params.T_body_camera(), atol=1e-12)
    finally:
        p.disconnect(client)
