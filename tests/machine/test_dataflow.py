"""Declared mission data: tasks declare the keys they write and read; the loader checks that every key a
state reads is written on every path into it (or has a default), guards read ``data.<key>``, task
parameters take ``$data.<key>``, an undeclared write stops the run with the task and key named, and the
summary lists the final values as ``outputs``.  Toys: ``toy_mark`` writes ``toy.mark`` (where the point
stands), ``toy_return`` reads it, ``toy_goto`` records its targets in ``toy.entries``."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from toys import MARK, ToyReturn

from taskflow.api import Observation, StepResult, Task
from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.data import DataAccess, DataAccessError
from taskflow.mission.loader import load_mission_text
from taskflow.registry import TASKS
from taskflow.testing import assert_outcome, assert_path

HEAD = """\
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.3, lose_at: %s}}
rate_hz: 20
max_time: 20 s
"""

# choose → back skips `mark`, the only writer of toy.mark: toy_return's read is not written on that path
SKIPS_THE_WRITER = HEAD % "[]" + """\
%s
machine:
  initial: choose
  states:
    choose:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: {kp: 2.0}}
      transitions:
        - {to: mark, on: target_lost}
        - {to: back, when: "pos_error < 1 cm"}
    mark:
      task: toy_mark
      transitions: [{to: back, after: 0.2 s}]
    back:
      task: toy_return
      bind: {gains: {kp: 2.0}}
      transitions: [{to: done, when: "pos_error < 1 cm"}]
    done: {final: succeeded}
"""

# mark (at x = 0.3) → away to 1.0 → home to the mark, through a $data parameter, guarded on the data
ROUND_TRIP = HEAD % "[]" + """\
machine:
  initial: mark
  states:
    mark:
      task: toy_mark
      transitions: [{to: away, when: "data.toy.mark > 20 cm"}]
    away:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: {kp: 2.0}}
      transitions: [{to: home, when: "pos_error < 1 cm"}]
    home:
      task: {name: toy_goto, params: {target: $data.toy.mark}}
      bind: {gains: {kp: 2.0}}
      transitions: [{to: done, when: "pos_error < 1 cm"}]
    done: {final: succeeded}
"""


def _starting_away(guard: str = "pos_error < 1 cm") -> str:
    """ROUND_TRIP entered at `away` (`mark` only after a lost target): no toy.mark on the way to `home`."""
    return ROUND_TRIP.replace("initial: mark", "initial: away").replace(
        'transitions: [{to: home, when: "pos_error < 1 cm"}]',
        f'transitions: [{{to: home, when: "{guard}"}}, {{to: mark, on: target_lost}}]')


def _problem(text: str) -> str:
    with pytest.raises(MissionError) as info:
        load_mission_text(text, "m.yaml")
    return str(info.value)


# -- the must-be-written analysis ----------------------------------------------------------------------

def test_a_read_not_written_on_some_path_is_a_load_error_at_the_reading_task() -> None:
    msg = _problem(SKIPS_THE_WRITER % "")
    # at the reading state's task (line 20, `task: toy_return`), naming the path that skips the writer
    assert "m.yaml:20:7: task 'toy_return' of state 'back' reads mission data 'toy.mark', which is not written " \
           "on every path into state 'back': not on (start) → choose → back" in msg, msg
    assert "written by toy_mark" in msg and "`data:`" in msg


def test_a_default_in_the_mission_makes_it_load_and_the_reader_gets_it() -> None:
    m = load_mission_text(SKIPS_THE_WRITER % "data: {toy.mark: 0.5}", "m.yaml")
    r = run_mission(m, record=False)
    assert_outcome(r, "succeeded")
    assert_path(r, ["choose", "back", "done"])
    assert r.executor.world.x == pytest.approx(0.5, abs=0.01)  # type: ignore[attr-defined]
    assert r.summary["outputs"]["toy.mark"] == 0.5  # the default, never overwritten


def test_when_every_path_passes_a_writer_the_mission_loads() -> None:
    # the only way into `back` is now through `mark`
    load_mission_text((SKIPS_THE_WRITER % "").replace('- {to: back, when: "pos_error < 1 cm"}',
                                                        '- {to: mark, when: "pos_error < 1 cm"}'), "m.yaml")


def test_a_cycle_back_to_the_reader_does_not_hide_the_first_pass() -> None:
    # back → mark → back would be fine, but the first entry of `back` comes straight from the start
    text = """\
machine:
  initial: back
  states:
    back:
      task: toy_return
      bind: {gains: {kp: 2.0}}
      transitions: [{to: mark, after: 1 s}]
    mark:
      task: toy_mark
      transitions: [{to: back, after: 1 s}, {to: done, after: 3 s, since: first_entry}]
    done: {final: succeeded}
"""
    assert "not on (start) → back" in _problem(HEAD % "[]" + text)


def test_a_history_resume_may_enter_any_leaf_and_sees_what_was_written_before_it_left() -> None:
    # `work` is left from `work.use` (lost target) and resumed there: the resume edge comes from `pause`,
    # which is entered only after `work.fill` wrote the mark — the mission loads and `use` finds the mark
    text = """\
machine:
  initial: work
  states:
    work:
      initial: fill
      history: true
      states:
        fill:
          task: toy_mark
          transitions: [{to: use, after: 0.5 s}]
        use:
          task: toy_return
          bind: {gains: {kp: 2.0}}
          transitions: [{to: finished, when: "pos_error < 1 cm", for: 0.5 s}]
        finished: {final: succeeded}
      transitions: [{to: pause, on: target_lost}, {to: done, done: true}]
    pause:
      task: {name: toy_goto, params: {target: 1.0}}
      bind: {gains: {kp: 2.0}}
      transitions: [{to: work, after: 1 s}]
    done: {final: succeeded}
