"""Loader behaviours added after the broken-mission corpus: YAML 1.2 numbers, --set through a bare
component name, every foreach item checked against the task, the control period in TaskContext."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission, load_mission_text
from taskflow.mission.yamlsrc import load_yaml_text

TOY = Path(__file__).parents[1] / "machine" / "missions" / "toy_full.yaml"


def test_yaml_12_exponent_floats_are_numbers():
    data, _ = load_yaml_text("a: 1e5\nb: 1.0e5\nc: -2.5E-3\nd: 1e\n", "f.yaml")
    assert data == {"a": 1e5, "b": 1e5, "c": -2.5e-3, "d": "1e"}


def test_set_reaches_params_of_a_component_named_by_a_bare_string():
    text = TOY.read_text()
    assert "robot: toy_point" in text
    m = load_mission_text(text, "toy.yaml", overrides=["robot.params.v_max=0.25"])
    assert m.robot_params.v_max == 0.25


def test_every_foreach_item_is_checked_against_the_task():
    text = TOY.read_text().replace("goals: [1.0, 2.0, 3.0]", "goals: [1.0, 2.0, three]")
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "toy.yaml")
    p = exc.value.problems[0]
    assert "item 2 of 'goals' does not fit task 'toy_goto'" in p.message
    assert p.line == next(i for i, line in enumerate(text.splitlines(), 1) if "goals:" in line)


def test_tasks_get_the_control_period():
    m = load_mission(TOY, overrides=["rate_hz=50"])
    seen = []

    def factory(cls, ctx):  # type: ignore[no-untyped-def]
        seen.append(ctx.dt)
        return cls(ctx)

    run_mission(m, task_factory=factory, record=False, max_time=3.0)
    assert seen and all(dt == pytest.approx(1 / 50) for dt in seen)


def test_a_partial_mapping_changes_one_field_of_a_default_sub_model():
    """``front_camera.width`` alone keeps the default mount (pose, rate): the sub-model is completed
    from the field's default, not rebuilt from the width alone (which has no pose and was refused)."""
    import taskflow_robots.racecar  # noqa: F401 - registration
    from taskflow_robots.racecar import RacecarParams

    viki = Path(__file__).resolve().parents[2] / "missions" / "viki_hyco.yaml"
    m = load_mission(viki, overrides=["robot.params.front_camera.width=320"])
    default = RacecarParams().front_camera
    cam = m.robot_params.front_camera
    assert cam.width == 320 and default.width != 320
    assert cam.model_dump(exclude={"width"}) == default.model_dump(exclude={"width"})
    assert m.robot_params.rear_camera == RacecarParams().rear_camera
    with pytest.raises(MissionError, match="front_camera.width"):
        load_mission(viki, overrides=["robot.params.front_camera.width=-3"])


def _keyed_task(speed_key: str) -> type:
    from taskflow.api import Observation, ObsKey, StepResult, Task, array, scalar

    pose = ObsKey("state.pose", array(3))
    speed = ObsKey(speed_key, scalar())

    class KeyedHold(Task):
        """Holds still; reads its pose and speed through keys."""

        command_interface = "ackermann"
        requires = (pose, speed)

        def step(self, obs: Observation) -> StepResult:
            speed(obs), pose(obs)
            return StepResult({"v": np.zeros(1), "steer": np.zeros(1)})

    return KeyedHold


KEYED = """mission: keyed
robot: racecar
world: flat_ground
rate_hz: 20
max_time: 1 s
machine:
  initial: go
  states:
    go:
      task: {name: keyed_hold}
      transitions:
        - {to: done, after: 0.5 s}
    done: {final: succeeded}
"""


@pytest.mark.parametrize("key, ok", [("state.v", True), ("state.vv", False), ("sensors.v", False)])
def test_a_misspelt_observation_key_is_an_error_at_load(key, ok):
    """A task reading ``state.vv`` (meaning ``state.v``) through an :class:`ObsKey` in its ``requires``
    is refused when the mission loads — not a robot that holds still because the read came back empty."""
    import taskflow_robots.racecar  # noqa: F401 - registration
    import taskflow_sim.ground.flat_ground  # noqa: F401 - registration

    from taskflow.registry import TASKS

    TASKS.add("keyed_hold", _keyed_task(key))
    try:
        if ok:
            m = load_mission_text(KEYED, "keyed.yaml")
            assert run_mission(m, record=False).outcome == "succeeded"
            return
        with pytest.raises(MissionError) as exc:
            load_mission_text(KEYED, "keyed.yaml")
        p = exc.value.problems[0]
        assert f"task 'keyed_hold' reads observation {key} (scalar)" in p.message
        assert "state.v (scalar)" in p.hint and p.line == 10
    finally:
        TASKS.remove("keyed_hold")


def test_an_absent_required_key_read_names_the_key():
    from taskflow.api import MissingObservation, Observation, ObsKey, scalar

    obs = Observation(t=0.0, state={"v": 0.0})
    assert ObsKey("state.v", scalar())(obs) == 0.0
    assert ObsKey("sensors.range", scalar(optional=True))(obs) is None
    with pytest.raises(MissingObservation, match="'state.vv'"):
        ObsKey("state.vv", scalar())(obs)
