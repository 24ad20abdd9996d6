"""Fidelity levels: named sets of a world's imperfection parameters, each value with its source.

A world whose parameter model derives from :class:`Fidelity` takes ``fidelity: NAME`` in its
``world.params`` (or ``--set world.params.fidelity=paper``).  ``ideal`` is the model's own defaults.
Any other level fills in the parameters it names *unless the mission sets them itself*: an explicit
``world.params`` key always wins, so ``fidelity: paper`` with ``dropout: 0.3`` is the paper-like world
with a worse detector.  A level's values are ordinary parameter values, so the run's ``mission.yaml`` (the
mission as run, every parameter resolved) records what it set, and the catalogue (``taskflow describe
WORLD``) lists every level with the source of each number.

("Fidelity", not "profile": a mission's profiles are the gain, PID and impedance sets its states bind.)

One table, one place: a world declares ``FIDELITY = {"paper": {"key": Sourced(v, "source")}}`` on its
parameter model.  A source says where the number comes from — a paper's stated rate or latency, a
sensor's datasheet, or a measurement of this project's detector (with its command).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import Field, field_validator, model_validator

from taskflow.api import StrictModel

IDEAL = "ideal"


@dataclass(frozen=True)
class Sourced:
    """One parameter value of a fidelity level and where it comes from (paper section, datasheet, measurement)."""

    value: Any
    source: str


Level = Mapping[str, Sourced]
"""Parameter name → value with its source."""


class Fidelity(StrictModel):
    """Mixin for a world's parameter model: a ``fidelity`` key choosing one of ``FIDELITY`` (or ``ideal``)."""

    FIDELITY: ClassVar[Mapping[str, Level]] = {}

    fidelity: str = Field(default=IDEAL, description="'ideal' (these defaults) or a named level of the world (e.g. "
                          "'paper'), which sets the imperfection parameters the mission leaves unset")

    @model_validator(mode="before")
    @classmethod
    def _apply_fidelity(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        name = data.get("fidelity", IDEAL)
        if not isinstance(name, str) or name not in cls.FIDELITY:
            return data  # ideal, or unknown: refused by _known_level with the key's own location
        filled = dict(data)
        for key, sourced in cls.FIDELITY[name].items():
            filled.setdefault(key, sourced.value)
        return filled

    @field_validator("fidelity")
    @classmethod
    def _known_level(cls, name: str) -> str:
        if name not in cls.fidelity_names():
            raise ValueError(f"unknown fidelity {name!r} — valid: {', '.join(cls.fidelity_names())}")
        return name

    @classmethod
    def fidelity_names(cls) -> tuple[str, ...]:
        """``ideal`` then the declared levels, in declaration order."""
        return (IDEAL, *cls.FIDELITY)


def check_fidelity(model: type[Fidelity]) -> None:
    """Raise ``TypeError`` if a level names a parameter the model does not have, or ``ValidationError``
    if the model refuses a level's values (the tests call it for every registered world)."""
    for name, level in model.FIDELITY.items():
        unknown = sorted(set(level) - set(model.model_fields))
        if unknown:
            raise TypeError(f"{model.__name__} fidelity {name!r} names unknown parameters {unknown}")
        model.model_validate({"fidelity": name})
