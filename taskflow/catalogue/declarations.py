"""Reading a registered class's declarations as catalogue data: its docstring's summary, a parameter model's
fields (:class:`Param`: type as a mission writes it, default as JSON, unit, bounds) and the models nested in it
(:class:`Model`).

A parameter's unit is read from its declaration, first found: ``Field(json_schema_extra={"unit": "m"})``;
the field's description (``"(m)"``, ``"(m/s), paper: 1.0"``, a leading ``"s without ..."``, a trailing
``"... m, m, rad"``); its model's docstring (``"``max_age`` (s)"``); its name's suffix (``_px``, ``_s``,
``_hz``, ``_m``, ``_rad``).  No unit found is shown as nothing, never guessed further.
"""

from __future__ import annotations

import collections.abc
import inspect
import json
import math
import re
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal, Union

import annotated_types
import numpy as np
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import to_jsonable_python

from taskflow.units import UNITS, suffix_unit


@dataclass(frozen=True)
class Param:
    """One field of a parameter, profile or robot-parameter model: ``type`` as a mission writes it
    (``float``, ``[float, float]``, ``"front" | "rear"``, a model's name), ``default`` as JSON (None with
    ``required``), ``unit`` (empty: none declared), ``bounds`` (``"> 0, ≤ 100"``)."""

    name: str
    type: str
    required: bool
    default: Any = None
    unit: str = ""
    bounds: str = ""
    description: str = ""


@dataclass(frozen=True)
class Model:
    """A pydantic model (or message class) a parameter's type names: its name, summary and fields."""

    name: str
    summary: str
    fields: tuple[Param, ...] = ()



# -- reading declarations -----------------------------------------------------------------------------
def own_doc(obj: object) -> str:
    """The object's own docstring, dedented ('' when it only inherits one)."""
    doc = vars(obj).get("__doc__") if isinstance(obj, type) else getattr(obj, "__doc__", None)
    return inspect.cleandoc(doc) if isinstance(doc, str) else ""


def class_doc(cls: type) -> str:
    """A registered class's docstring, followed by its module's when it refers the reader there."""
    doc = own_doc(cls)
    if "module docstring" in doc:
        module = inspect.getmodule(cls)
        if module is not None and module.__doc__:
            doc += "\n\n" + inspect.cleandoc(module.__doc__)
    return doc


def summary_of(doc: str) -> str:
    """The first sentence of a docstring's first paragraph, on one line."""
    para = " ".join(doc.split("\n\n", 1)[0].split())
    m = re.search(r"(?<![.\w]\w)(?<!e\.g)(?<!i\.e)(?<!eq)(?<!eqs)\.(\s|$)", para)
    return para[: m.start() + 1] if m else para


_EXTRA_UNITS = ("m/s²", "rad/s²", "N·m", "N/m", "N·s/m", "kg", "1/s", "m²")
_UNIT_WORDS = {u for u in UNITS if u} | set(_EXTRA_UNITS)
_UNIT = "|".join(re.escape(u) for u in sorted(_UNIT_WORDS, key=len, reverse=True))
_UNIT_LIST = rf"(?:{_UNIT})(?:,\s*(?:{_UNIT}))*"
_PAREN_UNIT = re.compile(rf"\(({_UNIT_LIST})(?:[);,]|\s*$)")
_LEADING_UNIT = re.compile(rf"^({_UNIT})(?=[\s:,])")
_TRAILING_UNIT = re.compile(rf"\)\s+({_UNIT_LIST})\s*$")


def param_unit(name: str, info: FieldInfo, model_doc: str = "") -> str:
    """The unit field ``name`` declares: explicitly, in its description, in its model's docstring
    ``model_doc`` or by its name's suffix (in that order; '' when none does)."""
    extra = info.json_schema_extra
    if isinstance(extra, dict) and isinstance(extra.get("unit"), str):
        return str(extra["unit"])
    text = info.description or ""
    for pattern in (_PAREN_UNIT, _LEADING_UNIT, _TRAILING_UNIT):
        m = pattern.search(text)
        if m:
            return m.group(1)
    m = re.search(rf"``{re.escape(name)}``\s*\(({_UNIT_LIST})[);,]", model_doc)
    if m:
        return m.group(1)
    return suffix_unit(name) or ""


