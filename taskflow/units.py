"""Units in mission files: quantities like ``2 px``, ``1 cm``, ``3 deg``, ``0.2 s``.

Every value is converted to the SI base unit of its dimension when the mission loads; metrics are
published in base units, so a guard compares plain floats at run time.
"""

from __future__ import annotations

import math
import re

# dimension -> {unit: factor to the base unit}; the base unit of a dimension is its unit of factor 1
_UNITS_OF: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "pixel": {"px": 1.0},
    "time": {"s": 1.0, "ms": 1e-3, "min": 60.0},
    "speed": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3},
    "angular_speed": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
    "frequency": {"Hz": 1.0, "kHz": 1e3},
    "force": {"N": 1.0},
    "torque": {"Nm": 1.0},
    "ratio": {"%": 1e-2, "": 1.0},
}

# unit -> (dimension, factor to the base unit)
UNITS: dict[str, tuple[str, float]] = {u: (dim, f) for dim, units in _UNITS_OF.items() for u, f in units.items()}

# the base unit a task or world may declare for a metric
BASE_UNIT_OF: dict[str, str] = {dim: next(u for u, f in units.items() if f == 1.0) for dim, units in _UNITS_OF.items()}

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z%/]*)\s*$")


class UnitError(ValueError):
    """A malformed quantity or a unit of the wrong dimension."""


def dimension(unit: str) -> str:
    try:
        return UNITS[unit][0]
    except KeyError:
        raise UnitError(f"unknown unit {unit!r} — valid: {', '.join(u for u in UNITS if u)}") from None


def to_base(value: float, unit: str) -> float:
    return value * UNITS[unit][1] if unit in UNITS else _unknown(unit)


def _unknown(unit: str) -> float:
    raise UnitError(f"unknown unit {unit!r} — valid: {', '.join(u for u in UNITS if u)}")


def with_article(word: str) -> str:
    word = word.replace("_", " ")
    return ("an " if word[0] in "aeiou" else "a ") + word


def parse_quantity(text: str | float | int, expect: str | None = None) -> tuple[float, str]:
    """``"2 cm"`` → ``(0.02, "length")``.  ``expect`` is a dimension the unit must have."""
    if isinstance(text, bool):
        raise UnitError(f"expected a quantity like '2 cm', got {text!r}")
    if isinstance(text, (int, float)):
        value, unit = float(text), ""
    else:
        m = _QUANTITY.match(str(text))
        if not m:
            raise UnitError(f"expected a number with a unit like '2 cm' or '0.5 s', got {text!r}")
        value, unit = float(m.group(1)), m.group(2)
    dim = dimension(unit)
    if expect is not None and dim != expect:
        if unit == "" and expect != "ratio":
            raise UnitError(f"{text!r} has no unit — write it in {BASE_UNIT_OF[expect]!r} or another {expect} unit")
        raise UnitError(f"{text!r} is {with_article(dim)}, expected {with_article(expect)} (e.g. {BASE_UNIT_OF[expect]!r})")
    return to_base(value, unit), dim


def parse_duration(text: str | float | int) -> float:
    """Seconds from ``"5 s"``, ``"200 ms"``, or a bare number of seconds (finite, ≥ 0)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        if not math.isfinite(text):
            raise UnitError(f"a duration must be a finite number of seconds, got {text!r}")
        if text < 0:
            raise UnitError(f"a duration cannot be negative: {text!r}")
        return float(text)
    value, _ = parse_quantity(text, expect="time")
    if not math.isfinite(value):
        raise UnitError(f"a duration must be finite, got {text!r}")
    if value < 0:
        raise UnitError(f"a duration cannot be negative: {text!r}")
    return value


def parse_bounded(text: str | float | int, dim: str, what: str, low: float, high: float,
                  low_inclusive: bool = False) -> float:
    """A finite quantity of dimension ``dim`` (a bare number is taken in its base unit) within
    ``(low, high]`` (``[low, high]`` with ``low_inclusive``), in base units."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        value, _ = parse_quantity(text, expect=dim)
    unit = BASE_UNIT_OF[dim]
    if not math.isfinite(value):
        raise UnitError(f"{what} must be a finite number of {unit}, got {text!r}")
    if value < low or (value == low and not low_inclusive) or value > high:
        lo = "≥" if low_inclusive else ">"
        raise UnitError(f"{what} must be {lo} {low:g} {unit} and ≤ {high:g} {unit}, got {text!r}")
    return value


MAX_TIME_S = 86_400.0
"""Longest simulated time a run may be given (one simulated day)."""

MAX_RATE_HZ = 10_000.0


def parse_max_time(text: str | float | int) -> float:
    """``max_time`` / ``--max-time``: ``"90 s"``, ``"2 min"`` or seconds; finite, > 0, ≤ one simulated day."""
    return parse_bounded(text, "time", "max_time", 0.0, MAX_TIME_S)


def parse_rate(text: str | float | int) -> float:
    """``rate_hz``: ``20``, ``"20 Hz"`` or ``"1 kHz"``; finite, > 0, ≤ 10 kHz."""
    return parse_bounded(text, "frequency", "rate_hz", 0.0, MAX_RATE_HZ)


SUFFIX_UNITS: dict[str, str] = {"_mps": "m/s", "_radps": "rad/s", "_mm": "mm", "_hz": "Hz", "_m": "m", "_deg": "deg",
                                "_rad": "rad", "_px": "px", "_s": "s", "_n": "N"}
"""Name suffix → the unit a name ending in it is in (``final_error_m``: m, ``gt_speed_mps``: m/s); longest
suffix first, so ``_mps`` wins over ``_s``."""


def suffix_unit(name: str) -> str | None:
    """The unit ``name`` declares by its suffix (:data:`SUFFIX_UNITS`); None when it declares none (a count,
    a ratio, a label)."""
    return next((unit for suffix, unit in SUFFIX_UNITS.items() if name.endswith(suffix)), None)
