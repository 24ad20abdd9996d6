"""The sensor stream (sim/core/sensors.py) without a simulator: rate, latency under both queue policies
and from the past, noise, dropout, faults, lost/found, determinism — and each of the three per-world
latency implementations it replaces, written out here as they were, reproduced draw for draw."""

from __future__ import annotations

import math

import numpy as np
import pytest
from taskflow_sim.core.sensors import Reading, SensorStream
from taskflow_sim.core.stepped import EPS_T, SensorSchedule

H = 1.0 / 240.0


def _times(n: int, h: float = H) -> list[float]:
    return [(k + 1) * h for k in range(n)]


def test_rate_captures_on_the_schedule_and_none_captures_every_poll():
    s = SensorStream(lambda t, _: t, 30.0)
    ref = SensorSchedule(30.0)
    got, want = [], []
    for t in _times(240):
        s.poll(t)
        got.append(s.captured)
        ref.poll(t)
        want.append(ref.fired)
    assert got == want and s.captured == 31  # t = 0, 1/30, ..., 1 s
    every = SensorStream(lambda t, _: t, None)
    for t in _times(10):
        every.poll(t)
    assert every.captured == every.delivered == 10


def test_latency_each_delivers_every_reading_in_order_after_the_delay():
    s = SensorStream(lambda t, _: t, 60.0, latency=0.05, delivery="each")
    delivered = []
    for t in _times(240):
        before = s.delivered
        s.poll(t)
        if s.delivered > before:
            assert s.latest is not None and s.latest.value is not None
            assert s.latest.stamp + 0.05 <= t + EPS_T
            delivered.append(s.latest.stamp)
    assert delivered == sorted(delivered) and len(delivered) >= 50


def test_latency_newest_drops_older_due_readings():
    s = SensorStream(lambda t, _: t, 60.0, latency=0.05, delivery="newest", poll="advance")
    seen = []
    for t in _times(20, h=0.1):  # a slow poll: several readings due at once, only the newest is seen
        s.poll(t)
        if s.new:
            assert s.latest is not None
            seen.append(s.latest.stamp)
        s.begin_advance()
    assert s.delivered == len(seen) == 19 < s.captured
    assert all(b - a == pytest.approx(0.1) for a, b in zip(seen, seen[1:]))


def test_past_delivery_captures_the_state_logged_latency_ago():
    state = {"x": 0.0}
    s = SensorStream(lambda t, snap: (t, snap), 10.0, latency=0.2, delivery="past", snapshot=lambda: state["x"],
                     poll="advance")
    for t in _times(30, h=0.05):
        state["x"] = t
        s.poll(t)
        if s.new:
            assert s.latest is not None and s.latest.value is not None
            stamp, snap = s.latest.value
            assert snap == stamp and stamp <= t - 0.2 + EPS_T or stamp == pytest.approx(0.05)


def test_dropout_faults_and_noise_draw_in_the_documented_order():
    rng = np.random.default_rng(3)
    s = SensorStream(lambda t, _: 1.0, None, faults=[(0.5, 1.0)], dropout=0.3, rng=rng,
                     corrupt=lambda v, t, r: v + r.normal())
    ref = np.random.default_rng(3)
    for t in _times(480):
        s.poll(t)
        assert s.latest is not None
        if 0.5 <= t < 1.0:
            assert s.latest.value is None  # a fault draws nothing
            continue
        if ref.random() < 0.3:
            assert s.latest.value is None
        else:
            assert s.latest.value == 1.0 + ref.normal()
    assert s.dropped > 0


def test_dropout_zero_still_draws_and_none_draws_nothing():
    a = np.random.default_rng(1)
    SensorStream(lambda t, _: 1.0, None, dropout=0.0, rng=a).poll(0.0)
    b = np.random.default_rng(1)
    SensorStream(lambda t, _: 1.0, None, rng=b).poll(0.0)
    assert a.random() != b.random()


