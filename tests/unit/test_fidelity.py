"""Fidelity levels: a level fills the parameters a mission leaves unset, explicit keys win, unknown
levels are refused with the valid names, and every registered world's tables name real parameters."""

from __future__ import annotations

from typing import ClassVar

import pytest
from pydantic import Field, ValidationError

from taskflow.fidelity import Fidelity, Level, Sourced, check_fidelity
from taskflow.registry import WORLDS


class Toy(Fidelity):
    FIDELITY: ClassVar[dict[str, Level]] = {
        "paper": {"noise": Sourced(2.0, "paper §4"), "latency": Sourced(0.044, "paper §5: 12 + 30 ms")}}
    noise: float = Field(default=0.5, ge=0.0)
    latency: float = 0.0
    other: int = 1


def test_ideal_is_the_models_defaults() -> None:
    assert Toy() == Toy.model_validate({"fidelity": "ideal"})
    assert (Toy().noise, Toy().latency) == (0.5, 0.0)


def test_a_level_fills_unset_parameters_and_explicit_keys_win() -> None:
    t = Toy.model_validate({"fidelity": "paper", "noise": 3.0})
    assert (t.fidelity, t.noise, t.latency, t.other) == ("paper", 3.0, 0.044, 1)
    assert Toy.model_validate({"fidelity": "paper"}).noise == 2.0


def test_an_unknown_level_names_the_valid_ones() -> None:
    with pytest.raises(ValidationError, match=r"unknown fidelity 'papr' — valid: ideal, paper"):
        Toy.model_validate({"fidelity": "papr"})


def test_check_fidelity_refuses_a_typo_and_a_bad_value() -> None:
    class Typo(Toy):
        FIDELITY: ClassVar[dict[str, Level]] = {"paper": {"noize": Sourced(1.0, "x")}}

    class Bad(Toy):
        FIDELITY: ClassVar[dict[str, Level]] = {"paper": {"noise": Sourced(-1.0, "x")}}

    with pytest.raises(TypeError, match="noize"):
        check_fidelity(Typo)
    with pytest.raises(ValidationError):
        check_fidelity(Bad)


WITH_LEVELS = [n for n in WORLDS.names() if issubclass(WORLDS.get(n).Params, Fidelity)]


def test_the_paper_worlds_have_fidelity_levels() -> None:
    assert {"viki_ground", "quad_room", "screw_conveyor"} <= set(WITH_LEVELS)


@pytest.mark.parametrize("name", WITH_LEVELS)
def test_every_world_level_names_real_parameters_with_sources(name: str) -> None:
    params = WORLDS.get(name).Params
    check_fidelity(params)
    for level in params.FIDELITY.values():
        assert all(s.source.strip() for s in level.values())


def test_the_catalogue_lists_each_level_with_its_sources() -> None:
    from taskflow.catalogue.catalogue import Entry, fidelity_levels
    from taskflow.catalogue.catalogue_render import describe_text

    text = describe_text(Entry(kind="world", name="toy", summary="", fidelity=fidelity_levels(Toy)))
    assert "fidelity paper (`world.params.fidelity: paper`" in text
    assert "latency: 0.044 — paper §5: 12 + 30 ms" in text and "noise: 2.0 — paper §4" in text
