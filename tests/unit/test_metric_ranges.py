"""Metric ranges: a task declares the values a metric can take (:class:`taskflow.api.Metric`), the loader
refuses a guard comparison no such value satisfies, and the catalogue shows each range with its reason."""

from __future__ import annotations

import math
import pickle
from typing import Any, ClassVar

import pytest
from toys import ToyMark

from taskflow.api import DISTANCE, FLAG, WRAPPED_ANGLE, MemoryKey, Metric, flag, scalar
from taskflow.catalogue.catalogue import build
from taskflow.catalogue.catalogue_render import describe_text
from taskflow.errors import MissionError
from taskflow.execution.data import DataCatalogue
from taskflow.mission.guards import bind_units, never_holds, parse_guard
from taskflow.mission.loader import load_mission_text


def _never(text: str, unit: str) -> list[bool]:
    g = parse_guard(text)
    assert bind_units(g, {c.metric: unit for c in g.comparisons()}, {}) == []
    return [never_holds(c, getattr(unit, "low", None), getattr(unit, "high", None)) for c in g.comparisons()]


def test_metric_is_its_unit_and_keeps_its_range() -> None:
    m = Metric("m", low=0.0, reason="a distance")
    assert m == "m" and isinstance(m, str) and {"x": m} == {"x": "m"}
    assert (m.low, m.high, m.reason, m.bounds()) == (0.0, None, "a distance", "≥ 0")
    back = pickle.loads(pickle.dumps(m))
    assert back == "m" and (back.low, back.high, back.reason) == (0.0, None, "a distance")
    assert WRAPPED_ANGLE.bounds() == f"in [{-math.pi:g}, {math.pi:g}]"
    with pytest.raises(ValueError, match="low <= high"):
        Metric("", low=1.0, high=0.0)


@pytest.mark.parametrize("text, unit, never", [
    ("x < -1 mm", DISTANCE, True), ("x <= 0 m", DISTANCE, False), ("x < 0 m", DISTANCE, True),
    ("x <= -1 mm", DISTANCE, True), ("x > 1 m", DISTANCE, False), ("x == -2 m", DISTANCE, True),
    ("x != -2 m", DISTANCE, False), ("x > 4 rad", WRAPPED_ANGLE, True), ("x >= 3 rad", WRAPPED_ANGLE, False),
    ("x < -3.2 rad", WRAPPED_ANGLE, True), ("x > -4 rad", WRAPPED_ANGLE, False), ("x > 180 deg", WRAPPED_ANGLE, True),
    ("abs(x) < 0 m", "m", True), ("abs(x) <= 0 m", "m", False), ("abs(x) <= -1 mm", "m", True),
    ("abs(x) > 4 rad", WRAPPED_ANGLE, True), ("abs(x) > 3 rad", WRAPPED_ANGLE, False),
    ("x < -1 m", "m", False), ("x > 1", FLAG, True), ("x >= 1", FLAG, False), ("x < 0", FLAG, True),
])
def test_a_comparison_outside_the_range_never_holds(text: str, unit: str, never: bool) -> None:
    assert _never(text, unit) == [never]


def test_abs_of_a_range_away_from_zero() -> None:
    g = parse_guard("abs(x) < 1 m")
    bind_units(g, {"x": "m"}, {})
    assert never_holds(g.comparisons()[0], 2.0, 5.0)  # |x| ≥ 2 there
    assert not never_holds(g.comparisons()[0], -0.5, 5.0)


MISSION = """\
mission: m
robot: racecar
world: flat_ground
rate_hz: 20
max_time: 10 s
parameters: {tol: %s}
profiles: {gains: {cruise: {k1: [1.0, 1.0], d: 0.325}}}
machine:
  initial: go
  states:
    go:
      task: {name: car_goto, params: {target: [1.0, 0.0]}}
      bind: {gains: cruise}
      transitions:
        - {to: done, when: "%s"}
        - {to: done, after: 5 s}
    done: {final: succeeded}
"""


def _problems(text: str) -> list[str]:
    try:
        load_mission_text(text, "m.yaml")
    except MissionError as exc:
        return [str(p) for p in exc.problems]
    return []


def test_the_loader_refuses_a_guard_its_metric_can_never_satisfy() -> None:
    (msg,) = _problems(MISSION % ("-1 mm", "pos_error < $tol or heading_error < 1 deg"))
    assert msg.startswith("m.yaml:15:22: ") and "pos_error < $tol = -0.001 m can never hold" in msg
    assert "pos_error is a distance: ≥ 0 m" in msg and "a threshold inside the metric's range" in msg
    assert "\n" not in msg
    msgs = _problems(MISSION % ("1 cm", "heading_error > 200 deg and speed < -1 m/s"))
    assert len(msgs) == 2 and "heading_error > 3.49066 rad can never hold" in msgs[0] and "speed < -1 m/s" in msgs[1]
    # a threshold from a --set: the --set is named
    try:
        load_mission_text(MISSION % ("1 cm", "pos_error < $tol"), "m.yaml", overrides=["parameters.tol=-1 mm"])
    except MissionError as exc:
        (p,) = exc.problems
        assert str(p).startswith("m.yaml: --set parameters.tol=-1 mm: guard 'pos_error < $tol': pos_error < $tol = "
                                 "-0.001 m can never hold"), str(p)
    else:
        pytest.fail("a --set threshold no distance reaches was accepted")
    # inside the range, and '!=' / the edges: accepted
    assert _problems(MISSION % ("0 mm", "pos_error <= $tol or abs(heading_error) <= 0 rad or speed != -1 m/s")) == []
    assert _problems(MISSION % ("1 cm", "heading_error >= 3.1 rad or heading_error < -3 rad")) == []


def test_a_flag_data_key_reads_as_one_or_zero_and_a_ranged_key_keeps_its_range() -> None:
    on = MemoryKey("t.on", flag())
    count = MemoryKey("t.count", scalar(), unit=Metric("", low=1.0, reason="a sequence number"))
    units = DataCatalogue(keys={k.name: k for k in (on, count)}).guard_units()
    assert units["data.t.on"] is FLAG and units["data.t.count"] is count.unit


def test_a_guard_on_a_ranged_data_key_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    ranged = MemoryKey("toy.mark", scalar(), unit=DISTANCE)  # as if toy.mark were a distance
    writes: ClassVar[tuple[MemoryKey[Any], ...]] = (ranged,)
    monkeypatch.setattr(ToyMark, "writes", writes)
    head = ("mission: m\nrobot: toy_point\nworld: {name: toy_line, params: {start: 0.3}}\nrate_hz: 20\nmax_time: 5 s\n"
            "machine:\n  initial: mark\n  states:\n    mark:\n      task: toy_mark\n"
            "      transitions: [{to: done, when: \"%s\"}]\n    done: {final: succeeded}\n")
    (msg,) = _problems(head % "data.toy.mark < -2 cm")
    assert "data.toy.mark < -0.02 m can never hold (data.toy.mark is a distance: ≥ 0 m)" in msg
    assert _problems(head % "data.toy.mark < 2 cm") == []


def test_describe_shows_each_metric_range_and_its_reason() -> None:
    text = describe_text(build().find("car_goto", "task"))
    assert "pos_error: m, ≥ 0 (a distance)" in text
    assert f"heading_error: rad, in [{-math.pi:g}, {math.pi:g}] (a wrapped angle)" in text
    hyco = describe_text(build().find("viki_hyco", "task"))
    assert "detected: (dimensionless), in [0, 1] (1 when true, 0 when false)" in hyco
    assert "object_x: m\n" in hyco  # a signed coordinate: no range
