"""Pydantic's validation errors as mission problems: each error's location mapped back to the file's
line and column (through the source map), union-member noise dropped, unknown keys answered with the
valid ones."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from taskflow.errors import Problem
from taskflow.mission.model import YPath
from taskflow.mission.schema import Mission, State
from taskflow.mission.yamlsrc import SourceMap
from taskflow.registry import describe_choices

_UNION_TAGS = ("str", "TaskRef", "ComponentRef", "bool", "float", "int", "list", "dict")


def clean_loc(loc: tuple[Any, ...]) -> tuple[Any, ...]:
    """Drop pydantic's union-member tags from an error location; map aliases back."""
    out: list[Any] = []
    for part in loc:
        if isinstance(part, str) and (part in _UNION_TAGS or "[" in part or part.startswith("function-")
                                      or part in ("literal['succeeded','failed','aborted']",)):
            continue
        out.append({"for_": "for", "in_": "in", "as_": "as"}.get(part, part) if isinstance(part, str) else part)
    return tuple(out)


_UNION_NOISE = ("bool_type", "bool_parsing", "string_type", "float_type", "float_parsing", "int_type",
                "int_parsing", "dict_type", "list_type", "model_type", "model_attributes_type")


def pydantic_problems(exc: ValidationError, smap: SourceMap, base: YPath, model: type[BaseModel] | None = None) -> list[Problem]:
    errors = [(base + clean_loc(tuple(e["loc"])), e) for e in exc.errors()]
    # a value that fails a union (e.g. `final: crashed` against bool | Literal[...]) produces one error per
    # member: keep the most telling ones (the literal's choices) and drop the members' type noise
    informative = {p for p, e in errors if e["type"] not in _UNION_NOISE}
    problems: list[Problem] = []
    seen: set[tuple[Any, ...]] = set()
    for path, err in errors:
        etype = err["type"]
        if etype in _UNION_NOISE and path in informative:
            continue
        loc = path[len(base):]
        msg = err["msg"].removeprefix("Value error, ")
        hint = ""
        if etype == "extra_forbidden":
            key = loc[-1] if loc else "?"
            valid = _allowed_keys(model or Mission, loc[:-1])
            msg = f"unknown key {key!r}"
            hint = describe_choices(str(key), valid) if valid else ""
        elif etype == "missing":
            msg = f"missing required key {loc[-1]!r}" if loc else "missing value"
            path = path[:-1]
        elif etype.startswith("literal_error"):
            hint = msg
            msg = f"invalid value {err.get('input')!r}"
        elif etype in ("bool_type", "bool_parsing"):
            msg = f"{err.get('input')!r}: {msg[0].lower()}{msg[1:]}"
            hint = "write true or false (YAML 1.2: yes/no/on/off are strings)"
        elif etype in _BOUND_ERRORS and model is not None:
            hint = _bound_reason(model, loc)  # the field's description says what it can be and why
        key = (path, msg)
        if key in seen:
            continue
        seen.add(key)
        problems.append(smap.problem(path, msg, hint))
    return dedupe(problems)


_BOUND_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


def _bound_reason(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """``NAME: its description`` of the field at ``loc`` in ``model`` (the bounds' reason), or empty."""
    current: Any = model
    info = None
    for part in loc:
        fields = getattr(current, "model_fields", None)
        if isinstance(part, int) or fields is None:
            continue
        info = fields.get(part)
        if info is None:
            return ""
        current = _inner_model(info.annotation)
    return f"{loc[-1]}: {' '.join(info.description.split())}" if info is not None and info.description else ""


def dedupe(problems: list[Problem]) -> list[Problem]:
    out: list[Problem] = []
    for p in problems:
        if any((q.file, q.line, q.col, q.message, q.via) == (p.file, p.line, p.col, p.message, p.via) for q in out):
            continue
        out.append(p)
    return sorted(out, key=lambda p: (p.line, p.col))


def _allowed_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str]:
    """Field names (aliases) of the model found at ``loc`` inside ``model``."""

    current: Any = model
    for part in loc:
        if isinstance(part, int):
            continue
        fields = getattr(current, "model_fields", None)
        if fields is None:
            return []
        name = {"for": "for_", "in": "in_", "as": "as_"}.get(part, part)
        if name in fields:
            current = _inner_model(fields[name].annotation)
        else:  # dict[str, Model] value
            continue
        if current is None:
            return []
    fields = getattr(current, "model_fields", None)
    if not fields:
        return []
    return [f.alias or n for n, f in fields.items()]


def _inner_model(annotation: Any) -> Any:
    import typing

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        m = _inner_model(arg)
        if m is not None:
            return m
    if isinstance(annotation, str):
        return {"State": State}.get(annotation)
    return None
