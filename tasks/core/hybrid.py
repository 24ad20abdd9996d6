"""ViKi-HyCo hybrid law (eq. 25) and velocity smoothing (eq. 26).

Velocities are robot commands ``V = [v, w]`` (m/s, rad/s); the functions work elementwise on any
vector.

Eq. 25 as printed, ``V = (1 - c) {VS} + c {kinematic}`` with ``c = 1`` when the object is
detected, would run the kinematic controller exactly when the camera sees the object. The text
around it (and section III-C) says the opposite: visual servoing while detected, the kinematic
controller when detections drop. As meant: ``V = c V_vs + (1 - c) V_kin``, ``c = 1`` if detected.

Eq. 26 as printed, ``V_n = (1 - (V_n - V_{n-1})) . V_n``, is meant to damp abrupt changes, but
its factor exceeds 1 whenever a component decreases (``V_n < V_{n-1}``) and becomes negative
when it rises by more than 1, flipping the sign of the command. As meant (REFERENCE.md): the
factor is ``clip(1 - |V_n - V_{n-1}|, 0, 1)`` elementwise, so the output never exceeds the new
command in magnitude and never flips its sign; a jump of 1 (m/s or rad/s) or more in a
component holds that component at 0 for the tick. Note the factor mixes units (m/s and rad/s
are damped by the same rule) as in the paper.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["hybrid_velocity", "smooth_velocity"]


def hybrid_velocity(
    v_vs: ArrayLike | None, v_kin: ArrayLike | None, detected: bool
) -> NDArray[np.float64]:
    """Eq. 25 as meant: ``c V_vs + (1 - c) V_kin`` with ``c = 1`` when the object is detected.

    The branch that is not selected may be ``None`` (e.g. no features to compute ``V_vs``).
    """
    chosen = v_vs if detected else v_kin
    if chosen is None:
        which = "v_vs" if detected else "v_kin"
        raise ValueError(f"{which} is required when detected={bool(detected)}")
    return np.array(chosen, dtype=float)


def smooth_velocity(v_new: ArrayLike, v_prev: ArrayLike) -> NDArray[np.float64]:
    """Eq. 26 as meant: ``clip(1 - |v_new - v_prev|, 0, 1) * v_new`` elementwise.

    ``v_prev`` is the command applied on the previous tick (this function's previous output).
    Never amplifies (``|out| <= |v_new|``) and never flips a sign.
    """
    a = np.asarray(v_new, dtype=np.float64)
    b = np.asarray(v_prev, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"v_new and v_prev must have the same shape, got {a.shape} and {b.shape}")
    factor: NDArray[np.float64] = np.maximum(1.0 - np.abs(a - b), 0.0)  # <= 1 by construction
    return factor * a
