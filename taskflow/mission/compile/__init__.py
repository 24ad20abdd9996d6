"""The mission compiler: a validated document in, a :class:`~taskflow.mission.model.CompiledMission` out.

Passes, in order (each a function over one :class:`~taskflow.mission.compile.context.Compilation`; the driver
stops after a pass that found problems, so later passes see a consistent tree):

1. ``components`` — robot, world, their parameters, distributions, rates;
2. ``tree`` — the state tree with inherited tasks and bindings, then the catalogue of metrics and events;
3. ``dataflow`` (catalogue) — the mission-data keys the tasks declare, the ``data:`` defaults;
4. ``bindings`` — profiles, task and action parameters for every ``foreach`` item, loop rules;
5. ``transitions`` — typed transition records, guards, events, clocks;
6. ``structure`` — ``done`` coverage, a way to end, reachability, ways out;
7. ``dataflow`` — every mission-data key a state reads is written on every path into it;
8. ``properties`` — the declared properties (:mod:`taskflow.mission.properties`) checked and compiled.
"""

from __future__ import annotations

from typing import Any

from taskflow.mission.compile.bindings import bind_profiles, check_parameters, profile_kind
from taskflow.mission.compile.components import resolve_components
from taskflow.mission.compile.context import Compilation
from taskflow.mission.compile.dataflow import check_dataflow, data_catalogue
from taskflow.mission.compile.structure import check_structure, finishing_outcomes
from taskflow.mission.compile.transitions import compile_transitions, guard_params
from taskflow.mission.compile.tree import build_tree, catalogue, check_region_metrics, check_region_names
from taskflow.mission.model import CompiledMission
from taskflow.mission.properties import Scope, compile_properties
from taskflow.mission.schema import Mission
from taskflow.mission.yamlsrc import SourceMap

__all__ = ["compile_document", "finishing_outcomes", "profile_kind"]


def compile_document(data: dict[str, Any], spec: Mission, smap: SourceMap) -> CompiledMission:
    c = Compilation(data, spec, smap)
    resolve_components(c)
    c.fail_if_problems()
    assert c.robot_cls is not None and c.world_cls is not None and c.robot_params is not None
    root = build_tree(c)
    check_region_metrics(c, root)
    check_region_names(c, root)
    c.fail_if_problems()
    metric_units, events = catalogue(c, root)
    mission_data = data_catalogue(c, root)
    bind_profiles(c, root)
    check_parameters(c, root)
    compile_transitions(c, root, events)
    c.fail_if_problems()
    check_structure(c, root)
    c.fail_if_problems()
    check_dataflow(c, root)
    c.fail_if_problems()
    quantities, not_quantities = guard_params(c)
    scope = Scope(c.states, events, metric_units, c.mission_data.guard_units(), quantities, not_quantities)
    properties = compile_properties(spec.properties, scope, c.err)
    c.fail_if_problems()
    return CompiledMission(
        file=smap.file, raw=data, spec=spec, root=root, states=c.states, transitions=c.transitions,
        robot_cls=c.robot_cls, robot_params=c.robot_params, world_cls=c.world_cls,
        world_params_raw=c.world_params_raw, metric_units=metric_units, events=events, data=mission_data,
        properties=properties)
