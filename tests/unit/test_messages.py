"""taskflow.messages: every message carries stamp and frame, is immutable, and checks against its ObsSpec."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from taskflow import messages as m
from taskflow.api import message
from taskflow.catalogue.conformance import equal

EYE = np.eye(4)


def examples() -> list[m.Message]:
    return [
        m.Image(stamp=0.5, frame="camera", pixels=np.zeros((4, 6, 3), dtype=np.uint8)),
        m.Depth(stamp=0.5, frame="front_camera", z=np.ones((4, 6))),
        m.Detection(stamp=0.5, frame="front_camera", camera="front", seq=2, bbox=(1.0, 2.0, 3.0, 4.0), depth=1.0,
                    intrinsics=(100.0, 100.0, 3.0, 2.0), width=6, height=4),
        m.FeatureView(stamp=0.5, frame="camera", ids=np.array([1, 4]), uv=np.array([[1.0, 2.0], [3.0, 4.0]])),
        m.Silhouette(stamp=0.5, frame="camera", u_left=10.0, u_right=20.0, touches_border=False),
        m.MarkerPose(stamp=0.4, frame="camera", T_camera_object=EYE, seq=1),
        m.Wrench(stamp=0.5, frame="tool", force=np.zeros(3), torque=np.zeros(3)),
        m.JointState(stamp=0.5, frame="arm", names=("a", "b"), position=np.zeros(2), velocity=np.zeros(2)),
        m.Odometry(stamp=0.5, frame="odom", pose=(1.0, 2.0, 0.1)),
    ]


@pytest.mark.parametrize("msg", examples(), ids=lambda x: type(x).__name__)
def test_every_message_has_a_stamp_and_a_frame_and_is_frozen(msg):
    assert isinstance(msg, m.Message) and isinstance(msg.stamp, float) and isinstance(msg.frame, str) and msg.frame
    with pytest.raises(dataclasses.FrozenInstanceError):
        msg.stamp = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        msg.frame = "world"  # type: ignore[misc]
    assert equal(msg, dataclasses.replace(msg))  # the conformance check compares messages field by field
    assert not equal(msg, dataclasses.replace(msg, frame="elsewhere"))


@pytest.mark.parametrize("cls", [type(x) for x in examples()], ids=lambda c: c.__name__)
def test_messages_are_built_by_keyword_only(cls):
    with pytest.raises(TypeError):
        cls(0.0, "camera")  # positional fields would silently swap stamp, frame, seq ...


def test_obs_spec_of_a_message_matches_its_class_only():
    img, feat = examples()[0], examples()[3]
    assert message(m.Image).problem(img) is None and message(m.Image).problem(None) is None  # optional
    assert "not Image" in message(m.Image).problem(feat)
    assert message(m.Image, optional=False).problem(None) == "is None"
    assert message(m.Image).satisfies(message(m.Image)) and not message(m.Image).satisfies(message(m.FeatureView))
    assert message(m.Detection).satisfies(message(m.Message))  # a consumer may ask for any message


def test_detection_stale_keeps_everything_but_fresh():
    d = examples()[2]
    s = d.stale()
    assert d.fresh and not s.fresh and s.stale() is s
    assert (s.stamp, s.frame, s.camera, s.seq, s.bbox, s.depth) == (d.stamp, d.frame, d.camera, d.seq, d.bbox, d.depth)
    assert d.depth_at(1.0, 1.0) is None and d.depth_in((0.0, 0.0, 1.0, 1.0)) is None  # no depth image by default


def test_feature_view_length_and_image_size():
    assert len(examples()[3]) == 2
    assert examples()[0].size == (6, 4)


def test_a_sequence_of_messages_checks_every_element():
    from taskflow.api import sequence

    views = (examples()[3], examples()[3])
    assert sequence(of=m.FeatureView).problem(views) is None and sequence().problem(views) is None
    assert sequence(of=m.Image).problem(views) == "has element 0 of type FeatureView, not Image"
    assert str(sequence(of=m.Image, optional=True)) == "sequence[Image]?"
    assert sequence(of=m.Image).satisfies(sequence()) and sequence(of=m.Image).satisfies(sequence(of=m.Message))
    assert not sequence().satisfies(sequence(of=m.Image)) and not sequence(of=m.Image).satisfies(sequence(of=m.FeatureView))


def test_the_compiler_refuses_a_task_reading_another_message_class_than_the_world_sends():
    from taskflow.api import Task
    from taskflow.mission.contracts import task_problem
    from taskflow.registry import ROBOTS, TASKS, WORLDS

    world, robot = WORLDS.get("screw_conveyor"), ROBOTS.get("mobile_iiwa")
    assert task_problem(TASKS.get("pbvs_arm"), robot, world) is None

    class ReadsMarkerAsImage(Task):
        name = "reads_marker_as_image"
        requires = {"sensors.marker": message(m.Image)}

    msg, hint = task_problem(ReadsMarkerAsImage, robot, world)
    assert "reads observation sensors.marker as Image?, but it is MarkerPose?" in msg
    assert "sensors.wrench (Wrench)" in hint
    for name in ("visual_path_servo", "visual_path_rematch"):  # both camera messages are declared by quad_room
        assert task_problem(TASKS.get(name), ROBOTS.get("quadcopter"), WORLDS.get("quad_room")) is None
