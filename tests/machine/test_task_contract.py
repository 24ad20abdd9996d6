"""A task declares the robot parameters it reads (``Task.robot_params``); the loader checks the mission's
robot has them, by field and type — not by robot name — and the framework hands the task a typed view of
them, so no task checks its robot, parameters or profiles again."""

from __future__ import annotations

import pytest
from pydantic import Field
from taskflow_robots.husky import Husky
from taskflow_robots.racecar import Racecar
from taskflow_tasks.ground.car_goto import CarGeometry, CarGoto
from taskflow_tasks.ground.unicycle_goto import UnicycleGoto
from toys import ToyGoto, ToyLine

from taskflow.api import Robot, StepResult, StrictModel
from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.contracts import build_robot_params, robot_params_problem
from taskflow.mission.loader import load_mission_text
from taskflow.registry import ROBOTS, TASKS, WORLDS
from taskflow.testing import assert_outcome, run_on_world

MISSION = """
mission: m
robot: %s
world: toy_line
rate_hz: 20
max_time: 5 s
machine:
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: {kp: 1.0}}
      transitions: [{to: done, when: "pos_error < 1 cm"}]
    done: {final: succeeded}
"""


class _StrParams(StrictModel):
    v_max: str = "fast"


class _StrRobot(Robot):
    Params = _StrParams
    command_keys = {"v": 1}


class _FastParams(StrictModel):
    v_max: float = Field(default=2.5, gt=0)
    mass: float = 3.0


class _FastRobot(Robot):
    Params = _FastParams
    command_keys = {"v": 1}


@pytest.fixture(autouse=True)
def _robots(register):
    """The two robots, registered for each test of this module only (``register``, tests/conftest.py)."""
    for name, cls in (("toy_str", _StrRobot), ("toy_fast", _FastRobot)):
        register(ROBOTS, name, cls)


def test_a_robot_without_the_parameters_a_task_reads_is_refused_at_the_task_line() -> None:
    with pytest.raises(MissionError) as exc:
        load_mission_text(MISSION % "toy_wheel", "m.yaml")
    p = exc.value.first
    assert (p.line, p.col) == (11, 14), p  # the task's name
    assert "reads robot parameters v_max (ToyLimits); robot 'toy_wheel' has no v_max" in p.message, p
    assert "toy_point" in p.hint and "toy_fast" in p.hint and "toy_wheel" not in p.hint


def test_a_parameter_of_the_wrong_type_is_named() -> None:
    with pytest.raises(MissionError, match="has v_max as str, not float"):
        load_mission_text(MISSION % "toy_str", "m.yaml")


def test_any_robot_with_the_fields_is_accepted_and_the_task_gets_a_typed_view() -> None:
    r = run_on_world(load_mission_text(MISSION % "toy_fast", "m.yaml"))
    assert_outcome(r, "succeeded")
    view = r.executor.memory["toy.robot_params"]
    assert type(view).__name__ == "ToyLimits" and view.v_max == 2.5 and not hasattr(view, "mass")


def test_shipped_tasks_state_what_they_read_from_a_robot() -> None:
    assert robot_params_problem(CarGoto, Racecar) is None
    msg, hint = robot_params_problem(CarGoto, Husky)  # type: ignore[misc]
    assert "robot 'husky' has no psi_max" in msg and "racecar" in hint
    msg, _ = robot_params_problem(UnicycleGoto, Racecar)  # type: ignore[misc]
    assert "robot 'racecar' has no w_max" in msg
    racecar = Racecar(Racecar.Params(wheelbase=0.4))
    view = build_robot_params(CarGoto, racecar)
    assert isinstance(view, CarGeometry) and view.wheelbase == 0.4 and view.psi_max == racecar.params.psi_max


# -- what a task needs sensed: StepResult.sensors → World.select_sensors --------------------------------------

class _Looker(ToyGoto):
    """toy_goto that names the sensor it reads on its first step only."""

    def step(self, obs):  # type: ignore[no-untyped-def]
        res = super().step(obs)
        first = not getattr(self, "_looked", False)
        self._looked = True
        return StepResult(res.command, res.metrics, sensors=("cam",) if first else None)


class _Selecting(ToyLine):
    def reset(self) -> None:
        super().reset()
        self.selected: list[tuple[int, tuple[str, ...]]] = []

    def select_sensors(self, names: tuple[str, ...]) -> None:
        self.selected.append((self.k, names))


def test_the_sensors_a_step_names_reach_the_world_before_its_command(register) -> None:
    for reg, name, cls in ((TASKS, "toy_look", _Looker), (WORLDS, "toy_selecting", _Selecting)):
        register(reg, name, cls)
    m = load_mission_text((MISSION % "toy_point").replace("world: toy_line", "world: toy_selecting")
                          .replace("name: toy_goto", "name: toy_look"), "m.yaml")
    world = _Selecting(m.build_robot(), m.world_params(0), 0)
    r = run_mission(m, world=world, record=False)
    assert_outcome(r, "succeeded")
    assert [names for _, names in world.selected] == [("cam",)]  # once: None afterwards changes nothing
