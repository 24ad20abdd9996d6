"""Loader behaviours added after the broken-mission corpus: YAML 1.2 numbers, --set through a bare
component name, every foreach item checked against the task, the control period in TaskContext."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission, load_mission_text
from taskflow.mission.yamlsrc import load_yaml_text

TOY = Path(__file__).parent / "machine" / "missions" / "toy_full.yaml"


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

    viki = Path(__file__).resolve().parents[1] / "missions" / "viki_hyco.yaml"
    m = load_mission(viki, overrides=["robot.params.front_camera.width=320"])
    default = RacecarParams().front_camera
    cam = m.robot_params.front_camera
    assert cam.width == 320 and default.width != 320
    assert cam.model_dump(exclude={"width"}) == default.model_dump(exclude={"width"})
    assert m.robot_params.rear_camera == RacecarParams().rear_camera
    with pytest.raises(MissionError, match="front_camera.width"):
        load_mission(viki, overrides=["robot.params.front_camera.width=-3"])
