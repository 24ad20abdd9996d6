"""What the screw tasks share across states: the mission data (one definition per key), the typed
observation keys they read, and the control period they integrate with.

Every :class:`~taskflow_tasks.screw.mobile_pbvs.MobilePbvs` task writes the PID, compliance and
nominal-trajectory keys (each starts from what is there, or from zero), so a state change switches
gains and set-points, not the controllers' memory (the platform keeps the integral that carries it
along with the part); :class:`~taskflow_tasks.screw.home.ArmHome` writes the arm's.  The part-motion
predictor's whole state is one object under :data:`PREDICTOR`.  The marker and wrench keys are the
shared laws' (:mod:`taskflow_tasks.core.keys`); the mobile iiwa's own state keys are here.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from taskflow_tasks.core.impedance import AdmittanceState
from taskflow_tasks.core.pid import PidState
from taskflow_tasks.screw.prediction import MotionPredictor

from taskflow.api import MemoryKey, ObsKey, TaskContext, array, instance

PID_B: MemoryKey[PidState] = MemoryKey("screw.pid_b", instance(PidState), output=False,
                                       doc="platform PID state (eqs. 25-33)")
PID_A: MemoryKey[PidState] = MemoryKey("screw.pid_a", instance(PidState), output=False,
                                       doc="arm PID state (eqs. 34-36)")
Q_NOM: MemoryKey[NDArray[np.float64]] = MemoryKey("screw.q_nom", array(7), unit="rad",
                                                  doc="the arm's nominal joint trajectory q*")
ADMITTANCE: MemoryKey[AdmittanceState] = MemoryKey("screw.adm", instance(AdmittanceState), output=False,
                                                   doc="compliance offset (eqs. 38-40)")
PREDICTOR: MemoryKey[MotionPredictor] = MemoryKey(
    "screw.predictor", instance(MotionPredictor), output=False,
    doc="the part-motion predictor (prediction): odometry history, the part's poses and their fitted motion")

ODOM: ObsKey[NDArray[np.float64]] = ObsKey("state.odom", array(3))
Q: ObsKey[NDArray[np.float64]] = ObsKey("state.q", array(7))
Q_REF: ObsKey[NDArray[np.float64]] = ObsKey("state.q_ref", array(7))


def control_period(ctx: TaskContext[Any, Any], name: str) -> float:
    """The control period ``ctx.dt`` (1 / rate_hz, set by the framework): the PIDs integrate it, the
    compensation (eqs. 34–36), the arm step (eq. 37), the admittance (eqs. 38–40) and the homing ramp
    use it; it is not estimated from observation times.  A task built without one would integrate
    nothing and never move the arm, so that is refused."""
    dt = float(ctx.dt)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"{name} needs the control period TaskContext.dt > 0 s (1 / rate_hz), got {ctx.dt!r}")
    return dt
