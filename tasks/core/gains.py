"""Checks of gain blocks, one definition for every profile that holds gains.

* :func:`positive_gains`: a fixed-length gain tuple whose every entry is finite and > 0 (eq. 4's ``k1``
  of the car laws, ViKi-HyCo's ``lam``);
* :func:`axis_gains`: a per-axis vector (a diagonal gain matrix) given as one number per named axis, or
  one number for all with ``broadcast`` — the six-axis PID's ``kp, ki, kd, u_max, i_limit``
  (``[ωx, ωy, ωz, vx, vy, vz]``) and the admittance's ``K, D, M, force`` (tool ``x, y, z``).

Both raise ``ValueError`` with the field's name, so pydantic reports them at the field.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def positive_gains(name: str, gains: Sequence[float]) -> tuple[float, ...]:
    """``gains`` as a tuple, refused (``ValueError``) unless every entry is finite and > 0."""
    if not all(math.isfinite(k) and k > 0.0 for k in gains):
        raise ValueError(f"{name} gains must be finite and > 0, got {list(gains)}")
    return tuple(gains)


def axis_gains(name: str, value: object, axes: Sequence[str], *, positive: bool = False, nonneg: bool = True,
               allow_inf: bool = False, broadcast: bool = False) -> tuple[float, ...]:
    """One number per axis of ``axes`` (a list or tuple; with ``broadcast`` one number stands for all).

    Every value is a number (not a bool), finite (``inf`` too with ``allow_inf``), ``>= 0`` with ``nonneg``
    and ``> 0`` with ``positive``."""
    n, names = len(axes), " ".join(axes)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if not broadcast:
            raise ValueError(f"{name} needs {n} values, one per axis ({names}), got the single number {value}")
        value = [value] * n
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{name} needs a list of {n} numbers ({names}), got {type(value).__name__}")
    if len(value) != n:
        either = " or one number for all" if broadcast else ""
        raise ValueError(f"{name} needs {n} values, one per axis ({names}){either}, got {len(value)}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"{name} values must be numbers, got {v!r}")
        f = float(v)
        if math.isnan(f) or (math.isinf(f) and not allow_inf):
            raise ValueError(f"{name} values must be finite, got {v!r}")
        if (nonneg or positive) and (f < 0.0 or (positive and f == 0.0)):
            raise ValueError(f"{name} values must be {'> 0' if positive else '>= 0'} on every axis, got {v!r}")
        out.append(f)
    return tuple(out)
