"""docs/extending.md's worked example, run as written: a noisy, delayed range sensor added to
``flat_ground`` as a declaration (a :class:`~taskflow_sim.core.sensors.SensorStream`), under 40 lines."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from taskflow_robots.racecar import Racecar

from taskflow.api import ObsKey, scalar
from taskflow.catalogue.conformance import check_pair

DOC = Path(__file__).resolve().parents[2] / "docs" / "extending.md"
ROBOT = Racecar(Racecar.Params())
DT = 0.05
RANGE = ObsKey("sensors.range", scalar(optional=True))


def _example() -> tuple[str, dict[str, object]]:
    text = DOC.read_text()
    code = re.search(r"<!-- range-sensor-example -->\n```python\n(.*?)```", text, re.S)
    assert code is not None, "the range-sensor example block is missing from docs/extending.md"
    ns: dict[str, object] = {"__name__": "range_example"}
    exec(compile(code.group(1), str(DOC), "exec"), ns)
    return code.group(1), ns


SOURCE, NS = _example()
RangeGround, RangeGroundParams = NS["RangeGround"], NS["RangeGroundParams"]


def _run(seed: int = 0, seconds: float = 2.0, **params):
    """(t, range read through the key, stamp of that reading, ground-truth x) at every control tick."""
    world = RangeGround(ROBOT, RangeGroundParams(**params), seed=seed)
    world.reset()
    out = []
    try:
        for _ in range(round(seconds / DT)):
            obs = world.observe()
            assert RANGE(obs) == RANGE(world.observe())  # observe() is pure
            latest = world.streams["range"].latest
            out.append((obs.t, RANGE(obs), None if latest is None else latest.stamp, world.ground_truth()["x"]))
            world.apply({"v": np.array([0.5]), "steer": np.array([0.0])})
            world.advance(DT)
    finally:
        world.close()
    return out


def test_the_example_is_short():
    lines = [ln for ln in SOURCE.splitlines() if ln.strip()]
    classes = SOURCE[SOURCE.index("class RangeGroundParams"):]
    assert len([ln for ln in classes.splitlines() if ln.strip()]) < 40, len(lines)


def test_the_range_arrives_after_its_latency_noisy_and_at_its_rate():
    run = _run(range_latency=0.1, range_noise=0.02, range_hz=10.0)
    ts, xs = np.array([r[0] for r in run]), np.array([r[3] for r in run])
    delivered = [(t, r, stamp) for t, r, stamp, _ in run if r is not None]
    assert all(0.1 - 1e-9 <= t - stamp < 0.1 + DT + 1e-9 for t, _, stamp in delivered)  # the latency
    assert delivered[0][2] == pytest.approx(1 / 240)  # captured after the first physics step
    errors = [r - (5.0 - float(np.interp(stamp, ts, xs))) for _, r, stamp in delivered]  # beacon ahead on x
    assert 0.01 < float(np.std(errors)) < 0.04 and abs(float(np.mean(errors))) < 0.015  # the 2 cm noise
    stamps = sorted({stamp for _, _, stamp in delivered})
    assert np.diff(stamps) == pytest.approx(0.1, abs=1 / 240)  # its own 10 Hz, not the 20 Hz loop
    clean = _run(range_noise=0.0)
    assert all(r is None or r == pytest.approx(5.0 - float(np.interp(st, ts, xs)), abs=2e-3) for _, r, st, _ in clean)


def test_the_example_is_deterministic_and_conforms():
    assert _run(seed=3, seconds=1.0) == _run(seed=3, seconds=1.0)
    assert _run(seed=3, seconds=1.0) != _run(seed=4, seconds=1.0)
    res = check_pair(RangeGround, Racecar, steps=4)
    assert res.ok, str(res)