def type_label(t: Any) -> str:
    """A field's type as a mission author reads it."""
    origin, args = typing.get_origin(t), typing.get_args(t)
    if t is type(None):
        return "null"
    if origin is typing.Annotated:
        return type_label(args[0])
    if origin is Literal:
        return " | ".join(json.dumps(a) for a in args)
    if origin in (Union, types.UnionType):
        return " | ".join(type_label(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"[{type_label(args[0])}, ...]"
        return "[" + ", ".join(type_label(a) for a in args) + "]"
    if origin in (list, typing.Sequence, set, frozenset):
        return f"list[{type_label(args[0])}]" if args else "list"
    if origin in (dict, typing.Mapping):
        return f"map[{type_label(args[0])}, {type_label(args[1])}]" if args else "map"
    if origin is np.ndarray:
        dtype = typing.get_args(args[1]) if len(args) == 2 else ()
        return f"array[{dtype[0].__name__}]" if dtype and isinstance(dtype[0], type) else "array"
    if origin is collections.abc.Callable:
        return f"({', '.join(type_label(a) for a in args[0])}) -> {type_label(args[1])}" if args else "callable"
    if t is typing.Any:
        return "any"
    if isinstance(t, type):
        return t.__name__
    return str(t).replace("typing.", "")


def _models_in(t: Any) -> list[type[BaseModel]]:
    """Pydantic models a type names (inside unions, lists, tuples, Annotated)."""
    if isinstance(t, type) and issubclass(t, BaseModel):
        return [t]
    return [m for a in typing.get_args(t) for m in _models_in(a)]


_BOUNDS = ((annotated_types.Gt, "gt", ">"), (annotated_types.Ge, "ge", "≥"), (annotated_types.Lt, "lt", "<"),
           (annotated_types.Le, "le", "≤"), (annotated_types.MinLen, "min_length", "length ≥"),
           (annotated_types.MaxLen, "max_length", "length ≤"))


def _bounds(info: FieldInfo) -> str:
    out = []
    for meta in info.metadata:
        for cls, attr, sym in _BOUNDS:
            if isinstance(meta, cls):
                out.append(f"{sym} {getattr(meta, attr):g}")
    return ", ".join(out)


def _default(info: FieldInfo) -> Any:
    """The field's default as strict JSON (non-finite numbers as the strings ``"inf"``, ``"-inf"``, ``"nan"``)."""
    return strict_json(to_jsonable_python(info.get_default(call_default_factory=True), fallback=repr))


def strict_json(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, list):
        return [strict_json(x) for x in v]
    if isinstance(v, dict):
        return {k: strict_json(x) for k, x in v.items()}
    return v


def params_of(model: type[BaseModel] | None) -> tuple[Param, ...]:
    """Every field of ``model`` (by its YAML key: the alias when it has one)."""
    if model is None:
        return ()
    doc = own_doc(model)
    out = []
    for name, info in model.model_fields.items():
        required = info.is_required()
        out.append(Param(name=info.alias or name, type=type_label(info.annotation), required=required,
                         default=None if required else _default(info), unit=param_unit(name, info, doc),
                         bounds=_bounds(info), description=" ".join((info.description or "").split())))
    return tuple(out)


def nested_models(roots: Iterable[type[BaseModel] | None]) -> tuple[Model, ...]:
    """The models the fields of ``roots`` name, recursively, each once, in order of first mention."""
    seen: dict[type[BaseModel], None] = {}
    todo = [r for r in roots if r is not None]
    top = set(todo)
    while todo:
        model = todo.pop(0)
        for info in model.model_fields.values():
            for m in _models_in(info.annotation):
                if m not in seen and m not in top:
                    seen[m] = None
                    todo.append(m)
    return tuple(Model(m.__name__, summary_of(own_doc(m)), params_of(m)) for m in seen)


def slot_required(model: type[BaseModel]) -> bool:
    return any(info.is_required() for info in model.model_fields.values())


def source_of(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


