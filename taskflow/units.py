"""Units in mission files: quantities like ``2 px``, ``1 cm``, ``3 deg``, ``0.2 s``.

Every value is converted to the SI base unit of its dimension when the mission loads; metrics are
published in base units, so a guard compares plain floats at run time.
"""

from __future__ import annotations

import math
import re

# unit -> (dimension, factor to the base unit)
UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "cm": ("length", 1e-2),
    "mm": ("length", 1e-3),
    "rad": ("angle", 1.0),
    "deg": ("angle", math.pi / 180.0),
    "px": ("pixel", 1.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "m/s": ("speed", 1.0),
    "cm/s": ("speed", 1e-2),
    "mm/s": ("speed", 1e-3),
    "rad/s": ("angular_speed", 1.0),
    "deg/s": ("angular_speed", math.pi / 180.0),
    "Hz": ("frequency", 1.0),
    "kHz": ("frequency", 1e3),
    "N": ("force", 1.0),
    "Nm": ("torque", 1.0),
    "%": ("ratio", 1e-2),
    "": ("ratio", 1.0),
}

# the base unit a task or world may declare for a metric
BASE_UNIT_OF: dict[str, str] = {
    "length": "m",
    "angle": "rad",
    "pixel": "px",
    "time": "s",
    "speed": "m/s",
    "angular_speed": "rad/s",
    "frequency": "Hz",
    "force": "N",
    "torque": "Nm",
    "ratio": "",
}

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
