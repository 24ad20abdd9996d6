"""The screwdriver of ``screw_conveyor`` as a small state machine, and its operation log.

Phases (:class:`Phase`)::

    IDLE --activate--> ACTIVATING --(end, bit stayed on the bolt)--> IDLE, coupled   event tool_activated
                                  --(end, off the bolt or no bolt)-> IDLE            event tool_failed
    IDLE --fasten (coupled)--> FASTENING --(end)------------------> IDLE, fastened   event screw_done
                                         --(bit slipped)----------> IDLE             event tool_failed
    IDLE --fasten (not coupled)--> FASTENING, failed -------------> IDLE (next tick) event tool_failed
    ACTIVATING / FASTENING --cancel--> IDLE  (a fastening that was on its bolt stays coupled: interrupted)

Every activation, and every fastening with nothing coupled, opens an :class:`Operation` in the
:class:`OperationLog`; a fastening of the coupled bolt continues the operation that coupled it.  The
machine sees the world only through numbers handed in (simulation time, the bit's errors to a bolt):
no simulator, so it is tested on its own (``tests/unit/sim/test_screwdriver.py``).  Outcome and failure
names are those of the summary's ``operation_log`` (module docstring of :mod:`taskflow_sim.screw.world`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from taskflow_robots.mobile_iiwa import ToolParams

EPS_T = 1e-9  # a phase ends on the first tick at or after its end time, within this (s)


class Phase(Enum):
    IDLE = "idle"
    ACTIVATING = "activate"
    FASTENING = "fasten"


@dataclass(frozen=True)
class BitErrors:
    """The bit's tip to one bolt's frame (m, rad, ground truth): distance, rotation angle, lateral offset
    from the bolt's axis, axial offset along it, tilt of the bit's axis against the bolt's."""

    translation: float
    rotation: float
    lateral: float
    axial: float
    tilt: float


@dataclass
class Operation:
    """One screwdriver operation: what the summary's ``operation_log`` records (fields in its key order),
    and the bit's error samples to its bolt."""

    operation: int
    bolt: int | None
    nearest_bolt: int
    nearest_bolt_mm: float
    bolt_already_fastened: bool
    t_start: float
    t_end: float | None = None
    outcome: str = "activating"
    failure: str | None = None
    coupling_error_mm: float | None = None
    screwing_s: float | None = None  # recorded once fastened
    err_t: list[float] = field(default_factory=list)  # tip → bolt distance per sample (m)
    err_r: list[float] = field(default_factory=list)  # tip → bolt rotation per sample (rad)

    def end(self, outcome: str, t: float, failure: str | None = None) -> None:
        self.outcome, self.t_end = outcome, t
        if failure is not None:
            self.failure = failure

    def record(self) -> dict[str, Any]:
        """The log entry without the samples (``screwing_s`` only once fastened)."""
        rec: dict[str, Any] = {
            "operation": self.operation, "bolt": self.bolt, "nearest_bolt": self.nearest_bolt,
            "nearest_bolt_mm": self.nearest_bolt_mm, "bolt_already_fastened": self.bolt_already_fastened,
            "t_start": self.t_start, "t_end": self.t_end, "outcome": self.outcome, "failure": self.failure,
            "coupling_error_mm": self.coupling_error_mm}
        if self.screwing_s is not None:
            rec["screwing_s"] = self.screwing_s
        return rec


@dataclass
class OperationLog:
    """The operations in order and the distinct bolts fastened."""

    ops: list[Operation] = field(default_factory=list)
    bolts_done: set[int] = field(default_factory=set)

    def open(self, t: float, nearest: int, dist: float, bolt: int | None, outcome: str) -> Operation:
        op = Operation(len(self.ops), bolt, nearest, 1e3 * dist, bolt is not None and bolt in self.bolts_done,
                       t, outcome=outcome)
        self.ops.append(op)
        return op


