"""The conformance check (``taskflow/catalogue/conformance.py``) over every shipped world x every shipped robot it
hosts, and proof that it catches what it claims to (on the toy world)."""

from __future__ import annotations

from importlib import metadata

import pytest
from toys import ToyLine, ToyPoint

from taskflow.api import ObsSpec, array, scalar
from taskflow.catalogue.conformance import IMPURE, check_pair, pairs

SHIPPED_WORLDS = sorted(ep.name for ep in metadata.entry_points(group="taskflow.worlds"))
SHIPPED_ROBOTS = sorted(ep.name for ep in metadata.entry_points(group="taskflow.robots"))
FAST = {"quad_room": {"perception": "geometric"}}  # projected landmarks instead of rendered frames
PAIRS = pairs(SHIPPED_WORLDS, SHIPPED_ROBOTS)


def test_every_shipped_robot_has_a_world_and_ground_robots_share_flat_ground():
    hosted = {r.name for _, r in PAIRS}
    assert hosted == set(SHIPPED_ROBOTS)
    assert {r.name for w, r in PAIRS if w.name == "flat_ground"} >= {"racecar", "husky"}
    assert ("viki_ground", "husky") in {(w.name, r.name) for w, r in PAIRS}  # it carries the camera mounts
    assert ("quad_room", "husky") not in {(w.name, r.name) for w, r in PAIRS}  # a unicycle is not a quadcopter


@pytest.mark.parametrize("world_cls, robot_cls", PAIRS, ids=[f"{w.name}-{r.name}" for w, r in PAIRS])
def test_shipped_pair_conforms(world_cls, robot_cls):
    res = check_pair(world_cls, robot_cls, FAST.get(world_cls.name), steps=4)
    assert res.ok, str(res)


def test_an_impure_observe_is_reported():
    class Impure(ToyLine):
        observations: dict[str, ObsSpec] = {"state.x": scalar()}

        def observe(self):
            self.x += 1.0  # observing moves the world
            return super().observe()

    Impure.name = "toy_impure"
    res = check_pair(Impure, ToyPoint, steps=2)
    assert IMPURE + " (after reset)" in res.problems and IMPURE + " (after an advance)" in res.problems
    pure = check_pair(type("Pure", (ToyLine,), {"observations": {"state.x": scalar()}, "name": "toy_pure"}),
                      ToyPoint, steps=2)
    assert not any(p.startswith(IMPURE) for p in pure.problems), pure.problems


def test_robots_of_one_interface_share_one_command_layout():
    from taskflow.registry import ROBOTS

    layouts: dict[str, dict[str, int]] = {}
    for name in SHIPPED_ROBOTS:
        cls = ROBOTS.get(name)
        assert cls.command_interface, f"{name} declares no command interface"
        assert layouts.setdefault(cls.command_interface, cls.command_keys) == cls.command_keys, name


def test_undeclared_observations_are_reported():
    res = check_pair(ToyLine, ToyPoint, steps=2)
    assert "observation state.x is not declared by the robot or the world" in res.problems


def test_wrong_types_and_missing_entries_are_reported():
    class Declared(ToyLine):
        observations: dict[str, ObsSpec] = {"state.x": array(3), "sensors.range": scalar()}

    Declared.name = "toy_declared"
    res = check_pair(Declared, ToyPoint, steps=2)
    assert any("observation state.x is float, not a numeric numpy array" in p for p in res.problems), res.problems
    assert "observation sensors.range (scalar) is declared but missing" in res.problems


def test_a_world_that_ignores_its_seed_is_reported():
    class Unseeded(ToyLine):
        observations: dict[str, ObsSpec] = {"state.x": scalar()}
        calls = 0

        def reset(self) -> None:
            super().reset()
            Unseeded.calls += 1
            self.x = float(Unseeded.calls)  # a different start every reset

    Unseeded.name = "toy_unseeded"
    res = check_pair(Unseeded, ToyPoint, steps=2)
    assert "two resets with one seed give different first observations" in res.problems
    assert "two seeded rollouts differ at tick 0" in res.problems


def test_cli_check_reports_and_exits_zero(capsys):
    from taskflow.cli import main

    assert main(["check", "--world", "flat_ground", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "flat_ground x husky: ok" in out and "flat_ground x racecar: ok" in out
    assert main(["check", "--world", "flat_grund"]) == 1
    assert "did you mean 'flat_ground'" in capsys.readouterr().err