def test_timeout_lost_found():
    seen = {"on": True}
    s = SensorStream(lambda t, _: 1.0 if seen["on"] else None, 30.0, events=("found", "lost"), lost_after=0.2)
    events = []
    for t in _times(480):
        seen["on"] = not (0.5 <= t < 1.0)
        s.begin_advance()
        s.poll(t)
        events += [(round(t, 3), e) for e in s.events]
    assert [e for _, e in events] == ["found", "lost", "found"]
    assert 0.666 < events[1][0] < 0.672 and events[2][0] >= 1.0  # last frame 0.4667 s, + lost_after 0.2 s


def test_change_lost_found_on_each_delivered_reading():
    vals = iter([None, None, 1.0, 1.0, None, 1.0])
    s = SensorStream(lambda t, _: next(vals), None, events=("found", "lost"), poll="advance")
    out = []
    for t in range(6):
        s.begin_advance()
        s.poll(float(t))
        out.append(tuple(s.events))
    assert out == [(), (), ("found",), (), ("lost",), ("found",)]


def test_present_predicate_and_disabled_stream():
    s = SensorStream(lambda t, _: {"bbox": None}, None, events=("found", "lost"), present=lambda v: v["bbox"] is not None)
    s.poll(0.0)
    assert s.events == [] and s.last_present is None and s.latest == Reading(0.0, {"bbox": None})
    s.enabled = False
    s.poll(1.0)
    assert s.captured == 1


def test_deterministic_and_restart():
    def run() -> list[object]:
        s = SensorStream(lambda t, _: t, 45.0, latency=0.03, dropout=0.2, rng=np.random.default_rng(9),
                         corrupt=lambda v, t, r: v + r.normal(0.0, 0.01))
        out = []
        for t in _times(300):
            s.poll(t)
            out.append(s.latest)
        return out
    assert run() == run()
    s = SensorStream(lambda t, _: t, 10.0, latency=1.0)
    for t in _times(100):
        s.poll(t)
    s.restart(0.0)
    assert s.queue == [] and s.latest is None and s.captured == 0


def test_bad_configuration_is_refused():
    with pytest.raises(ValueError, match="rng"):
        SensorStream(lambda t, _: 1.0, 10.0, dropout=0.1)
    with pytest.raises(ValueError, match="snapshot"):
        SensorStream(lambda t, _: 1.0, 10.0, delivery="past")
    with pytest.raises(ValueError, match="latency"):
        SensorStream(lambda t, _: 1.0, 10.0, latency=-1.0)


# -- the three latency implementations the stream replaces, as the worlds wrote them -----------------


def _screw_reference(truth, visible, rate, lat, lost_after, dropout, noise_std, seed, n):
    """screw_conveyor (pose mode): capture per physics step, queue, each in order, timeout lost/found."""
    rng = np.random.default_rng(seed)
    sched, queue, out = SensorSchedule(rate), [], []
    last_seen, vis = None, False
    for t in _times(n):
        events = []
        if sched.poll(t):
            if not visible(t) or rng.random() < dropout:
                queue.append((t, None))
            else:
                queue.append((t, truth(t) + rng.normal(0.0, noise_std)))
        marker = None
        while queue and queue[0][0] + lat <= t + EPS_T:
            st, v = queue.pop(0)
            if v is not None:
                marker = (st, v)
                last_seen = st
                if not vis:
                    vis = True
                    events.append("target_found")
        if vis and last_seen is not None and t - last_seen > lost_after + lat:
            vis = False
            events.append("target_lost")
        out.append((marker, tuple(events)))
    return out


def test_reproduces_the_screw_world_stream():
    truth, visible = (lambda t: math.sin(t)), (lambda t: not (0.8 <= t < 1.4))
    ref = _screw_reference(truth, visible, 30.0, 0.07, 0.2, 0.1, 0.01, 5, 720)
    rng = np.random.default_rng(5)
    s = SensorStream(lambda t, _: truth(t) if visible(t) else None, 30.0, latency=0.07, delivery="each",
                     dropout=0.1, rng=rng, corrupt=lambda v, t, r: v + r.normal(0.0, 0.01),
                     events=("target_found", "target_lost"), lost_after=0.2)
    got = []
    for t in _times(720):
        s.begin_advance()
        before = s.last_present
        s.poll(t)
        marker = s.last_present if s.last_present is not before else None
        got.append((None if marker is None else (marker.stamp, marker.value), tuple(s.events)))
    assert got == ref


