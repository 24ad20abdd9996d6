"""The plumbing every stepped world shares: the simulation clock, the physics-step accumulator, sensor
schedules at declared rates and the command check against the robot's declared ``command_keys``.

:class:`SteppedWorld` owns ``advance(dt)``: it takes whole physics steps (a fractional remainder carries
to the next call, so ticks of a control rate that divides the physics rate all last the same) and calls
the world's :meth:`SteppedWorld.physics_step` for each, then :meth:`SteppedWorld.after_physics_step` at
the new time (where a world polls sensors scheduled per physics step).  Time is a count of physics
steps, never the wall clock.  A world keeps its scoring (ground truth, summary metrics) apart from this.

:class:`SensorSchedule` says when a sensor of rate ``r`` fires: on the first tick at or after each
``t0 + k / r``.  Fault intervals (dropouts, occlusions, blackouts) are :mod:`taskflow_sim.core.faults`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Any, Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, Field

from taskflow.api import Command, Robot, World

if TYPE_CHECKING:
    from taskflow_sim.core.sensors import SensorStream

EPS_T = 1e-9
"""Slack (s) when comparing a tick's time (steps / physics_hz) with a time computed another way (k / rate)."""

PhysicsHz = Annotated[float, Field(ge=100.0, le=10_000.0)]
"""The type of a world's ``physics_hz`` parameter (Hz): 100 Hz to 10 kHz, the bounds every PyBullet world
shares (contact needs at least 100 Hz); each world gives its own default and description."""


def check_command(robot: Robot, command: Command) -> dict[str, NDArray[np.float64]]:
    """``command`` as flat float arrays, after checking its keys and lengths against the robot's
    ``command_keys`` and that every value is finite (``ValueError`` naming what was expected otherwise)."""
    keys = robot.command_keys
    if set(command) != set(keys):
        raise ValueError(f"{robot.name} command needs keys {sorted(keys)}, got {sorted(command)}")
    out = {k: np.asarray(command[k], dtype=np.float64).reshape(-1) for k in keys}
    bad = {k: a.shape for k, a in out.items() if a.shape != (keys[k],)}
    if bad:
        want = ", ".join(f"{k}({n})" for k, n in keys.items())
        raise ValueError(f"{robot.name} command arrays must have lengths {want}, got {bad}")
    nonfinite = sorted(k for k, a in out.items() if not np.all(np.isfinite(a)))
    if nonfinite:
        raise ValueError(f"{robot.name} command values must be finite, got {({k: out[k] for k in nonfinite})}")
    return out


class SensorSchedule:
    """When a sensor of ``rate_hz`` fires: at the first tick whose time reaches ``t0 + k / rate_hz``
    (k = 0, 1, …; within :data:`EPS_T`).  A tick that passes several grid times fires once and the next
    firing is the next grid time after it, so a 15 Hz camera polled by a 20 Hz loop fires 3 ticks in 4,
    always the same ones.  Deterministic: a function of the tick times only.  :meth:`restart` begins a
    new stream (a camera switched on) at ``t0``, optionally at another rate."""

    def __init__(self, rate_hz: float, t0: float = 0.0) -> None:
        self.restart(t0, rate_hz)

    def restart(self, t0: float, rate_hz: float | None = None) -> None:
        if rate_hz is not None:
            if not (math.isfinite(rate_hz) and rate_hz > 0.0):
                raise ValueError(f"a sensor rate must be finite and > 0 Hz, got {rate_hz!r}")
            self.rate_hz = float(rate_hz)
        self.t0 = t0
        self.k = 0  # grid index of the next firing
        self.next_t = t0
        self.fired = 0

    def due(self, t: float) -> bool:
        """Whether a tick at ``t`` reaches the next grid time."""
        return t + EPS_T >= self.next_t

    def fire(self, t: float) -> None:
        """Record a firing at ``t``: the next one is at the first grid time after ``t``."""
        self.k = max(self.k + 1, math.floor((t - self.t0) * self.rate_hz + 1e-6) + 1)
        self.next_t = self.t0 + self.k / self.rate_hz
        self.fired += 1

    def poll(self, t: float) -> bool:
        """``due(t)``, and if so :meth:`fire` at ``t``."""
        if not self.due(t):
            return False
        self.fire(t)
        return True


class Scene(Protocol):
    """What a stepped world builds in ``reset``: a simulator client and its bodies, closed by ``close``."""

    def close(self) -> None: ...


