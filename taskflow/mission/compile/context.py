"""What every compile pass works on: the document, its validated shape, the source map, the problems
found so far, and what earlier passes resolved (robot, world, states, transitions)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from taskflow.api import Robot, World
from taskflow.errors import MissionError, Problem
from taskflow.execution.data import DataCatalogue
from taskflow.mission.diagnostics import dedupe, pydantic_problems
from taskflow.mission.model import StateNode, Transition, YPath, with_model_defaults
from taskflow.mission.schema import Machine, Mission, Region, State
from taskflow.mission.yamlsrc import SourceMap


class Compilation:
    """One compile of one mission.  Passes report with :meth:`err` (``FILE:LINE:COL`` from the source map,
    or the ``--set`` that wrote the value) and the driver stops between passes when any were found."""

    def __init__(self, data: dict[str, Any], spec: Mission, smap: SourceMap) -> None:
        self.data, self.spec, self.smap = data, spec, smap
        self.problems: list[Problem] = []
        self.robot_cls: type[Robot] | None = None
        self.robot_params: BaseModel | None = None
        self.world_cls: type[World] | None = None
        self.world_params_raw: dict[str, Any] = {}
        self.states: dict[str, StateNode] = {}
        self.transitions: list[Transition] = []
        self.mission_data = DataCatalogue()  # the mission data its tasks declare (set by dataflow.data_catalogue)

    def err(self, path: YPath, message: str, hint: str = "") -> None:
        self.problems.append(self.smap.problem(path, message, hint))

    def fail_if_problems(self) -> None:
        if self.problems:
            raise MissionError(dedupe(self.problems))

    def validate_model(self, model: type[BaseModel], values: Any, path: YPath) -> BaseModel | None:
        """``values`` validated by ``model`` (partial sub-models completed from their defaults), or None
        with the problems recorded at ``path``."""
        try:
            return model.model_validate(with_model_defaults(model, values))
        except ValidationError as exc:
            self.problems.extend(pydantic_problems(exc, self.smap, path, model))
        except (TypeError, ValueError) as exc:
            self.err(path, str(exc))
        return None

    def spec_of(self, node: StateNode) -> State | Machine | Region:
        """The schema model the state (or parallel region) ``node`` was compiled from."""
        spec: State | Machine | Region = self.spec.machine
        for a in node.ancestors()[1:]:
            spec = spec.regions[a.name] if isinstance(spec, State) and spec.regions else spec.states[a.name]
        return spec

    @property
    def world(self) -> type[World]:
        assert self.world_cls is not None, "resolve_components() runs first"
        return self.world_cls

    @property
    def robot(self) -> type[Robot]:
        assert self.robot_cls is not None, "resolve_components() runs first"
        return self.robot_cls