def _viki_reference(detect, rate, lat, dt, n):
    """viki_ground: capture at control ticks, newest due frame wins, events on a change of outcome."""
    sched, pending, out = SensorSchedule(rate), [], []
    last, last_det = None, None
    def publish(d, events):
        nonlocal last, last_det
        last = d
        if d[1] != last_det and (last_det is not None or d[1]):
            events.append("target_found" if d[1] else "target_lost")
        last_det = d[1]

    for k in range(n):
        t = k * dt
        events: list[str] = []
        fresh = False
        if sched.due(t):
            sched.fire(t)
            det = (t, detect(t))
            if lat > 0.0:
                pending.append(det)
            else:
                publish(det, events)
                fresh = True
        if lat > 0.0:
            due = [i for i, d in enumerate(pending) if d[0] + lat <= t + 1e-9]
            if due:
                d = pending[due[-1]]
                del pending[:due[-1] + 1]
                publish(d, events)
                fresh = True
        out.append((last, fresh, tuple(events)))
    return out


@pytest.mark.parametrize("lat", [0.0, 0.044, 0.2])
def test_reproduces_the_viki_world_stream(lat):
    detect = lambda t: (int(t * 7) % 3) != 0
    ref = _viki_reference(detect, 15.0, lat, 0.05, 200)
    s = SensorStream(lambda t, _: (t, detect(t)), 15.0, latency=lat, delivery="newest", poll="advance",
                     events=("target_found", "target_lost"), present=lambda d: d[1])
    got = []
    for k in range(200):
        t = k * 0.05
        s.begin_advance()
        if k == 0:
            s.restart(0.0)
        s.poll(t)
        got.append((None if s.latest is None else s.latest.value, s.new, tuple(s.events)))
    assert got == ref


def test_reproduces_the_room_world_frame_latency():
    """quad_room: frames at the camera rate captured from the pose logged ``latency`` ago."""
    lat, dt, rate = 0.1, 1.0 / 30.0, 10.0
    pose = [0.0]
    log = [(0.0, 0.0)]
    sched = SensorSchedule(rate)
    ref = []
    s = SensorStream(lambda t, snap: (t, snap), rate, latency=lat, delivery="past", snapshot=lambda: pose[0],
                     poll="advance")
    s.poll(0.0)
    got = [s.latest.value if s.latest else None]
    if sched.poll(0.0):
        ref.append(log[0])
    for k in range(1, 100):
        t = k * dt
        pose[0] = math.cos(t)
        log.append((t, pose[0]))
        s.begin_advance()
        s.poll(t)
        got.append(s.latest.value if s.latest else None)
        if sched.poll(t):
            due = t - lat + 1e-9
            while len(log) > 1 and log[1][0] <= due:
                log.pop(0)
            ref.append(log[0])
        else:
            ref.append(ref[-1])
    assert got == ref


def test_hooks_see_every_capture_and_delivery_and_presents_counts_seen_readings():
    captured, delivered = [], []
    vals = iter([1.0, None, 2.0, 3.0])
    s = SensorStream(lambda t, _: next(vals), None, latency=1.0, on_capture=captured.append,
                     on_deliver=delivered.append)
    for t in (0.0, 1.0, 2.0, 3.0):
        s.poll(t)
    assert [r.stamp for r in captured] == [0.0, 1.0, 2.0, 3.0]
    assert [r.value for r in delivered] == [1.0, None, 2.0]
    assert s.presents == 2 and s.delivered == 3 and s.last_present == Reading(2.0, 2.0)
