"""Six-axis PID with anti-windup — the control law of the screw-fastening paper, eqs. (15)–(18), (33), (36).

``V = K_p L + K_i ∫ L dt + K_d dL/dt`` with diagonal gain matrices, one gain per twist axis in the
paper's order ``[ωx, ωy, ωz, vx, vy, vz]`` (a twist is ``[ω; v]``, section 4).  The paper switches
gain sets per state (``K_b ∈ {boost, operate}``, ``K_a ∈ {boost, operate, zero}``); the *state* of
the controller (integral, last error, filtered derivative) survives a switch, so a platform that
tracks a moving part keeps the integral that carries it when the state machine changes gains.

Anti-windup (beyond the paper, which does not say how its PID is bounded):

* **clamping** — each axis' integral is kept within ``±i_limit``;
* **conditional integration** — when an axis' output saturates at ``±u_max`` and the error would
  push it further out, that axis does not integrate this tick.

The derivative acts on the error through a first-order filter with time constant ``d_tau`` and is
skipped on the first tick after a reset or a set-point jump (:meth:`PidState.reset_derivative`), so a
state change does not kick the output.

Everything here is pure: :func:`pid_step` takes arrays and a :class:`PidState` and returns the
output and a new state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationInfo, field_validator
from taskflow_tasks.core.gains import axis_gains

from taskflow.api import StrictModel

AXES = ("wx", "wy", "wz", "vx", "vy", "vz")
N_AXES = 6


class PidProfile(StrictModel):
    """One PID gain set (eq. 15/16): diagonal ``kp``, ``ki`` (1/s), ``kd`` (s) per axis
    ``[ωx, ωy, ωz, vx, vy, vz]``; ``u_max`` output limit per axis (rad/s, m/s), ``i_limit`` bound on
    each integral (rad·s, m·s), ``d_tau`` derivative filter time constant (s).

    Profiles of this model live under ``profiles.pid``: the ``platform`` and ``arm`` slots both take
    them (``kind = "pid"``).
    """

    kind: ClassVar[str] = "pid"

    kp: tuple[float, ...]
    ki: tuple[float, ...] = (0.0,) * N_AXES
    kd: tuple[float, ...] = (0.0,) * N_AXES
    u_max: tuple[float, ...] = (math.inf,) * N_AXES
    i_limit: tuple[float, ...] = (math.inf,) * N_AXES
    d_tau: float = 0.02

    @field_validator("kp", "ki", "kd", mode="before")
    @classmethod
    def _gains(cls, v: object, info: ValidationInfo) -> tuple[float, ...]:
        return axis_gains(str(info.field_name), v, AXES)

    @field_validator("u_max", mode="before")
    @classmethod
    def _umax(cls, v: object) -> tuple[float, ...]:
        return axis_gains("u_max", v, AXES, positive=True, allow_inf=True)

    @field_validator("i_limit", mode="before")
    @classmethod
    def _ilim(cls, v: object) -> tuple[float, ...]:
        return axis_gains("i_limit", v, AXES, allow_inf=True)

    @field_validator("d_tau")
    @classmethod
    def _dtau(cls, v: float) -> float:
        if not (math.isfinite(v) and v >= 0.0):
            raise ValueError(f"d_tau must be a finite time >= 0 s, got {v}")
        return v

    def arrays(self) -> PidGains:
        """The gains as numpy arrays (built once per state entry, not per tick)."""
        return PidGains(np.array(self.kp), np.array(self.ki), np.array(self.kd), np.array(self.u_max),
                        np.array(self.i_limit), float(self.d_tau))


@dataclass(frozen=True)
class PidGains:
    """:class:`PidProfile` as arrays."""

    kp: NDArray[np.float64]
    ki: NDArray[np.float64]
    kd: NDArray[np.float64]
    u_max: NDArray[np.float64]
    i_limit: NDArray[np.float64]
    d_tau: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "has_i", bool(np.any(self.ki)))
        object.__setattr__(self, "has_d", bool(np.any(self.kd)))
        object.__setattr__(self, "neg_i_limit", -self.i_limit)
        object.__setattr__(self, "neg_u_max", -self.u_max)

    @staticmethod
    def of(kp: float | list[float], ki: float | list[float] = 0.0, kd: float | list[float] = 0.0,
           u_max: float | list[float] = math.inf, i_limit: float | list[float] = math.inf,
           d_tau: float = 0.0) -> PidGains:
        """Convenience for tests and scripts: scalars broadcast to all six axes."""
        def f(v: float | list[float]) -> NDArray[np.float64]:
            return np.broadcast_to(np.asarray(v, dtype=np.float64), (N_AXES,)).copy()

        return PidGains(f(kp), f(ki), f(kd), f(u_max), f(i_limit), float(d_tau))


@dataclass
class PidState:
    """Integral, last error and filtered derivative of one six-axis PID."""

    integral: NDArray[np.float64] = field(default_factory=lambda: np.zeros(N_AXES))
    last_error: NDArray[np.float64] | None = None
    derivative: NDArray[np.float64] = field(default_factory=lambda: np.zeros(N_AXES))

    def reset_derivative(self) -> None:
        """Forget the last error: the next step has no derivative term (set-point changed)."""
        self.last_error = None
        self.derivative = np.zeros(N_AXES)

    def copy(self) -> PidState:
        return PidState(self.integral.copy(), None if self.last_error is None else self.last_error.copy(),
                        self.derivative.copy())


def pid_step(error: NDArray[np.float64], state: PidState, gains: PidGains, dt: float) -> tuple[NDArray[np.float64], PidState]:
    """One PID tick, eqs. (33)/(36): ``u = Kp e + Ki ∫e + Kd de/dt`` with anti-windup.

    ``error`` is the 6-vector ``L_E = [ω; v]`` (eq. 26), ``dt`` the tick (s; ``0`` → no integration,
    no derivative).  Returns ``(u, new_state)`` with ``|u_i| <= u_max_i``; ``state`` is not modified.
    """
    e = np.asarray(error, dtype=np.float64)
    if e.shape != (N_AXES,):
        raise ValueError(f"pid_step needs a 6-vector error, got shape {e.shape}")
    if not (dt >= 0.0 and math.isfinite(dt)):
        raise ValueError(f"pid_step needs a finite dt >= 0, got {dt}")
    deriv = state.derivative
    if dt > 0.0 and state.last_error is not None and gains.has_d:  # type: ignore[attr-defined]
        a = dt / (gains.d_tau + dt)
        deriv = deriv + a * ((e - state.last_error) / dt - deriv)
    integral = state.integral
    p_d = gains.kp * e
    if gains.has_d:  # type: ignore[attr-defined]
        p_d = p_d + gains.kd * deriv
    if dt > 0.0 and gains.has_i:  # type: ignore[attr-defined]
        cand = np.minimum(np.maximum(integral + e * dt, gains.neg_i_limit), gains.i_limit)  # type: ignore[attr-defined]
        u_try = p_d + gains.ki * cand
        # conditional integration: an axis saturated in the direction its error pushes keeps its integral
        winding = (np.abs(u_try) > gains.u_max) & (u_try * e > 0.0)
        if winding.any():
            cand = np.where(winding, integral, cand)
        integral = cand
    u = np.minimum(np.maximum(p_d + gains.ki * integral, gains.neg_u_max), gains.u_max)  # type: ignore[attr-defined]
    return u, PidState(integral, e.copy(), deriv)
