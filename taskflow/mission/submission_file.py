"""A sub-mission file (``submission:`` + ``machine:``, :mod:`taskflow.mission.submission`): its top level
(:class:`Submission`) and the checks it passes before its machine is spliced into the mission that uses it
(:func:`check_submission`)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from taskflow.errors import Problem
from taskflow.mission.diagnostics import pydantic_problems
from taskflow.mission.statetree import MAX_STATE_DEPTH, state_names, targets, too_deep
from taskflow.mission.yamlsrc import SourceMap
from taskflow.registry import describe_choices

MACHINE_KEYS = ("initial", "states", "task", "bind")
"""The keys a sub-mission's ``machine:`` may have."""


def with_via(p: Problem, via: tuple[str, ...]) -> Problem:
    return Problem(p.file, p.line, p.col, p.message, p.hint, p.via + via)


class Submission(BaseModel):
    """A sub-mission file's top level (its machine is checked with the mission it is spliced into)."""

    model_config = ConfigDict(extra="forbid")

    submission: str = Field(description="name of the sub-mission")
    description: str = ""
    parameters: dict[str, Any] = Field(default_factory=dict, description="name → default; null: required")
    profiles: dict[str, dict[str, dict[str, Any]]] = Field(default_factory=dict)
    exits: list[str] = Field(default_factory=list, description="states of the using mission that transitions of "
                                                               "this machine may go to (by name)")
    machine: dict[str, Any]


def check_submission(data: Any, inner_map: SourceMap, via: tuple[str, ...]) -> tuple[Submission | None, list[Problem]]:
    """The sub-mission file ``data`` (read with ``inner_map``; used from ``via``) shape-checked: its top level,
    its machine's keys, its depth, its transitions' targets (its own states or its ``exits``).  The
    problems carry ``via``; the document is None when it cannot be used."""
    problems: list[Problem] = []
    if not isinstance(data, dict):
        problems.append(with_via(inner_map.problem((), "a sub-mission is a mapping of keys",
                                                   "start with `submission: NAME`"), via))
        return None, problems
    if "mission" in data:
        problems.append(with_via(inner_map.problem(
            ("mission",), "a used file is a sub-mission, not a mission",
            "write `submission: NAME` instead of `mission:`, and no robot, world, rate_hz, seed or max_time"), via))
        return None, problems
    try:
        doc = Submission.model_validate(data)
    except ValidationError as exc:
        problems.extend(with_via(p, via) for p in pydantic_problems(exc, inner_map, (), Submission))
        return None, problems
    odd = [k for k in doc.machine if k not in MACHINE_KEYS]
    if odd:
        problems.append(with_via(inner_map.problem(
            ("machine", odd[0]), f"unknown key {odd[0]!r}", describe_choices(odd[0], list(MACHINE_KEYS))), via))
        return None, problems
    deep = too_deep(doc.machine.get("states"), ("machine", "states"))
    if deep is not None:
        problems.append(with_via(inner_map.problem(deep, f"states nest more than {MAX_STATE_DEPTH} levels deep here",
                                                   f"a mission's states may nest at most {MAX_STATE_DEPTH} levels; "
                                                   "flatten it"), via))
        return None, problems
    own = state_names(doc.machine.get("states"))
    for tpath, to in targets(doc.machine.get("states"), ("machine", "states")):
        if to.split(".")[0] not in own and to not in doc.exits:
            problems.append(with_via(inner_map.problem(
                tpath, f"target {to!r} is not a state of this sub-mission",
                f"{describe_choices(to.split('.')[0], sorted(own | set(doc.exits)))} (its states and exits), or "
                f"list {to!r} under `exits:` when it is a state of the mission that uses it"), via))
    return doc, problems
