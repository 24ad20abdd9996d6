"""The task contract's declarations beyond parameters: the robot kinematics a law computes with
(``Task.kinematics`` against ``Robot.kinematics_model``) and the profiles bound from a slot's defaults."""

from __future__ import annotations

import pytest
from pydantic import Field

from taskflow.api import NoParams, Robot, StrictModel, Task
from taskflow.mission.contracts import kinematics_problem
from taskflow.testing import task_context


class Kin:
    """A kinematics model."""


class SubKin(Kin):
    pass


class KinRobot(Robot):
    name = "kin_robot"
    command_keys = {"v": 1}
    kinematics_model = SubKin

    def __init__(self, params: NoParams) -> None:
        super().__init__(params)
        self.kinematics = SubKin()


class PlainRobot(Robot):
    name = "plain_robot"
    command_keys = {"v": 1}


class Defaults(StrictModel):
    gain: float = Field(default=2.0, gt=0.0)


class Required(StrictModel):
    gain: float


class KinTask(Task):
    name = "kin_task"
    kinematics = Kin
    slots = {"defaults": Defaults, "required": Required}


def test_the_loader_checks_the_robot_provides_the_kinematics():
    assert kinematics_problem(KinTask, KinRobot) is None  # a subclass serves
    why = kinematics_problem(KinTask, PlainRobot)
    assert why is not None and "computes with Kin kinematics; robot 'plain_robot' provides none" in why[0]
    assert kinematics_problem(Task, PlainRobot) is None  # a task that declares none


def test_ctx_kinematics_is_typed_and_checked():
    ctx = task_context(KinTask, NoParams(), KinRobot(NoParams()), {"required": Required(gain=1.0)})
    assert isinstance(ctx.kinematics(Kin), SubKin)
    with pytest.raises(TypeError, match="no Kin kinematics"):
        task_context(KinTask, NoParams(), PlainRobot(NoParams())).kinematics(Kin)


def test_a_slot_with_defaults_is_bound_to_them_and_one_without_is_not():
    bound = KinTask.default_profiles({"required": Required(gain=1.0)})
    assert bound == {"required": Required(gain=1.0), "defaults": Defaults()}
    assert KinTask.default_profiles() == {"defaults": Defaults()}
    ctx = task_context(KinTask, NoParams(), KinRobot(NoParams()))
    assert ctx.profile("defaults", Defaults).gain == 2.0 and ctx.optional_profile("required", Required) is None
