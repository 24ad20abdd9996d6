"""The mission file format as pydantic models (unknown keys are errors).

These models check the *shape* of a mission.  Names (tasks, states, profiles, metrics, events) are
resolved afterwards by :mod:`taskflow.loader`, which knows the registries.  ``taskflow schema``
prints :func:`mission_json_schema` for editors.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator

from .units import UnitError, parse_duration

OUTCOMES = ("succeeded", "failed", "aborted")
Outcome = Literal["succeeded", "failed", "aborted"]


def _duration(v: Union[str, float, int]) -> float:
    try:
        return parse_duration(v)
    except UnitError as exc:
        raise ValueError(str(exc)) from None


Duration = Annotated[Union[float, int, str], AfterValidator(_duration)]
"""``"5 s"``, ``"200 ms"`` or a number of seconds; stored as seconds."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class ComponentRef(_Model):
    """A registered robot or world with its parameters."""

    name: str
    params: dict[str, Any] = Field(default_factory=dict)


class TaskRef(_Model):
    """A registered task with its parameters; ``$name`` values refer to mission parameters or
    ``foreach`` items."""

    name: str
    params: dict[str, Any] = Field(default_factory=dict)


class Foreach(_Model):
    """Run the sub-machine once per item of the list parameter ``in``, exposing it as ``as``."""

    in_: str = Field(alias="in", description="name of a list parameter")
    as_: str = Field(alias="as", description="name under which tasks see the current item")
    on_failure: Literal["stop", "continue"] = Field(
        "stop", description="an iteration ending failed/aborted: stop the loop (done with that outcome) or record it and go on")


class Action(_Model):
    """An asynchronous action the world runs while the state is active (e.g. a screwdriver)."""

    name: str
    params: dict[str, Any] = Field(default_factory=dict)


class Transition(_Model):
    """One way out of a state.  Exactly one trigger: ``when``, ``after``, ``on`` or ``done``."""

    to: str = Field(description="target state: a sibling or ancestor's sibling name, or a dotted path from the root")
    when: str | None = Field(None, description="guard expression over metrics, e.g. 'pos_error < 1 cm'")
    for_: Duration | None = Field(None, alias="for", description="the guard must hold this long")
    after: Duration | None = Field(None, description="time in the state")
    on: str | None = Field(None, description="event name")
    done: bool | Outcome | None = Field(None, description="the sub-machine finished (true: any outcome)")
    resume: bool = Field(True, description="re-enter a history state where it was left")
    blend: Duration | None = Field(None, description="blend outgoing → incoming command with h(t) over this time")

    @model_validator(mode="after")
    def _one_trigger(self) -> "Transition":
        given = [k for k in ("when", "after", "on", "done") if getattr(self, k) not in (None, False)]
        if len(given) != 1:
            raise ValueError(
                f"a transition needs exactly one of when/after/on/done (got {', '.join(given) or 'none'})")
        if self.for_ is not None and self.when is None:
            raise ValueError("'for' (dwell) only goes with a 'when' guard")
        return self


class State(_Model):
    """A state: a leaf runs a task; a composite holds ``states`` and an ``initial`` one."""

    description: str = ""
    task: str | TaskRef | None = Field(None, description="task name, or {name, params}; children inherit it")
    bind: dict[str, str | dict[str, Any]] = Field(
        default_factory=dict, description="profile slot → profile name (or inline values); children inherit")
    initial: str | None = None
    states: dict[str, "State"] = Field(default_factory=dict)
    transitions: list[Transition] = Field(default_factory=list)
    history: bool = Field(False, description="re-entry resumes the sub-state last active")
    foreach: Foreach | None = None
    action: Action | None = None
    final: bool | Outcome | None = Field(None, description="final state with this outcome (true = succeeded)")


class Machine(_Model):
    """The top of the machine: like a composite state without transitions of its own."""

    initial: str
    states: dict[str, State]
    task: str | TaskRef | None = None
    bind: dict[str, str | dict[str, Any]] = Field(default_factory=dict)


class Mission(_Model):
    """A whole mission file."""

    mission: str = Field(description="mission name (used for run directories)")
    description: str = ""
    robot: str | ComponentRef
    world: str | ComponentRef
    rate_hz: float = Field(gt=0, le=10_000, description="control rate")
    seed: int = Field(0, ge=0)
    max_time: Duration = Field(600.0, description="simulated time limit; reaching it ends the run as 'timeout'")
    parameters: dict[str, Any] = Field(default_factory=dict, description="poses, lists of poses, thresholds ...")
    profiles: dict[str, dict[str, dict[str, Any]]] = Field(
        default_factory=dict, description="profile kind (gains, pid, impedance, setpoints ...) → name → values")
    machine: Machine


def mission_json_schema() -> dict[str, Any]:
    schema = Mission.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "taskflow mission"
    return schema