"""
    r = run_mission(load_mission_text(HEAD % "[0.6]" + text, "m.yaml"), record=False)
    assert_outcome(r, "succeeded")
    assert_path(r, ["work.fill", "work.use", "pause", "work.use", "work.finished", "done"])
    assert r.executor.world.x == pytest.approx(0.3, abs=0.01)  # type: ignore[union-attr]


# -- mission `data:` defaults ----------------------------------------------------------------------------

def test_a_default_for_an_unknown_key_or_of_the_wrong_type_is_refused() -> None:
    msg = _problem(SKIPS_THE_WRITER % "data: {toy.marc: 0.5}")
    assert "no task of this mission declares mission data 'toy.marc'" in msg and "did you mean 'toy.mark'" in msg
    msg = _problem(SKIPS_THE_WRITER % "data: {toy.mark: [1, 2]}")
    assert "mission data 'toy.mark'" in msg and "it takes scalar" in msg
    assert "only a task can write" in _problem(SKIPS_THE_WRITER % "data: {toy.robot_params: {v_max: 1}}")


# -- guards and $data parameters ---------------------------------------------------------------------------

def test_a_guard_reads_data_and_a_parameter_takes_it_on_entry() -> None:
    r = run_mission(load_mission_text(ROUND_TRIP, "m.yaml"), record=False)
    assert_outcome(r, "succeeded")
    assert_path(r, ["mark", "away", "home", "done"])
    # the guard held at the first tick (the mark is written by the step before the guards are checked)
    assert r.summary["time_in_state_s"]["mark"] == 0.0
    assert r.summary["outputs"]["toy.entries"] == [1.0, pytest.approx(0.3)]  # home's target came from the mark
    assert r.executor.world.x == pytest.approx(0.3, abs=0.01)  # type: ignore[attr-defined]


def test_a_guard_on_an_unknown_key_or_in_the_wrong_unit_is_a_load_error() -> None:
    msg = _problem(ROUND_TRIP.replace("data.toy.mark > 20 cm", "data.toy.marc > 20 cm"))
    assert "'data.toy.marc' is not mission data a guard can read" in msg and "did you mean 'data.toy.mark'" in msg
    msg = _problem(ROUND_TRIP.replace("data.toy.mark > 20 cm", "data.toy.entries > 20 cm"))
    assert "'toy.entries' holds sequence; guards read scalar, flag and fixed-length 1-D array keys only" in msg
    msg = _problem(ROUND_TRIP.replace("data.toy.mark > 20 cm", "data.toy.mark > 20 deg"))
    assert "data.toy.mark is a length" in msg


def test_a_guard_reading_data_not_yet_written_is_a_load_error() -> None:
    # `away` compares the mark, but nothing before it (nor its own task) writes it
    text = _starting_away("pos_error < 1 cm and data.toy.mark < 1 m")
    assert "the guard 'pos_error < 1 cm and data.toy.mark < 1 m' of state 'away' reads mission data 'toy.mark'" \
           in _problem(text)


def test_a_data_parameter_needs_the_key_written_before_its_state() -> None:
    msg = _problem(_starting_away())
    assert "(parameter $data.toy.mark) reads mission data 'toy.mark'" in msg and "not on (start) → away → home" in msg
    msg = _problem(ROUND_TRIP.replace("$data.toy.mark", "$data.toy.marc"))
    assert "unknown reference $data.toy.marc" in msg and "'$data.toy.mark'" in msg


# -- access at run time ------------------------------------------------------------------------------------

class _Sneak(Task):
    """Writes toy.mark without declaring it."""

    def step(self, obs: Observation) -> StepResult:
        MARK.set(self.ctx.memory, 1.0)
        return StepResult({"v": np.zeros(1)})


def test_an_undeclared_write_stops_the_run_naming_the_task_and_the_key(register) -> None:
    register(TASKS, "toy_sneak", _Sneak)  # for this test only (tests/conftest.py)
    text = HEAD % "[]" + """\
machine:
  initial: sneak
  states:
    sneak:
      task: toy_sneak
      transitions: [{to: done, after: 1 s}]
    done: {final: succeeded}
"""
    r = run_mission(load_mission_text(text, "m.yaml"), record=False)
    assert r.outcome == "aborted"
    assert "task 'toy_sneak' writes mission data 'toy.mark', which it does not declare" in r.summary["reason"]


def test_a_view_refuses_undeclared_reads_and_values_of_the_wrong_type() -> None:
    values: dict[str, Any] = {"toy.mark": 0.5, "toy.entries": [1.0]}
    view = DataAccess(values, ToyReturn)
    assert MARK(view) == 0.5
    with pytest.raises(DataAccessError, match="task 'toy_return' reads mission data 'toy.entries'"):
        view["toy.entries"]
    with pytest.raises(DataAccessError, match="task 'toy_return' writes mission data 'toy.mark'"):
        MARK.set(view, 1.0)
    writer = DataAccess(values, TASKS.get("toy_mark"))
    with pytest.raises(DataAccessError, match="writes mission data 'toy.mark' a value that is str"):
        writer["toy.mark"] = "far"


def test_outputs_list_the_final_values_of_output_keys_in_json_form() -> None:
    r = run_mission(load_mission_text(ROUND_TRIP, "m.yaml"), record=False)
    out = r.summary["outputs"]
    assert set(out) == {"toy.entries", "toy.mark"}  # toy.robot_params is declared output=False
    assert isinstance(out["toy.mark"], float) and out["toy.mark"] == pytest.approx(0.3, abs=0.01)