@dataclass
class Screwdriver:
    """The phase, the running operation with its end time and verdict so far, and the coupled bolt."""

    tool: ToolParams
    log: OperationLog = field(default_factory=OperationLog)
    phase: Phase = Phase.IDLE
    op: Operation | None = None
    end_t: float = 0.0
    ok: bool = False  # the bit is where the phase needs it (so far)
    failure: str | None = None  # why not: no_bolt, coupling, slipped, not_coupled
    worst_lateral: float = 0.0  # largest lateral error during this activation (m)
    coupled: int | None = None  # the bolt the bit is coupled to

    @property
    def running(self) -> bool:
        return self.phase is not Phase.IDLE

    @property
    def bolt(self) -> int | None:
        """The running operation's bolt (None when idle or without a bolt)."""
        return self.op.bolt if self.op is not None and self.running else None

    def on_bolt(self, e: BitErrors) -> bool:
        """Within the coupling tolerances (lateral, axial, tilt)."""
        tp = self.tool
        return e.lateral <= tp.tol_t and abs(e.axial) <= tp.tol_axial and e.tilt <= tp.tol_r

    def activate(self, t: float, duration: float, nearest: int, e: BitErrors) -> None:
        """Start an activation at the bolt ``nearest`` when the bit is on it (errors ``e``), else one that fails."""
        on_bolt = self.on_bolt(e)
        self.coupled = None
        op = self.log.open(t, nearest, e.translation, nearest if on_bolt else None, "activating")
        self._start(Phase.ACTIVATING, op, t + duration, on_bolt, None if on_bolt else "no_bolt")

    def can_continue(self) -> bool:
        """Whether a fastening would continue the last operation: its bolt is coupled and it was not
        fastened or failed since."""
        last = self.log.ops[-1] if self.log.ops else None
        return (self.coupled is not None and last is not None and last.bolt == self.coupled
                and last.outcome in ("coupled", "interrupted"))

    def fasten_coupled(self, t: float, duration: float) -> None:
        """Fasten the coupled bolt, continuing its operation (:meth:`can_continue` must hold)."""
        op = self.log.ops[-1]
        op.outcome = "fastening"
        self._start(Phase.FASTENING, op, t + duration, True, None)

    def fasten_uncoupled(self, t: float, duration: float, nearest: int, dist: float) -> None:
        """A fastening with nothing coupled: an operation of its own that fails at the next update."""
        op = self.log.open(t, nearest, dist, None, "fastening")
        self._start(Phase.FASTENING, op, t + duration, False, "not_coupled")

    def _start(self, phase: Phase, op: Operation, end_t: float, ok: bool, failure: str | None) -> None:
        self.phase, self.op, self.end_t, self.ok, self.failure, self.worst_lateral = phase, op, end_t, ok, failure, 0.0

    def _stop(self) -> Operation:
        op = self.op
        assert op is not None  # internal invariant: a running phase has its operation
        self.phase, self.op = Phase.IDLE, None
        return op

    def cancel(self, t: float) -> None:
        """Stop the running phase: an activation ends its operation (``cancelled``); a fastening on its
        bolt leaves it ``interrupted`` and coupled (the next fasten continues it)."""
        if not self.running:
            return
        phase, ok, op = self.phase, self.ok, self._stop()
        if phase is Phase.ACTIVATING:
            self.coupled = None
            if op.bolt is not None:
                op.coupling_error_mm = 1e3 * self.worst_lateral
            op.end("cancelled", t)
        elif ok:
            op.outcome = "interrupted"
        else:
            op.end("cancelled", t)

    def sample(self, e: BitErrors) -> None:
        """One control tick's errors of the bit to the operation's bolt: logged, and checked against
        the coupling tolerances (activating) or the slip limit (fastening)."""
        op = self.op
        if not self.running or op is None or op.bolt is None:
            return
        tp = self.tool
        op.err_t.append(e.translation)
        op.err_r.append(e.rotation)
        if self.phase is Phase.ACTIVATING:
            self.worst_lateral = max(self.worst_lateral, e.lateral)
            if self.ok and not self.on_bolt(e):
                self.ok, self.failure = False, "coupling"
        elif self.ok and (e.lateral > tp.slip_t or abs(e.axial) > 2.0 * tp.tol_axial):
            self.ok, self.failure = False, "slipped"

    def update(self, t: float) -> str | None:
        """End the phase if it is over at ``t``; the end event (``tool_activated``, ``tool_failed``,
        ``screw_done``) or None."""
        if not self.running:
            return None
        if self.phase is Phase.ACTIVATING:
            if t + EPS_T < self.end_t:
                return None
            op = self._stop()
            if op.bolt is not None:
                op.coupling_error_mm = 1e3 * self.worst_lateral
            if self.ok:
                self.coupled = op.bolt
                op.outcome = "coupled"
                return "tool_activated"
            self.coupled = None
            op.end("failed", t, self.failure)
            return "tool_failed"
        if not self.ok:
            op = self._stop()
            self.coupled = None
            op.end("failed", t, self.failure)
            return "tool_failed"
        if t + EPS_T >= self.end_t:
            op = self._stop()
            self.coupled = None
            assert op.bolt is not None  # ok while fastening implies a coupled bolt
            self.log.bolts_done.add(op.bolt)
            op.end("fastened", t)
            op.screwing_s = t - op.t_start
            return "screw_done"
        return None
