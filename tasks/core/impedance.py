"""Admittance (compliance) controller of the screw-fastening paper, eqs. (19), (38)–(40).

Eq. (38) relates a Cartesian displacement ``Δx`` of the tool from its nominal pose to the force::

    M Δẍ + D Δẋ + K Δx = ΔF,        ΔF = F_measured − F_desired                     (38)

Eq. (39) as printed, ``ΔX = ΔF / (M Δt² + D Δt + K)``, is a one-step discretisation that mixes units
(``M Δt²`` is not a stiffness) and forgets the displacement and velocity of the previous tick, so it
has no dynamics at all.  As meant (REFERENCE.md §2) the admittance is **integrated every tick**; here
with implicit (backward) Euler, which is unconditionally stable, so a "stiff" profile with a very
large ``K`` is as safe as a compliant one::

    v⁺ = v + dt a⁺,   x⁺ = x + dt v⁺,   M a⁺ + D v⁺ + K x⁺ = ΔF
    ⇒ x⁺ = (ΔF + M (x + dt v)/dt² + D x/dt) / (M/dt² + D/dt + K)                     (39, as meant)

Its steady state is ``K Δx = ΔF``.  The displacement is added to the nominal joints with the
pseudo-inverse at the nominal configuration (eq. 40, :func:`taskflow_tasks.core.pbvs.arm_twist_step` does the
solve).

Axes: the paper's compliant profile ``I_c`` is compliant in X, Y, Z (translation only), so the law
acts on the three translational axes of the **tool frame**.  ``force`` is the force the tool should
exert on the part, in the tool frame (+z pushes along the screwdriver axis into the bolt); the
*measured* force ``F`` is the environment's force on the tool (what a gravity-compensated F/T sensor
reads), so the contact settles when ``F = −force``.  With that convention ΔF = F + force.
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

TOOL_AXES = ("x", "y", "z")


class ImpedanceProfile(StrictModel):
    """An impedance set ``I = {K, D, M}`` (eq. 19): diagonal stiffness ``K`` (N/m, > 0), damping
    ``D`` (N·s/m, ≥ 0) and virtual mass ``M`` (kg, > 0) on the tool's x, y, z axes, plus the
    contact ``force`` (N, tool frame) the tool should exert.  Profiles live under
    ``profiles.impedance`` (paper: ``stiff`` I_s and ``compliant`` I_c)."""

    kind: ClassVar[str] = "impedance"

    K: tuple[float, float, float]
    D: tuple[float, float, float] = (0.0, 0.0, 0.0)
    M: tuple[float, float, float] = (1.0, 1.0, 1.0)
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)

    # field → (name in messages, > 0 required, >= 0 required)
    _RULES: ClassVar[dict[str, tuple[str, bool, bool]]] = {
        "K": ("stiffness K", True, True), "M": ("mass M", True, True),
        "D": ("damping D", False, True), "force": ("force", False, False)}

    @field_validator("K", "M", "D", "force", mode="before")
    @classmethod
    def _xyz(cls, v: object, info: ValidationInfo) -> tuple[float, float, float]:
        name, positive, nonneg = cls._RULES[str(info.field_name)]
        x, y, z = axis_gains(name, v, TOOL_AXES, positive=positive, nonneg=nonneg, broadcast=True)
        return (x, y, z)

    def arrays(self) -> ImpedanceGains:
        return ImpedanceGains(np.array(self.K), np.array(self.D), np.array(self.M), np.array(self.force))


@dataclass(frozen=True)
class ImpedanceGains:
    """:class:`ImpedanceProfile` as arrays (tool x, y, z)."""

    K: NDArray[np.float64]
    D: NDArray[np.float64]
    M: NDArray[np.float64]
    force: NDArray[np.float64]


@dataclass
class AdmittanceState:
    """Displacement ``Δx`` (m) and its rate (m/s) in the tool frame."""

    x: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    v: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


def admittance_step(force: NDArray[np.float64], state: AdmittanceState, gains: ImpedanceGains,
                    dt: float) -> AdmittanceState:
    """Integrate eq. (38) over one tick with implicit Euler (eq. 39 as meant).

    ``force``: measured force of the environment on the tool (N, tool frame).  Returns the new
    ``(Δx, Δẋ)``; ``dt = 0`` returns the state unchanged.
    """
    f = np.asarray(force, dtype=np.float64)
    if f.shape != (3,):
        raise ValueError(f"admittance_step needs a 3-vector force, got shape {f.shape}")
    if not (dt >= 0.0 and math.isfinite(dt)):
        raise ValueError(f"admittance_step needs a finite dt >= 0, got {dt}")
    if dt == 0.0:
        return state
    dF = f + gains.force
    m_dt2 = gains.M / (dt * dt)
    d_dt = gains.D / dt
    x_new = (dF + m_dt2 * (state.x + dt * state.v) + d_dt * state.x) / (m_dt2 + d_dt + gains.K)
    v_new = (x_new - state.x) / dt
    return AdmittanceState(x_new, v_new)


def static_displacement(force: NDArray[np.float64], gains: ImpedanceGains) -> NDArray[np.float64]:
    """The steady state of eq. (38): ``Δx = ΔF / K``."""
    return (np.asarray(force, dtype=np.float64) + gains.force) / gains.K
