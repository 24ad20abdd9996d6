"""The mission JSON Schema completed with what is registered, for editors (``taskflow schema``).

:func:`taskflow.mission.schema.mission_json_schema` checks a mission's shape only (names are strings there: the
schema module does not know the registries).  :func:`completed_json_schema` adds the registered names
as enums — ``TaskName``, ``RobotName``, ``WorldName``, ``ActionName`` in ``$defs`` — and, for
``{name, params}`` forms, the parameters of the named class: ``if name is X then params is X's Params``
(the Params models' own JSON Schemas, under ``$defs`` as ``task.MODEL``, ``robot.MODEL``, ``world.MODEL``,
``action.MODEL``).  Where a mission may write something the Params model itself would not take, the
schema takes it too: a ``$name`` reference anywhere in task and action parameters, a distribution
(``{uniform: [a, b]}`` ...) anywhere in world parameters.  The loader remains the judge (every
problem with its line); this schema is what an editor completes and flags as one types.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable
from typing import Any

from pydantic import BaseModel
from pydantic.json_schema import models_json_schema

from taskflow.catalogue.catalogue import loaded
from taskflow.mission.distributions import KINDS as DISTRIBUTIONS
from taskflow.mission.schema import mission_json_schema
from taskflow.registry import ROBOTS, TASKS, WORLDS

Schema = dict[str, Any]

REFERENCE: Schema = {"type": "string", "pattern": r"^\$[A-Za-z_][A-Za-z0-9_]*$",
                     "description": "a mission parameter or foreach item: $name"}
DISTRIBUTION: Schema = {"type": "object", "minProperties": 1, "maxProperties": 1, "additionalProperties": False,
                        "properties": {k: {"type": "array"} for k in DISTRIBUTIONS},
                        "description": "a value drawn with the run's seed: {uniform: [a, b]}, {normal: [mu, sigma]}, "
                                       "{choice: [...]}, {randint: [a, b]}, {signed_uniform: [a, b]} (±[a, b])"}
_KEEP_OUTSIDE = ("title", "description", "default")


def _also(node: Any, alternatives: list[Schema]) -> Any:
    """``node`` accepting ``alternatives`` wherever a value goes, at its own level and below."""
    inner = _inside(node, alternatives)
    if not alternatives or not isinstance(inner, dict):
        return inner
    outer = {k: inner.pop(k) for k in _KEEP_OUTSIDE if k in inner}
    return {**outer, "anyOf": [inner, *alternatives]}


def _inside(node: Any, alternatives: list[Schema]) -> Any:
    """``node`` with every value position under it (properties, items, map values, union members'
    positions) accepting ``alternatives``."""
    if not isinstance(node, dict):
        return node
    node = dict(node)
    if isinstance(node.get("properties"), dict):
        node["properties"] = {k: _also(v, alternatives) for k, v in node["properties"].items()}
    for key in ("items", "additionalProperties"):
        if isinstance(node.get(key), dict):
            node[key] = _also(node[key], alternatives)
    if isinstance(node.get("prefixItems"), list):
        node["prefixItems"] = [_also(v, alternatives) for v in node["prefixItems"]]
    for key in ("anyOf", "oneOf", "allOf"):
        if isinstance(node.get(key), list):
            node[key] = [_inside(v, alternatives) for v in node[key]]
    return node


def _params_defs(prefix: str, models: Iterable[type[BaseModel]],
                 alternatives: list[Schema]) -> tuple[dict[type, Schema], Schema]:
    """Each model's schema (a ``$ref``) and the ``$defs`` they use, keyed ``PREFIX.NAME``."""
    unique = list(dict.fromkeys(models))
    if not unique:
        return {}, {}
    refs, top = models_json_schema([(m, "validation") for m in unique], ref_template=f"#/$defs/{prefix}.{{model}}")
    defs = {f"{prefix}.{name}": _inside(d, alternatives) for name, d in top.get("$defs", {}).items()}
    return {m: refs[(m, "validation")] for m in unique}, defs