SceneT = TypeVar("SceneT", bound=Scene)


class SteppedWorld(World, Generic[SceneT]):
    """A world advanced in whole physics steps of ``1 / physics_hz`` (a ``physics_hz`` parameter, or
    the class's).  Subclasses implement :meth:`physics_step` and call :meth:`restart_clock` in ``reset``;
    the hooks :meth:`begin_steps`, :meth:`after_physics_step` and :meth:`end_steps` frame the steps
    of one ``advance``.  A world that keeps its simulator in ``self.sim`` (built by ``reset``; ``scene`` is the class's figure
    markers, :meth:`taskflow.api.World.scene`) gets
    :meth:`close` and :meth:`_require_sim`."""

    sim: SceneT | None
    """The simulator client and its bodies, built by ``reset`` (None before it and after :meth:`close`)."""

    def __init__(self, robot: Robot, params: BaseModel, seed: int, gui: bool = False) -> None:
        super().__init__(robot, params, seed, gui)
        self.physics_hz = float(getattr(params, "physics_hz", type(self).physics_hz))
        self.sim = None
        self._steps = 0
        self.substep = 0
        self._carry = 0.0
        self.streams: dict[str, SensorStream[Any]] = {}

    def add_stream(self, name: str, stream: SensorStream[Any]) -> SensorStream[Any]:
        """Declare ``stream`` under ``name`` (replacing one of that name); returns it."""
        self.streams[name] = stream
        return stream

    def start_streams(self) -> None:
        """Restart every stream at :attr:`t` (call at the end of ``reset``, once the scene exists); a
        stream polled per ``advance`` takes its first poll now (a reading at the reset time)."""
        t = self.t
        for s in self.streams.values():
            s.restart(t)
            if s.poll_point == "advance":
                s.poll(t)

    def close(self) -> None:
        if self.sim is not None:
            self.sim.close()
            self.sim = None

    def _require_sim(self) -> SceneT:
        if self.sim is None:
            raise RuntimeError(f"{self.name or type(self).__name__}: call reset() before using the world")
        return self.sim

    def restart_clock(self) -> None:
        self._steps = 0
        self.substep = 0
        self._carry = 0.0

    @property
    def t(self) -> float:
        """Simulation time (s): physics steps taken since :meth:`reset` over ``physics_hz``.  The steps of
        an ``advance`` count once it returns; inside it (in :meth:`after_physics_step`) the steps taken
        so far count too, so an ``advance`` cut short (Ctrl-C) leaves the clock where it was."""
        return (self._steps + self.substep) / self.physics_hz

    def physics_step(self, h: float) -> None:  # pragma: no cover - interface
        """One physics step of ``h`` seconds."""
        raise NotImplementedError

    def advance(self, dt: float) -> None:
        """Step ``dt * physics_hz`` whole physics steps (a fractional remainder carries to the next call)."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"advance(dt) needs a finite dt >= 0, got {dt!r}")
        self._before_steps()
        streams = self.streams.values()
        for s in streams:
            s.begin_advance()
        per_step = [s for s in streams if s.poll_point == "physics_step"]
        self._carry += dt * self.physics_hz
        n = round(self._carry)
        self._carry -= n
        h = 1.0 / self.physics_hz
        self.begin_steps(n, h)
        try:
            for _ in range(n):  # substep: index of the step being taken (after it: the steps taken)
                self.physics_step(h)
                self.substep += 1
                if per_step:
                    t = self.t
                    for s in per_step:
                        s.poll(t)
                self.after_physics_step(h)
        finally:
            self.substep = 0
        self._steps += n
        self.end_steps(n, h)
        if streams:
            t = self.t
            for s in streams:
                if s.poll_point == "advance":
                    s.poll(t)

    def _before_steps(self) -> None:
        """Hook run before the step count is taken (e.g. a check that the scene exists); default: nothing."""

    def begin_steps(self, n: int, h: float) -> None:
        """Hook run once ``n`` (possibly 0) steps of ``h`` are decided, before the first; default: nothing."""

    def after_physics_step(self, h: float) -> None:
        """Hook run after each physics step, with :attr:`t` already at the step's end; default: nothing."""

    def end_steps(self, n: int, h: float) -> None:
        """Hook run after the ``n`` steps of one ``advance`` (also when n = 0); default: nothing."""
