"""The mission file format as pydantic models (unknown keys are errors).

These models check the *shape* of a mission.  Names (tasks, states, profiles, metrics, events) are
resolved afterwards by :mod:`taskflow.mission.loader`, which knows the registries.  ``taskflow schema``
prints :func:`mission_json_schema` for editors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    field_validator,
    model_validator,
)

from taskflow.units import UnitError, parse_duration, parse_max_time, parse_rate

OUTCOMES = ("succeeded", "failed", "aborted")
SEED_MAX = 2**63 - 1
"""The largest seed (``seed:``, ``--seed``): numpy's and the record's 64-bit signed integers."""
Outcome = Literal["succeeded", "failed", "aborted"]


def _quantity(parse: Callable[[str | float | int], float]) -> AfterValidator:
    """A pydantic validator that parses a number-or-quantity with ``parse`` (a :mod:`taskflow.units`
    parser) and turns its :class:`UnitError` into the validation error pydantic reports."""

    def validate(v: str | float | int) -> float:
        try:
            return parse(v)
        except UnitError as exc:
            raise ValueError(str(exc)) from None

    return AfterValidator(validate)


Duration = Annotated[float | int | str, _quantity(parse_duration)]
"""``"5 s"``, ``"200 ms"`` or a number of seconds; stored as seconds."""

MaxTime = Annotated[float | int | str, _quantity(parse_max_time)]
"""A run's simulated time limit: a duration > 0 and at most one simulated day."""

Rate = Annotated[float | int | str, _quantity(parse_rate)]
"""A rate: ``20``, ``"20 Hz"`` or ``"1 kHz"``; stored in Hz."""


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


MAX_RETRIES = 10
"""The most further attempts a ``foreach`` item may declare (``retry``): every expansion has a budget."""


class Retry(_Model):
    """``retry: N`` or ``retry: {times: N, on: [FINAL, ...]}``: an item whose sub-machine ends in one of the
    final states ``on`` (default: every ``failed`` final of the sub-machine) is run again from the
    sub-machine's ``initial`` state, up to ``times`` more times, before it counts."""

    times: StrictInt = Field(description=f"further attempts of a failed item, 0 to {MAX_RETRIES}")
    on: list[str] | None = Field(None, description="the final states of the sub-machine worth retrying "
                                                   "(default: every `failed` one; `aborted` ones only when named)")

    @field_validator("times")
    @classmethod
    def _times(cls, v: int) -> int:
        if not 0 <= v <= MAX_RETRIES:
            raise ValueError(f"retry {v}: an item may be attempted again 0 to {MAX_RETRIES} times "
                             "(every expansion has a budget)")
        return v


class Foreach(_Model):
    """Run the sub-machine once per item of the list parameter ``in``, exposing it as ``as``."""

    in_: str = Field(alias="in", description="name of a list parameter")
    as_: str = Field(alias="as", description="name under which tasks see the current item")
    on_failure: Literal["stop", "continue"] = Field(
        "stop", description="an iteration ending failed/aborted: stop the loop (done with that outcome) or record it and go on")
    require: Literal["all"] | StrictInt | str = Field(
        "all", description="the loop's success rule: 'all' items, at least N items (an integer), or a share like '75 %'; "
                           "with fewer the loop finishes failed")
    retry: Retry | None = Field(None, description="run a failed item again: `retry: N` or `retry: {times: N, on: [FINAL, ...]}`; "
                                                  "the item counts on its last attempt")

    @field_validator("retry", mode="before")
    @classmethod
    def _retry(cls, v: Any) -> Any:
        if isinstance(v, (bool, float, str)):
            raise ValueError(f"retry {v!r} is not a number of further attempts (0 to {MAX_RETRIES}) "
                             "nor {times: N, on: [FINAL, ...]}")
        return {"times": v} if isinstance(v, int) else v

    @field_validator("require")
    @classmethod
    def _require(cls, v: str | int) -> str | int:
        if isinstance(v, bool):
            raise ValueError("require is 'all', a number of items or a share like '75 %', not a boolean")
        if isinstance(v, int):
            if v < 1:
                raise ValueError(f"require: at least 1 item must succeed, got {v}")
            return v
        if v == "all":
            return v
        text = v.strip()
        if text.endswith("%"):
            try:
                share = float(text[:-1])
            except ValueError:
                share = float("nan")
            if 0.0 < share <= 100.0:
                return f"{share:g} %"
        raise ValueError(f"require {v!r} is not 'all', a number of items or a share like '75 %'")

    def required(self, n_items: int) -> int:
        """How many of ``n_items`` must succeed for the loop to succeed."""
        if self.require == "all":
            return n_items
        if isinstance(self.require, int):
            return self.require
        share = float(str(self.require).rstrip(" %"))
        return max(1, math.ceil(share * n_items / 100.0 - 1e-9))


