"""Mission data: the keys a mission's tasks declare, the run's values, each task's checked
view of them, and the values' JSON form (the summary's ``outputs``, ``$data`` parameters).

On the model of py_trees' blackboard clients: a task declares the :class:`~taskflow.api.MemoryKey` it
writes (:attr:`Task.writes`, which also lets it read them) and those it needs written before its state is
entered (:attr:`Task.reads`); the executor hands it a :class:`DataAccess` over the run's one value dict
that refuses every other key, and checks every value written against the key's declared type.  The
loader (:mod:`taskflow.mission.compile.dataflow`) builds the :class:`DataCatalogue` and checks, over the
machine's transition graph, that every read key is written on every path or has a default.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Iterator, MutableMapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from taskflow.api import FLAG, MemoryKey, Metric, Task
from taskflow.mission.guards import (
    DATA_PREFIX,  # what a guard writes before a key's name (data.viki.object[0]); $data. in a parameter
)
from taskflow.specs import ObsSpec


class DataAccessError(RuntimeError):
    """A task used a mission-data key it does not declare, or wrote a value of the wrong type."""


class DataAccess(MutableMapping[str, Any]):
    """One task's view of the run's mission data: it reads the keys it declares (``reads`` and ``writes``)
    and writes those of ``writes``, each value checked against the key's spec; anything else raises
    :class:`DataAccessError` naming the task and the key.  The values live in the run's one dict
    (``values``, kept as ``_store``: the name ``values`` is the mapping's method), shared by every task's
    view."""

    __slots__ = ("_store", "owner", "_readable", "_writable")

    def __init__(self, values: dict[str, Any], task: type[Task[Any, Any]]) -> None:
        self._store = values
        self.owner = task.name or task.__name__
        self._writable: dict[str, MemoryKey[Any]] = {k.name: k for k in task.writes}
        self._readable: frozenset[str] = frozenset(k.name for k in (*task.reads, *task.writes))

    def _refuse(self, verb: str, name: str) -> DataAccessError:
        declared = ", ".join(sorted(self._writable if verb == "writes" else self._readable)) or "none"
        where = "writes" if verb == "writes" else "reads or writes"
        return DataAccessError(f"task {self.owner!r} {verb} mission data {name!r}, which it does not declare — "
                               f"add its MemoryKey to the task's `{where}` (it declares: {declared})")

    def __getitem__(self, name: str) -> Any:
        if name not in self._readable:
            raise self._refuse("reads", name)
        return self._store[name]

    def get(self, name: str, default: Any = None) -> Any:
        if name not in self._readable:
            raise self._refuse("reads", name)
        return self._store.get(name, default)

    def __contains__(self, name: object) -> bool:
        if name not in self._readable:
            raise self._refuse("reads", str(name))
        return name in self._store

    def __setitem__(self, name: str, value: Any) -> None:
        key = self._writable.get(name)
        if key is None:
            raise self._refuse("writes", name)
        problem = key.spec.problem(value)
        if problem is not None:
            raise DataAccessError(f"task {self.owner!r} writes mission data {name!r} a value that {problem} "
                                  f"— the key holds {key.spec}")
        self._store[name] = value

    def setdefault(self, name: str, default: Any = None) -> Any:
        if name in self._store and name in self._writable:
            return self._store[name]
        self[name] = default
        return default

    def __delitem__(self, name: str) -> None:
        if name not in self._writable:
            raise self._refuse("writes", name)
        del self._store[name]

    def __iter__(self) -> Iterator[str]:
        return (k for k in self._store if k in self._readable)

    def __len__(self) -> int:
        return sum(k in self._readable for k in self._store)


def clean_floats(data: Any) -> Any:
    """NaN/inf → None, numpy → Python, recursively (summary.json must be strict JSON)."""
    if isinstance(data, dict):
        return {str(k): clean_floats(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [clean_floats(v) for v in data]
    if isinstance(data, np.ndarray):
        return clean_floats(data.tolist())
    if isinstance(data, np.generic):
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def json_value(value: Any) -> Any:
    """``value`` as strict JSON: arrays and tuples as lists, dataclasses as dicts of their fields, numpy
    scalars as Python numbers, NaN/inf as None."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = {f.name: json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    elif isinstance(value, dict):
        value = {k: json_value(v) for k, v in value.items()}
    elif isinstance(value, (list, tuple)):
        value = [json_value(v) for v in value]
    return clean_floats(value)


def from_yaml(spec: ObsSpec, value: Any) -> Any:
    """A value written in a mission (``data:``) as a key of ``spec`` holds it; raises ValueError saying
    what the key takes."""
    bad = _not_finite_or_bool(value) if spec.kind in ("array", "scalar") else not_finite(value)
    if bad is not None:
        raise ValueError(f"holds {bad!r}: a value of the mission's data must be a finite number"
                         f"{' (not true/false)' if isinstance(bad, bool) else ''}; it takes {spec}")
    if spec.kind == "array":
        try:
            out: Any = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"takes {spec}: a list of numbers") from None
    elif spec.kind == "scalar" and isinstance(value, (int, float)) and not isinstance(value, bool):
        out = float(value)
    elif spec.kind == "message":
        raise ValueError(f"holds {spec.cls.__name__ if spec.cls else 'an object'} objects, which only a task can write")
    else:
        out = value
    problem = spec.problem(out)
    if problem is not None:
        raise ValueError(f"{problem}; it takes {spec}")
    return out


