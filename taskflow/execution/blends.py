"""Command blending after a transition with ``blend: T``: the last outgoing command fades into the incoming one
with the papers' activation ``h(τ) = ½(1 − cos(π τ / T))`` for ``τ < T`` (quadcopter paper eq. 20).

Inside a parallel region a blend covers only the command parts that region ``owns``, and runs alongside a
sibling region's blend; a transition outside any region blends every part and replaces every blend in progress.
"""

from __future__ import annotations

from dataclasses import dataclass

from taskflow.api import Command
from taskflow.mission.model import StateNode
from taskflow.shaping import activation

__all__ = ["Blend", "Blends", "blend_weight"]

blend_weight = activation
"""The papers' activation ``h(t)`` (quadcopter paper eq. 20), used by ``blend:``."""


@dataclass
class Blend:
    """One blend in progress: ``old`` (the command when its transition fired) fades into the new one."""

    t0: float  # sim time the transition fired
    duration: float  # seconds (the transition's ``blend:``)
    old: Command
    parts: tuple[str, ...] | None = None  # the command parts blended (None: all)


class Blends:
    """The blends in progress, by the region whose transition started them (None: a transition outside any
    region).  The tick reads :attr:`active` to skip the work when there is none."""

    def __init__(self) -> None:
        self.active: dict[str | None, Blend] = {}

    def start(self, t: float, duration: float, last: Command, region: StateNode | None) -> None:
        """A transition with ``blend:`` fired at sim time ``t`` in ``region`` (None: outside any): fade ``last``,
        the command it leaves, into the new one over ``duration``.  It replaces the blends it covers — every one
        for a transition outside any region (it starts from the command they shaped), its own region's and those
        nested in it otherwise — and leaves a sibling region's blend running on the parts that region owns."""
        if region is None:
            self.active.clear()
        else:
            inner = region.path + "."
            for key in [k for k in self.active if k is not None and (k == region.path or k.startswith(inner))]:
                del self.active[key]
        self.active[None if region is None else region.path] = Blend(
            t, duration, last, region.owns if region is not None else None)

    def apply(self, command: Command, t: float) -> Command:
        """``command`` with every blend in progress applied (in the order they started); a finished one is dropped."""
        for key, b in list(self.active.items()):
            h = blend_weight(t - b.t0, b.duration)
            if h >= 1.0:
                del self.active[key]
                continue
            command = {k: h * v + (1.0 - h) * b.old[k] if k in b.old and (b.parts is None or k in b.parts) else v
                       for k, v in command.items()}
        return command

    def clear(self) -> None:
        self.active.clear()