class Action(_Model):
    """An asynchronous action the world runs while the state is active (e.g. a screwdriver)."""

    name: str
    params: dict[str, Any] = Field(default_factory=dict)


SINCE_ENTRY = "entry"
SINCE_FIRST_ENTRY = "first_entry"


class Transition(_Model):
    """One way out of a state.  One trigger — ``when``, ``after``, ``on`` or ``done`` — or an event
    with a condition (``on`` + ``when``, SCXML's event + cond)."""

    to: str = Field(description="target state: a sibling or ancestor's sibling name, or a dotted path from the root")
    when: str | None = Field(None, description="guard expression over metrics, e.g. 'pos_error < 1 cm'; with `on`, "
                                                "the condition the event must find true")
    for_: Duration | None = Field(None, alias="for", description="the guard must hold this long")
    after: Duration | None = Field(None, description="time in the state (see `since`)")
    since: str | None = Field(None, description="what `after` counts from: 'entry' (default, every entry), 'first_entry' "
                                                "(kept across history resumes and re-entries), or the name of an "
                                                "enclosing state (its last entry)")
    on: str | None = Field(None, description="event name")
    done: StrictBool | Outcome | None = Field(None, description="the sub-machine finished (true: any outcome)")
    resume: StrictBool = Field(True, description="re-enter a history state where it was left")
    blend: Duration | None = Field(None, description="blend outgoing → incoming command with h(t) over this time")

    @model_validator(mode="after")
    def _one_trigger(self) -> Transition:
        given = [k for k in ("when", "after", "on", "done") if getattr(self, k) not in (None, False)]
        if len(given) != 1 and set(given) != {"on", "when"}:
            raise ValueError(
                f"a transition needs exactly one of when/after/on/done, or on + when (got {', '.join(given) or 'none'})")
        if self.for_ is not None and (self.when is None or self.on is not None):
            raise ValueError("'for' (dwell) only goes with a 'when' guard without 'on' (an event has no duration)")
        if self.since is not None and self.after is None:
            raise ValueError("'since' only goes with 'after'")
        return self


class State(_Model):
    """A state: a leaf runs a task; a composite holds ``states`` and an ``initial`` one."""

    description: str = ""
    task: str | TaskRef | None = Field(None, description="task name, or {name, params}; children inherit it")
    bind: dict[str, str | dict[str, Any]] = Field(
        default_factory=dict, description="profile slot → profile name (or inline values); children inherit")
    initial: str | None = None
    states: dict[str, State] = Field(default_factory=dict)
    transitions: list[Transition] = Field(default_factory=list)
    history: StrictBool = Field(False, description="re-entry resumes the sub-state last active")
    foreach: Foreach | None = None
    action: Action | None = None
    final: StrictBool | Outcome | None = Field(None, description="final state with this outcome (true = succeeded)")
    regions: dict[str, Region] = Field(
        default_factory=dict, description="parallel (orthogonal) regions, all active while the state is")
    outcome_map: dict[Outcome, dict[str, Outcome]] = Field(
        default_factory=dict, description="outcome → {region: outcome, ...}: the parallel state finishes with the "
                                          "first outcome whose regions have all finished so (checked in order)")
    use: str | None = Field(None, description="a sub-mission file (relative to this one, or taskflow:PATH for a shipped one) whose machine is this state's "
                                              "sub-machine; resolved at load by taskflow.mission.submission")
    with_: dict[str, Any] | None = Field(None, alias="with", description="the used sub-mission's parameters: a value "
                                                                          "or $name of this file")


class Region(_Model):
    """One parallel region of a state: a sub-machine that runs alongside the others and drives only the
    parts of the robot's command it ``owns``."""

    description: str = ""
    owns: list[str] = Field(default_factory=list, description="command parts this region drives (e.g. base_twist); "
                                                                "none: it commands nothing (a monitor)")
    task: str | TaskRef | None = Field(None, description="task name, or {name, params}; its states inherit it")
    bind: dict[str, str | dict[str, Any]] = Field(default_factory=dict, description="profile slot → profile name")
    initial: str
    states: dict[str, State]


State.model_rebuild()


class Machine(_Model):
    """The top of the machine: like a composite state without transitions of its own."""

    initial: str
    states: dict[str, State]
    task: str | TaskRef | None = None
    bind: dict[str, str | dict[str, Any]] = Field(default_factory=dict)


