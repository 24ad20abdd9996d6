"""The screwdriver state machine (sim/screw/screwdriver.py) on its own: phases, events, operation records."""

from __future__ import annotations

import pytest
from taskflow_robots.mobile_iiwa import ToolParams
from taskflow_sim.screw.screwdriver import BitErrors, Phase, Screwdriver

TOOL = ToolParams()  # tol_t 3 mm, tol_axial 3 mm, tol_r 3 deg, slip_t 5 mm
ON = BitErrors(translation=0.001, rotation=0.01, lateral=0.001, axial=0.0005, tilt=0.01)
OFF = BitErrors(translation=0.02, rotation=0.01, lateral=0.02, axial=0.0, tilt=0.01)
LOOSE = BitErrors(translation=0.004, rotation=0.01, lateral=0.004, axial=0.0, tilt=0.01)  # coupling no, slip no
SLIP = BitErrors(translation=0.006, rotation=0.01, lateral=0.006, axial=0.0, tilt=0.01)


def activated(bolt: int = 2) -> Screwdriver:
    sd = Screwdriver(TOOL)
    sd.activate(0.0, 1.0, bolt, ON)
    sd.sample(ON)
    assert sd.update(1.0) == "tool_activated"
    return sd


def test_activation_on_a_bolt_couples_it_at_its_end_time():
    sd = Screwdriver(TOOL)
    sd.activate(0.0, 1.0, 2, ON)
    assert sd.phase is Phase.ACTIVATING and sd.bolt == 2
    sd.sample(ON)
    assert sd.update(0.5) is None and sd.running
    assert sd.update(1.0 - 1e-10) == "tool_activated"  # within the tick slack
    assert sd.phase is Phase.IDLE and sd.coupled == 2
    op = sd.log.ops[0]
    assert (op.outcome, op.bolt, op.failure, op.t_end) == ("coupled", 2, None, None)
    assert op.coupling_error_mm == pytest.approx(1.0) and op.err_t == [0.001]


def test_activation_off_every_bolt_fails_no_bolt_and_records_no_samples():
    sd = Screwdriver(TOOL)
    sd.activate(0.0, 1.0, 3, OFF)
    sd.sample(OFF)
    assert sd.bolt is None and sd.update(1.0) == "tool_failed"
    op = sd.log.ops[0]
    assert (op.outcome, op.failure, op.bolt, op.nearest_bolt, op.t_end) == ("failed", "no_bolt", None, 3, 1.0)
    assert op.nearest_bolt_mm == pytest.approx(20.0) and op.err_t == [] and op.coupling_error_mm is None


def test_leaving_the_tolerances_while_activating_fails_coupling_at_the_end():
    sd = Screwdriver(TOOL)
    sd.activate(0.0, 1.0, 1, ON)
    sd.sample(LOOSE)
    sd.sample(ON)
    assert sd.update(0.9) is None  # an activation ends at its end time, whatever happened
    assert sd.update(1.0) == "tool_failed" and sd.coupled is None
    op = sd.log.ops[0]
    assert (op.outcome, op.failure) == ("failed", "coupling") and op.coupling_error_mm == pytest.approx(4.0)


def test_fastening_the_coupled_bolt_continues_its_operation_until_screw_done():
    sd = activated()
    assert sd.can_continue()
    sd.fasten_coupled(1.0, 3.0)
    sd.sample(LOOSE)  # within slip_t
    assert sd.phase is Phase.FASTENING and sd.update(2.0) is None
    assert sd.update(4.0) == "screw_done"
    assert len(sd.log.ops) == 1 and sd.log.bolts_done == {2} and sd.coupled is None
    rec = sd.log.ops[0].record()
    assert list(rec)[-2:] == ["coupling_error_mm", "screwing_s"]
    assert (rec["outcome"], rec["t_end"], rec["screwing_s"]) == ("fastened", 4.0, 4.0)


def test_a_slipping_bit_fails_at_once():
    sd = activated()
    sd.fasten_coupled(1.0, 3.0)
    sd.sample(SLIP)
    assert sd.update(1.01) == "tool_failed"
    assert (sd.log.ops[0].outcome, sd.log.ops[0].failure) == ("failed", "slipped") and not sd.can_continue()


def test_fastening_with_nothing_coupled_is_an_operation_that_fails_at_the_next_update():
    sd = Screwdriver(TOOL)
    assert not sd.can_continue()
    sd.fasten_uncoupled(0.0, 3.0, 1, 0.05)
    assert sd.phase is Phase.FASTENING and sd.update(0.01) == "tool_failed"
    op = sd.log.ops[0]
    assert (op.outcome, op.failure, op.bolt, op.nearest_bolt_mm) == ("failed", "not_coupled", None, pytest.approx(50.0))
    assert "screwing_s" not in op.record()


def test_cancelling_a_fastening_interrupts_it_and_the_next_fasten_resumes():
    sd = activated()
    sd.fasten_coupled(1.0, 3.0)
    sd.cancel(2.0)
    assert sd.phase is Phase.IDLE and sd.log.ops[0].outcome == "interrupted" and sd.coupled == 2
    assert sd.can_continue()
    sd.fasten_coupled(5.0, 1.0)
    assert sd.update(6.0) == "screw_done" and sd.log.ops[0].screwing_s == 6.0


def test_cancelling_an_activation_ends_its_operation_and_a_second_fastened_bolt_is_marked():
    sd = Screwdriver(TOOL)
    sd.activate(0.0, 1.0, 0, ON)
    sd.sample(LOOSE)
    sd.cancel(0.5)
    op = sd.log.ops[0]
    assert (op.outcome, op.t_end, op.coupling_error_mm) == ("cancelled", 0.5, pytest.approx(4.0)) and sd.coupled is None
    sd.cancel(0.6)  # idle: nothing happens
    assert sd.update(0.7) is None and len(sd.log.ops) == 1
    sd = activated(bolt=1)
    sd.fasten_coupled(1.0, 1.0)
    sd.update(2.0)
    sd.activate(3.0, 1.0, 1, ON)
    assert sd.log.ops[-1].bolt_already_fastened