def _numbers(value: Any) -> Iterator[Any]:
    """Every scalar inside ``value`` (lists, tuples and mapping values, walked without recursion)."""
    todo = [value]
    while todo:
        v = todo.pop()
        if isinstance(v, dict):
            todo.extend(reversed(list(v.values())))
        elif isinstance(v, (list, tuple)):
            todo.extend(reversed(v))
        else:
            yield v


def not_finite(value: Any) -> Any:
    """The first NaN or infinite number inside ``value`` (None: there is none)."""
    return next((v for v in _numbers(value) if isinstance(v, float) and not math.isfinite(v)), None)


def _not_finite_or_bool(value: Any) -> Any:
    """As :func:`not_finite`, and a boolean where a number belongs (``[true, false]`` is no array)."""
    return next((v for v in _numbers(value) if isinstance(v, bool) or (isinstance(v, float) and not math.isfinite(v))),
                None)


def guard_names(key: MemoryKey[Any]) -> list[str]:
    """The names a guard may compare for ``key``: ``data.<name>`` for a scalar or flag, ``data.<name>[i]``
    for each component of a 1-D array of fixed length; none for other kinds."""
    spec, name = key.spec, DATA_PREFIX + key.name
    if spec.kind in ("scalar", "flag"):
        return [name]
    if spec.kind == "array" and len(spec.shape) == 1 and spec.shape[0] is not None:
        return [f"{name}[{i}]" for i in range(spec.shape[0])]
    return []


def sample(spec: ObsSpec) -> Any:
    """A stand-in value of ``spec`` in JSON form, to validate a ``$data`` parameter at load."""
    if spec.kind == "array":
        return np.zeros([n if n is not None else 1 for n in spec.shape]).tolist()
    return {"scalar": 0.0, "flag": False, "text": "", "mapping": {}, "sequence": []}.get(spec.kind)


@dataclass
class DataCatalogue:
    """The mission data of one mission: every key its tasks declare (name → key) and the value each key
    holds from the start of a run (the key's own default, or the mission's ``data:`` entry over it)."""

    keys: dict[str, MemoryKey[Any]] = field(default_factory=dict)
    defaults: dict[str, Any] = field(default_factory=dict)

    def initial_values(self) -> dict[str, Any]:
        """A new run's value dict: the defaults, copied (a run never changes another's)."""
        return {k: copy.deepcopy(v) for k, v in self.defaults.items()}

    def guard_units(self) -> dict[str, str]:
        """Every ``data.…`` name a guard may read → the unit of its key (a flag key's is
        :data:`taskflow.api.FLAG`: a guard reads it as 1 or 0, so ``data.KEY > 1`` can never hold)."""
        return {n: FLAG if key.spec.kind == "flag" and not isinstance(key.unit, Metric) else key.unit
                for key in self.keys.values() for n in guard_names(key)}

    def samples(self) -> dict[str, Any]:
        """Key name → a value of its type in JSON form (its default when it has one), for load-time checks
        of ``$data`` parameters; keys holding objects (``instance``) are left out: no parameter takes one."""
        return {name: json_value(self.defaults[name]) if name in self.defaults else sample(key.spec)
                for name, key in self.keys.items() if key.spec.kind != "message"}  # objects are no parameters

    def outputs(self, values: dict[str, Any]) -> dict[str, Any]:
        """The final values of the output keys that hold one, in JSON form, by name."""
        return {name: json_value(values[name]) for name in sorted(values)
                if name in self.keys and self.keys[name].output}