PROPERTY_PATTERNS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "absence": (("never",), ("while",)),
    "universality": (("always",), ()),
    "response": (("after", "within", "then"), ()),
    "precedence": (("only_after", "occurs"), ()),
}
"""A property's specification pattern → (the keys it requires, those it may add)."""


class Property(_Model):
    """One declared property of the mission (``properties: NAME: …``), in one specification pattern:
    absence (``never: A`` [``while: B``]), universality (``always: A``), response (``after: A``, ``within: T``,
    ``then: B``) or precedence (``only_after: A``, ``occurs: B``).  A, B: expressions over ``state(PATH)``,
    ``event(NAME)``, ``outcome(NAME)`` and metric comparisons with units, joined by and/or/not."""

    description: str = ""
    never: str | None = Field(None, description="absence: this never holds (while `while` holds, if given)")
    while_: str | None = Field(None, alias="while", description="absence: the condition under which `never` is forbidden")
    always: str | None = Field(None, description="universality: this holds at every tick")
    after: str | None = Field(None, description="response: once this holds, `then` must hold within `within`")
    within: str | float | int | None = Field(None, description="response: the deadline, a time with its unit ('0.05 s')")
    then: str | None = Field(None, description="response: what must follow `after`")
    only_after: str | None = Field(None, description="precedence: `occurs` may hold only once this has held")
    occurs: str | None = Field(None, description="precedence: what may happen only after `only_after`")

    @model_validator(mode="after")
    def _one_pattern(self) -> Property:
        given = {k for k in ("never", "while", "always", "after", "within", "then", "only_after", "occurs")
                 if getattr(self, "while_" if k == "while" else k) is not None}
        forms = "never [+ while] | always | after + within + then | only_after + occurs"
        for need, may in PROPERTY_PATTERNS.values():
            if need[0] in given:
                missing = [k for k in need if k not in given]
                extra = sorted(given - set(need) - set(may))
                if missing or extra:
                    parts = [f"missing {', '.join(map(repr, missing))}"] if missing else []
                    if extra:
                        parts.append(f"{', '.join(map(repr, extra))} {'does' if len(extra) == 1 else 'do'} not belong to it")
                    what = "; ".join(parts)
                    raise ValueError(f"a property in the form {need[0]!r}: {what} — one pattern per property: {forms}")
                return self
        raise ValueError(f"a property needs one pattern: {forms}")

    @property
    def pattern(self) -> str:
        """Its pattern's name (one of :data:`PROPERTY_PATTERNS`)."""
        return next(k for k, (need, _) in PROPERTY_PATTERNS.items() if getattr(self, need[0]) is not None)


class Mission(_Model):
    """A whole mission file."""

    mission: str = Field(description="mission name (used for run directories)")
    description: str = ""
    robot: str | ComponentRef
    world: str | ComponentRef
    rate_hz: Rate = Field(description="control rate: 20 or '20 Hz'; must divide the world's physics rate")
    seed: int = Field(0, ge=0, le=SEED_MAX)
    max_time: MaxTime = Field(600.0, description="simulated time limit (≤ one simulated day); reaching it ends the run "
                                                 "as 'timeout'")
    parameters: dict[str, Any] = Field(default_factory=dict, description="poses, lists of poses, thresholds ...")
    profiles: dict[str, dict[str, dict[str, Any]]] = Field(
        default_factory=dict, description="profile kind (gains, pid, impedance, setpoints ...) → name → values")
    events: list[str] = Field(default_factory=list, description="events the mission itself declares, raised only by an "
                                                            "operator (`taskflow ctl RUN inject NAME`), e.g. "
                                                            "operator_confirmed")
    data: dict[str, Any] = Field(default_factory=dict, description="mission-data key (declared by a task of the "
                                 "mission, e.g. viki.object) → the value it holds from the start of the run")
    properties: dict[str, Property] = Field(
        default_factory=dict, description="property name → one specification pattern (never/while, always, "
        "after/within/then, only_after/occurs), checked at load and monitored in every run")
    machine: Machine

    @field_validator("parameters", "data", "profiles", "machine", "properties", mode="before")
    @classmethod
    def _keys_are_names(cls, value: Any) -> Any:
        """``1: 2`` or ``~: x`` under a block of names: say so (pydantic says "Input should be a valid string")."""
        if isinstance(value, dict):
            odd = next((k for k in value if not isinstance(k, str)), None)
            if odd is not None or None in value:
                raise ValueError(f"key {'~ (null)' if odd is None else f'{odd!r} ({type(odd).__name__})'} is not a name: "
                                 "write the name as text (quote it if it looks like a number)")
        return value


def mission_json_schema() -> dict[str, Any]:
    schema = Mission.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "taskflow mission"
    return schema