def _named_ref(names: Schema, cases: dict[str, tuple[Schema, bool]], description: str) -> Schema:
    """``{name, params}`` with ``name`` one of ``names`` and ``params`` the named class's (``cases``: name →
    (params schema, whether params are required))."""
    return {
        "type": "object", "description": description, "additionalProperties": False, "required": ["name"],
        "properties": {"name": names, "params": {"type": "object"}},
        "allOf": [{"if": {"properties": {"name": {"const": n}}, "required": ["name"]},
                   "then": {"properties": {"params": schema}, **({"required": ["params"]} if required else {})}}
                  for n, (schema, required) in cases.items()],
    }


def _requires_params(model: type[BaseModel]) -> bool:
    return any(f.is_required() for f in model.model_fields.values())


def _swap_in_union(node: Schema, old: Schema, new: Schema) -> None:
    """Replace the member ``old`` of ``node``'s ``anyOf`` by ``new`` (nothing when it has none)."""
    members = node.get("anyOf")
    if isinstance(members, list):
        node["anyOf"] = [new if m == old else m for m in members]


def completed_json_schema() -> Schema:
    """:func:`~taskflow.mission.schema.mission_json_schema` with the registered names and their parameters."""
    schema = copy.deepcopy(mission_json_schema())
    defs: Schema = schema.setdefault("$defs", {})
    tasks, robots, worlds = loaded(TASKS), loaded(ROBOTS), loaded(WORLDS)
    actions = {a: w.action_params.get(a) for w in worlds.values() for a in w.actions}

    task_refs, task_defs = _params_defs("task", (t.Params for t in tasks.values()), [REFERENCE])
    robot_refs, robot_defs = _params_defs("robot", (r.Params for r in robots.values()), [])
    world_refs, world_defs = _params_defs("world", (w.Params for w in worlds.values()), [DISTRIBUTION])
    action_refs, action_defs = _params_defs("action", (m for m in actions.values() if m is not None), [REFERENCE])
    defs.update({**task_defs, **robot_defs, **world_defs, **action_defs})

    def cases(table: dict[str, Any], refs: dict[type, Schema]) -> dict[str, tuple[Schema, bool]]:
        return {n: (refs[m], _requires_params(m)) for n, m in table.items() if m is not None}

    for kind, table, refs in (("Task", {n: t.Params for n, t in tasks.items()}, task_refs),
                              ("Robot", {n: r.Params for n, r in robots.items()}, robot_refs),
                              ("World", {n: w.Params for n, w in worlds.items()}, world_refs),
                              ("Action", actions, action_refs)):
        defs[f"{kind}Name"] = {"type": "string", "enum": sorted(table),
                               "description": f"a registered {kind.lower()} (taskflow list {kind.lower()}s)"}
        defs[f"{kind}Named"] = _named_ref({"$ref": f"#/$defs/{kind}Name"}, cases(table, refs),
                                          f"a registered {kind.lower()} and its parameters "
                                          f"(taskflow describe NAME)")

    string = {"type": "string"}
    for node in _schemas_in(schema):
        if {"$ref": "#/$defs/TaskRef"} in node.get("anyOf", []):
            _swap_in_union(node, string, {"$ref": "#/$defs/TaskName"})
            _swap_in_union(node, {"$ref": "#/$defs/TaskRef"}, {"$ref": "#/$defs/TaskNamed"})
        if node.get("$ref") == "#/$defs/Action":
            node["$ref"] = "#/$defs/ActionNamed"
    props = schema.get("properties", {})
    for key, kind in (("robot", "Robot"), ("world", "World")):
        if key in props:
            _swap_in_union(props[key], string, {"$ref": f"#/$defs/{kind}Name"})
            _swap_in_union(props[key], {"$ref": "#/$defs/ComponentRef"}, {"$ref": f"#/$defs/{kind}Named"})
    return schema


def _schemas_in(node: Any) -> Iterable[Schema]:
    """Every schema object inside ``node`` (depth first, ``node`` included)."""
    if isinstance(node, dict):
        yield node
        for v in node.values():
            yield from _schemas_in(v)
    elif isinstance(node, list):
        for v in node:
            yield from _schemas_in(v)
