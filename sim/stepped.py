"""The plumbing every stepped world repeats: the simulation clock, the physics-step accumulator and the
command check against the robot's declared ``command_keys``.

:class:`SteppedWorld` owns ``advance(dt)``: it takes whole physics steps (a fractional remainder carries
to the next call, so ticks of a control rate that divides the physics rate all last the same) and calls
the world's :meth:`SteppedWorld.physics_step` for each.  Time is a count of physics steps, never the
wall clock.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from taskflow.api import Command, Robot, World


def check_command(robot: Robot, command: Command) -> dict[str, NDArray[np.float64]]:
    """``command`` as flat float arrays, after checking its keys and lengths against the robot's
    ``command_keys`` (``ValueError`` naming what was expected otherwise)."""
    keys = robot.command_keys
    if set(command) != set(keys):
        raise ValueError(f"{robot.name} command needs keys {sorted(keys)}, got {sorted(command)}")
    out = {k: np.asarray(command[k], dtype=np.float64).reshape(-1) for k in keys}
    bad = {k: a.shape for k, a in out.items() if a.shape != (keys[k],)}
    if bad:
        want = ", ".join(f"{k}({n})" for k, n in keys.items())
        raise ValueError(f"{robot.name} command arrays must have lengths {want}, got {bad}")
    return out


class SteppedWorld(World):
    """A world advanced in whole physics steps of ``1 / physics_hz`` (a ``physics_hz`` parameter, or
    the class's).  Subclasses implement :meth:`physics_step` and call :meth:`restart_clock` in ``reset``."""

    def __init__(self, robot: Robot, params: BaseModel, seed: int, gui: bool = False) -> None:
        super().__init__(robot, params, seed, gui)
        self.physics_hz = float(getattr(params, "physics_hz", type(self).physics_hz))
        self._steps = 0
        self._carry = 0.0

    def restart_clock(self) -> None:
        self._steps = 0
        self._carry = 0.0

    @property
    def t(self) -> float:
        """Simulation time (s): physics steps taken since :meth:`reset` over ``physics_hz``."""
        return self._steps / self.physics_hz

    def physics_step(self, h: float) -> None:  # pragma: no cover - interface
        """One physics step of ``h`` seconds."""
        raise NotImplementedError

    def advance(self, dt: float) -> None:
        """Step ``dt * physics_hz`` whole physics steps (a fractional remainder carries to the next call)."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"advance(dt) needs a finite dt >= 0, got {dt!r}")
        self._before_steps()
        self._carry += dt * self.physics_hz
        n = round(self._carry)
        self._carry -= n
        h = 1.0 / self.physics_hz
        for _ in range(n):
            self.physics_step(h)
        self._steps += n

    def _before_steps(self) -> None:
        """Hook run before stepping (e.g. a check that the scene exists); default: nothing."""
