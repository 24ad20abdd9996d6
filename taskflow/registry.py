"""Name → class registries for tasks, robots, worlds and the simulator bodies of robots.

One mechanism for all three.  A class is registered either with the decorators below (importing the
module registers it) or through an entry point in a package's ``pyproject.toml``::

    [project.entry-points."taskflow.tasks"]
    my_law = "my_package.laws:MyLaw"

Entry points are imported lazily, the first time a name is looked up.  Registering a name twice is
refused; looking up an unknown name raises :class:`UnknownName` carrying the valid names and the
closest match.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from importlib import import_module, metadata
from typing import Generic, TypeVar

from .api import Robot, Task, World

T = TypeVar("T", bound=type)


class RegistryError(Exception):
    """A registration problem (duplicate name, broken entry point, wrong base class)."""


class UnknownName(KeyError):
    """Lookup of a name no registry entry has; ``valid`` lists the names that exist."""

    def __init__(self, kind: str, name: str, valid: list[str]) -> None:
        self.kind, self.name, self.valid = kind, name, valid
        super().__init__(name)

    def __str__(self) -> str:
        return f"unknown {self.kind} {self.name!r} — {describe_choices(self.name, self.valid)}"


def describe_choices(name: str, valid: list[str]) -> str:
    """'did you mean X? valid: a, b, c' — the tail of every unknown-name message."""
    close = difflib.get_close_matches(name, valid, n=1, cutoff=0.5)
    listing = ", ".join(sorted(valid)) if valid else "(none)"
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"{hint}valid: {listing}"


_CONTRACT_INSTEAD = {
    "task": "`command_interface`, `requires` (observations) and `robot_params` (the robot parameters it reads)",
    "world": "`needs` (a RobotNeeds: command interfaces, sensor mounts, a body) and `observations`",
}
"""What replaced the robot-name lists, by kind (docs/extending.md)."""


class Registry(Generic[T]):
    """Registered classes of one kind, keyed by the name used in mission files."""

    def __init__(self, kind: str, base: type, group: str) -> None:
        self.kind, self.base, self.group = kind, base, group
        self._items: dict[str, type] = {}
        self._entry_points: dict[str, metadata.EntryPoint] | None = None

    # -- registration --------------------------------------------------------------------------
    def add(self, name: str, cls: type) -> type:
        if not isinstance(cls, type) or not issubclass(cls, self.base):
            raise RegistryError(f"{self.kind} {name!r}: {cls!r} is not a subclass of {self.base.__name__}")
        if not name.isidentifier():
            raise RegistryError(f"{self.kind} name {name!r} must be an identifier")
        if "robots" in vars(cls) and self.kind in _CONTRACT_INSTEAD:
            raise RegistryError(
                f"{self.kind} {name!r} ({cls.__module__}.{cls.__qualname__}) declares `robots`, a list of robot names "
                f"taskflow no longer reads; declare what it needs instead: {_CONTRACT_INSTEAD[self.kind]}")
        existing = self._items.get(name)
        if existing is not None and existing is not cls:
            raise RegistryError(
                f"{self.kind} {name!r} is already registered by {existing.__module__}.{existing.__qualname__}"
            )
        cls.name = name
        self._items[name] = cls
        return cls

    def register(self, name: str) -> Callable[[T], T]:
        def deco(cls: T) -> T:
            self.add(name, cls)
            return cls

        return deco

    def remove(self, name: str) -> None:
        """Forget a registration (tests use it to clean up)."""
        self._items.pop(name, None)

    # -- lookup --------------------------------------------------------------------------------
    def _eps(self) -> dict[str, metadata.EntryPoint]:
        if self._entry_points is None:
            eps = metadata.entry_points(group=self.group)
            self._entry_points = {ep.name: ep for ep in eps}
        return self._entry_points

    def names(self) -> list[str]:
        return sorted(set(self._items) | set(self._eps()))

    def get(self, name: str) -> T:
        cls = self._items.get(name)
        if cls is not None:
            return cls  # type: ignore[return-value]
        ep = self._eps().get(name)
        if ep is None:
            raise UnknownName(self.kind, name, self.names())
        try:
            loaded = ep.load()
        except Exception as exc:  # a broken plugin must not crash validation with a traceback
            raise RegistryError(f"{self.kind} {name!r}: entry point {ep.value!r} failed to load: {exc}") from exc
        if self._items.get(name) is None:
            self.add(name, loaded)
        return self._items[name]  # type: ignore[return-value]

    def __contains__(self, name: str) -> bool:
        return name in self._items or name in self._eps()

    def load_all(self) -> dict[str, T]:
        """Import every entry point (conformance tests iterate over this)."""
        return {n: self.get(n) for n in self.names()}


TASKS: Registry[type[Task]] = Registry("task", Task, "taskflow.tasks")
ROBOTS: Registry[type[Robot]] = Registry("robot", Robot, "taskflow.robots")
WORLDS: Registry[type[World]] = Registry("world", World, "taskflow.worlds")
BODIES: Registry[type] = Registry("body", object, "taskflow.bodies")
"""Robot name → its simulator body class (``sim/``; the base is ``taskflow_sim.core.bodies.GroundBody``).
The framework only asks whether a robot has one (:attr:`taskflow.api.RobotNeeds.body`), never imports it."""

register_task = TASKS.register
register_robot = ROBOTS.register
register_world = WORLDS.register
register_body = BODIES.register


def import_builtin(module: str) -> None:
    """Import a module for its registration side effects."""
    import_module(module)
