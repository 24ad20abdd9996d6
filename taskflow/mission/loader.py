"""Load a mission file: YAML → pydantic shape check → the compiler → a :class:`CompiledMission`.

Every problem is collected as a :class:`~taskflow.errors.Problem` with file, line and column and
raised together in one :class:`~taskflow.errors.MissionError`.  Nothing here runs the simulator.
The compiled model lives in :mod:`taskflow.mission.model`, the passes in :mod:`taskflow.mission.compile`, the mapping
of pydantic's errors to lines in :mod:`taskflow.mission.diagnostics`; their names are re-exported here for
callers that load missions.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from taskflow.errors import MissionError, Problem
from taskflow.mission.compile import compile_document
from taskflow.mission.diagnostics import pydantic_problems
from taskflow.mission.model import (  # noqa: F401
    CompiledMission,
    DoneTransition,
    EventTransition,
    GuardTransition,
    Loop,
    StateNode,
    TimeoutTransition,
    Transition,
    UnknownRef,
    resolve_refs,
    with_model_defaults,
)
from taskflow.mission.schema import Mission
from taskflow.mission.submission import expand_uses
from taskflow.mission.yamlsrc import MissionLoader, SourceMap, gc_paused, load_yaml_file, load_yaml_text
from taskflow.registry import describe_choices


def load_mission(path: str | Path, overrides: list[str] | None = None) -> CompiledMission:
    with gc_paused():  # from the YAML to the compiled mission: no collection in between either
        data, smap, _ = load_yaml_file(path)
        return compile_mission(data, smap, overrides)


def load_mission_text(text: str, file: str = "<string>", overrides: list[str] | None = None) -> CompiledMission:
    with gc_paused():
        data, smap = load_yaml_text(text, file)
        return compile_mission(data, smap, overrides)


def apply_overrides(data: Any, overrides: list[str], file: str, smap: SourceMap | None = None) -> Any:
    """``--set a.b.0.c=value``: the value is read as YAML by the same safe YAML 1.2 reader as the file
    (``on:`` stays a key, ``1e3`` is a number).

    A key path may create keys that the file does not have (``world.params.speed`` on a world given by
    name), but not a state: a path through ``states:`` (or ``regions:``) must name one that exists, so
    ``machine.states.patroll.x=1`` is refused with "did you mean 'patrol'".  With ``smap``, each
    overridden path — and each key it created — is remembered, so that a problem inside it names the
    ``--set`` that caused it instead of a line of the file.  Every message names the ``--set`` as given."""
    data = copy.deepcopy(data)
    for item in overrides:
        key, sep, text = item.partition("=")

        def refuse(message: str, hint: str = "", item: str = item) -> MissionError:
            return MissionError([Problem(file, 0, 0, f"--set {item}: {message}", hint)])

        if not sep or not key:
            raise MissionError([Problem(file, 0, 0, f"--set {item!r} is not KEY=VALUE", "write e.g. --set world.params.speed=0.05")])
        try:
            value = yaml.load(text, Loader=MissionLoader)
        except yaml.YAMLError as exc:
            raise refuse(f"value is not valid YAML ({getattr(exc, 'problem', None) or exc})") from None
        node = data
        parts = key.split(".")
        ypath: list[Any] = []
        created: list[tuple[Any, ...]] = []
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            if isinstance(node, list):
                try:
                    idx = int(part)
                    ypath.append(idx)
                    if last:
                        node[idx] = value
                    else:
                        node = node[idx]
                    continue
                except (ValueError, IndexError):
                    raise refuse(f"{part!r} is not an index of a list of {len(node)}") from None
            if not isinstance(node, dict):
                raise refuse(f"{'.'.join(parts[:i])} is not a mapping")
            if not last and isinstance(node.get(part), str) and part in ("robot", "world", "task"):
                node[part] = {"name": node[part]}  # `robot: racecar` → `{name: racecar}` so params can be set
            if not last and part not in node and ypath and ypath[-1] in ("states", "regions") and "machine" in ypath[:1]:
                what = "state" if ypath[-1] == "states" else "region"
                raise refuse(f"no {what} {part!r} in {'.'.join(map(str, ypath))}",
                             describe_choices(part, [str(k) for k in node]))
            ypath.append(part)
            if part not in node:
                created.append(tuple(ypath))
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        if smap is not None:
            for made in created[:1]:  # the first key it created holds all the others
                smap.overrides.setdefault(made, item)
            smap.overrides[tuple(ypath)] = item
    return data


def compile_mission(data: Any, smap: SourceMap, overrides: list[str] | None = None,
                    sources: Mapping[Path, str] | None = None) -> CompiledMission:
    """The load path after YAML: ``use:`` expanded (``sources``: resolved path → unsaved text to read instead of
    that sub-mission file), ``--set`` applied, the shape check, the compile passes (the garbage collector held off:
    :func:`~taskflow.mission.yamlsrc.gc_paused`)."""
    with gc_paused():
        return _compile_mission(data, smap, overrides, sources)


def _compile_mission(data: Any, smap: SourceMap, overrides: list[str] | None,
                     sources: Mapping[Path, str] | None) -> CompiledMission:
    file = smap.file
    if isinstance(data, dict):
        data = expand_uses(data, smap, sources)  # `use:` sub-missions spliced in; `--set` applies to the result
    if overrides:
        data = apply_overrides(data, overrides, file, smap)
    if not isinstance(data, dict):
        raise MissionError([smap.problem((), f"a mission is a mapping of keys, got {type(data).__name__}",
                                         "start with `mission: NAME`")])
    try:
        spec = Mission.model_validate(data)
    except ValidationError as exc:
        raise MissionError(pydantic_problems(exc, smap, ())) from None
    return compile_document(data, spec, smap)
