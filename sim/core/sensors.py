"""The sensor stream: one component owning a sensor's rate, latency, noise, dropout, fault intervals and
lost/found events, polled by the stepping base (:class:`~taskflow_sim.core.stepped.SteppedWorld`).

Anchored on dm_control's ``Observable`` (update interval, delay, corruptor, enabled).  A world declares
its streams (``self.streams = {"marker": SensorStream(...)}``, or :meth:`SteppedWorld.add_stream`) and
reads what they delivered in ``observe()`` (``stream.latest``, ``stream.new``, ``stream.events``);
``observe()`` itself never captures, draws noise or clears anything, so two calls in a row return
equal observations.

The contract, per poll at simulation time ``t`` (a stream with ``poll="physics_step"`` is polled after
every physics step, one with ``poll="advance"`` once at the end of every ``advance`` and once by
:meth:`SteppedWorld.start_streams` at the end of ``reset``):

1. **Rate.**  A :class:`~taskflow_sim.core.stepped.SensorSchedule` at ``rate_hz`` decides whether a
   reading is captured at ``t``; ``rate_hz=None`` captures at every poll (odometry read every control
   tick).  A disabled stream (``enabled = False``) is not polled at all.
2. **Capture**, in this order, which is also the order of the random draws (all from ``rng``):
   a fault interval active at ``t`` → an empty reading (no draw); ``dropout`` with
   ``dropout_first=True`` → one uniform draw, below ``dropout`` → empty (the sensor is not read at
   all: nothing rendered); then ``read(stamp, state)`` gives the true value or ``None`` (nothing in
   view); a value and ``dropout_first=False`` → one uniform draw, below ``dropout`` → empty; a value left
   → ``corrupt(value, stamp, rng)`` (the noise).  ``dropout=None`` draws nothing; ``dropout=0.0``
   still draws (so a mission's draw order does not depend on the probability).  ``on_capture`` sees
   every captured :class:`Reading`, ``on_deliver`` every delivered one (before its lost/found event).
3. **Latency and delivery.**  A captured reading waits in a queue until ``stamp + latency <= t``
   (within :data:`~taskflow_sim.core.stepped.EPS_T`).  ``delivery="each"`` delivers every due reading
   in capture order; ``delivery="newest"`` delivers only the newest due one (older due ones are dropped
   unseen, a detector's queue of one); ``delivery="past"`` has no queue: the reading is captured now
   from the world's state ``latency`` ago (``snapshot()`` is logged at every poll; ``read`` gets the
   newest snapshot logged at or before ``t - latency`` and its stamp).
4. **Lost/found.**  With ``events=(found, lost)``: ``lost_after`` set → *timeout*: ``found`` when a
   present reading is delivered while lost (or never seen), ``lost`` when ``t - last_seen > lost_after +
   latency`` (``last_seen``: stamp of the last present reading delivered); ``lost_after=None`` →
   *change*: an event whenever a delivered reading's presence differs from the previous delivered
   reading's (the first reading emits ``found`` only if present).  ``present(value)`` says whether a
   non-empty value counts as seen (default: every value).  Events go to ``emit`` (default: the stream's
   own ``events``, cleared when the next ``advance`` begins).

Everything is a function of the poll times and the seed: a stream is deterministic.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Generic, Literal, TypeVar

import numpy as np
from pydantic import Field
from taskflow_sim.core.faults import Interval, IntervalFault
from taskflow_sim.core.stepped import EPS_T, SensorSchedule

V = TypeVar("V")

Delivery = Literal["each", "newest", "past"]
PollPoint = Literal["physics_step", "advance"]

DropoutFraction = Annotated[float, Field(ge=0.0, lt=1.0)]
"""The type of a world's ``dropout`` parameter (the chance a frame is missed): in [0, 1), as a sensor
that misses every frame sees nothing; each world gives its own default and description."""


@dataclass(frozen=True, slots=True)
class Reading(Generic[V]):
    """One captured reading: its capture time and value (``None``: empty — a fault, a dropout or nothing
    in view)."""

    stamp: float
    value: V | None


class SensorStream(Generic[V]):
    """One sensor's pipeline (see the module docstring for the contract).

    ``read(stamp, state)``: the true value at capture (``state`` is the snapshot of ``delivery="past"``,
    else ``None``).  ``corrupt(value, stamp, rng)``: the noise.  ``faults``: intervals (or an
    :class:`IntervalFault`) of empty readings.  After a poll: ``latest`` (the last delivered reading,
    empty or not), ``last_present`` (the last delivered present one; ``presents`` counts them — a
    message's ``seq``), ``new`` (something was delivered since the current ``advance`` began),
    ``delivered`` / ``dropped`` / ``captured`` counters.  ``on_capture`` / ``on_deliver`` see each reading
    as it is captured / delivered (a world scoring perception error against the truth at capture)."""

    def __init__(
        self,
        read: Callable[[float, Any], V | None],
        rate_hz: float | None,
        *,
        latency: float = 0.0,
        delivery: Delivery = "each",
        corrupt: Callable[[V, float, np.random.Generator], V] | None = None,
        rng: np.random.Generator | None = None,
        dropout: float | None = None,
        dropout_first: bool = False,
        faults: IntervalFault | Sequence[Interval] = (),
        events: tuple[str, str] | None = None,
        lost_after: float | None = None,
        present: Callable[[V], bool] | None = None,
        emit: Callable[[str], None] | None = None,
        on_capture: Callable[[Reading[V]], None] | None = None,
        on_deliver: Callable[[Reading[V]], None] | None = None,
        snapshot: Callable[[], Any] | None = None,
        poll: PollPoint = "physics_step",
        enabled: bool = True,
    ) -> None:
        if not latency >= 0.0:
            raise ValueError(f"a sensor latency must be >= 0 s, got {latency!r}")
        if dropout is not None and not 0.0 <= dropout <= 1.0:
            raise ValueError(f"a dropout probability must be in [0, 1], got {dropout!r}")
        if (dropout is not None or corrupt is not None) and rng is None:
            raise ValueError("a sensor stream with dropout or noise needs its rng")
        if delivery == "past" and snapshot is None:
            raise ValueError('delivery="past" needs a snapshot() of the state to capture from')
        self.read = read
        self.schedule = SensorSchedule(rate_hz) if rate_hz is not None else None
        self.latency = float(latency)
        self.delivery: Delivery = delivery
        self.corrupt = corrupt
        self.rng = rng
        self.dropout = dropout
        self.dropout_first = dropout_first
        self.faults = faults if isinstance(faults, IntervalFault) else IntervalFault(faults)
        self.event_names = events
        self.lost_after = lost_after
        self.present = present
        self.events: list[str] = []
        self.emit: Callable[[str], None] = emit if emit is not None else self.events.append
        self.on_capture = on_capture
        self.on_deliver = on_deliver
        self.snapshot = snapshot
        self.poll_point: PollPoint = poll
        self.enabled = enabled
        self.restart(0.0)

    # -- lifecycle --------------------------------------------------------------------------------
    def restart(self, t0: float, rate_hz: float | None = None) -> None:
        """A new stream at ``t0`` (a reset, a sensor switched on): the schedule restarts, nothing is in
        flight, nothing delivered, never seen.  The rng is the caller's (re-seed it on reset)."""
        if self.schedule is not None:
            self.schedule.restart(t0, rate_hz)
        elif rate_hz is not None:
            self.schedule = SensorSchedule(rate_hz, t0)
        self.queue: list[Reading[V]] = []
        self._log: list[tuple[float, Any]] = []
        self.latest: Reading[V] | None = None
        self.last_present: Reading[V] | None = None
        self.last_seen: float | None = None
        self.visible = False
        self._was_present: bool | None = None
        self.new = False
        self.captured = 0
        self.delivered = 0
        self.presents = 0
        self.dropped = 0
        self.events.clear()

    def begin_advance(self) -> None:
        """Called by the stepping base before an ``advance``: ``new`` and the own event list start empty."""
        self.new = False
        self.events.clear()

    # -- the poll ---------------------------------------------------------------------------------
    def poll(self, t: float) -> None:
        """Capture if the schedule is due at ``t``, deliver what is due, check lost/found."""
        if not self.enabled:
            return
        if self.delivery == "past":
            assert self.snapshot is not None
            self._log.append((t, self.snapshot()))
            if self.schedule is None or self.schedule.poll(t):
                self._deliver(self._capture(*self._past(t)))
        else:
            if self.schedule is None or self.schedule.poll(t):
                self.queue.append(self._capture(t, None))
            if self.queue:
                self._deliver_due(t)
        if self.lost_after is not None and self.visible and self.last_seen is not None \
                and t - self.last_seen > self.lost_after + self.latency:
            self.visible = False
            if self.event_names is not None:
                self.emit(self.event_names[1])

    def _past(self, t: float) -> tuple[float, Any]:
        due = t - self.latency + EPS_T
        log = self._log
        while len(log) > 1 and log[1][0] <= due:
            log.pop(0)
        return log[0]

    def _capture(self, stamp: float, state: Any) -> Reading[V]:
        self.captured += 1
        value: V | None = None
        if self.faults.active(stamp) or self.dropout_first and self._dropped():
            pass
        else:
            value = self.read(stamp, state)
            if value is not None and not self.dropout_first and self._dropped():
                value = None
            elif value is not None and self.corrupt is not None:
                assert self.rng is not None
                value = self.corrupt(value, stamp, self.rng)
        reading = Reading(stamp, value)
        if self.on_capture is not None:
            self.on_capture(reading)
        return reading

    def _dropped(self) -> bool:
        if self.dropout is None:
            return False
        assert self.rng is not None
        if self.rng.random() < self.dropout:
            self.dropped += 1
            return True
        return False

    def _deliver_due(self, t: float) -> None:
        q, lat = self.queue, self.latency
        if self.delivery == "each":
            while q and q[0].stamp + lat <= t + EPS_T:
                self._deliver(q.pop(0))
            return
        n = 0
        while n < len(q) and q[n].stamp + lat <= t + EPS_T:
            n += 1
        if n:
            reading = q[n - 1]
            del q[:n]
            self._deliver(reading)

    def _deliver(self, reading: Reading[V]) -> None:
        self.latest = reading
        self.new = True
        self.delivered += 1
        value = reading.value
        is_present = value is not None and (self.present is None or self.present(value))
        if is_present:
            self.last_present = reading
            self.presents += 1
        if self.on_deliver is not None:
            self.on_deliver(reading)
        names = self.event_names
        if self.lost_after is not None:
            if is_present:
                self.last_seen = reading.stamp
                if not self.visible:
                    self.visible = True
                    if names is not None:
                        self.emit(names[0])
            return
        was = self._was_present
        if is_present != was and (was is not None or is_present):
            self.visible = is_present
            if names is not None:
                self.emit(names[0] if is_present else names[1])
        self._was_present = is_present
