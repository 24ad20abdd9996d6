"""Mission properties (``properties:``): parsed with the guard grammar's atoms, checked at load with
``FILE:LINE:COL`` like guards, compiled to :class:`taskflow.mission.properties.Property`."""

from __future__ import annotations

import pytest

from taskflow.errors import MissionError
from taskflow.mission.guards import GuardSyntaxError, parse_guard
from taskflow.mission.loader import load_mission_text
from taskflow.mission.properties import resolve_state
from taskflow.mission.schema import mission_json_schema

pytestmark = pytest.mark.machine

TOY = """\
mission: toy
robot: racecar
world: flat_ground
rate_hz: 20
events: [operator_ok]
parameters:
  far: 5 m
properties:
  p1:
    never: "state(move) and pos_error > $far"
    while: "event(operator_ok)"
    description: never far while the operator confirms
  p2: {always: "pos_error >= 0 m"}
  p3: {after: "event(operator_ok)", within: 100 ms, then: "state(done) or outcome(succeeded)"}
  p4: {only_after: "state(move)", occurs: "outcome(succeeded)"}
machine:
  initial: move
  states:
    move:
      task: {name: car_goto, params: {target: [1.0, 0.0]}}
      transitions: [{to: done, when: "pos_error < 1 cm"}, {to: done, on: operator_ok}]
    done: {final: succeeded}
"""


def problems(text: str) -> list[str]:
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "toy.yaml")
    return [str(p) for p in exc.value.problems]


def test_the_four_patterns_compile_with_their_atoms() -> None:
    m = load_mission_text(TOY, "toy.yaml")
    by = {p.name: p for p in m.properties}
    assert [p.pattern for p in m.properties] == ["absence", "universality", "response", "precedence"]
    assert [(a.kind, a.name) for a in by["p1"].atoms()] == [("state", "move"), ("metric", "pos_error"),
                                                           ("event", "operator_ok")]
    assert by["p1"].exprs["never"].comparisons()[0].value == 5.0  # $far bound in base units
    assert by["p1"].description == "never far while the operator confirms"
    assert by["p3"].within == pytest.approx(0.1)
    assert not by["p1"].structural and not by["p2"].structural
    assert by["p3"].structural and by["p4"].structural
    assert [a.kind for a in by["p4"].atoms()] == ["state", "outcome"]


def test_a_bare_state_name_resolves_to_its_path_and_an_ambiguous_one_is_refused() -> None:
    text = TOY.replace("""    done: {final: succeeded}
""", """    done: {final: succeeded}
    sub:
      initial: move
      transitions: [{to: done, done: true}]
      states:
        move: {task: {name: car_goto, params: {target: [0.0, 1.0]}}, transitions: [{to: fin, after: 1 s}]}
        fin: {final: succeeded}
""")
    text = text.replace('{to: done, on: operator_ok}]', '{to: done, on: operator_ok}, {to: sub, after: 5 s}]')
    m = load_mission_text(text.replace("state(move) and", "state(fin) and state(move) and"), "toy.yaml")
    assert m.properties[0].states == {"fin": "sub.fin", "move": "move"}  # a path first, else the one state so named
    assert ("state", "sub.fin") in [(a.kind, a.name) for a in m.properties[0].atoms()]
    m.states["sub.fin"].name = "move"  # two states called 'move' below the root, neither at path 'move'
    del m.states["move"]
    assert resolve_state(m.states, "move") == (None, "state(move) is ambiguous: sub.fin, sub.move — write the dotted path")


def test_load_errors_name_file_line_col_with_the_valid_choices() -> None:
    bad = (TOY.replace("state(done)", "state(dne)").replace('"event(operator_ok)"', '"event(operator_k)"')
           .replace("within: 100 ms", "within: 0.1").replace("pos_error >= 0 m", "pos_eror >= 0 m")
           .replace('occurs: "outcome(succeeded)"', 'occurs: "outcome(won)"'))
    assert problems(bad) == [
        "toy.yaml:11:5: property 'p1': while 'event(operator_k)': unknown event 'operator_k': no world, sensor, "
        "action or task of this mission emits it, nor does its `events:` list declare it — did you mean "
        "'operator_ok'? valid: operator_ok; `taskflow describe NAME` lists a world's or task's events",
        "toy.yaml:13:8: property 'p2': metric 'pos_eror' is published by no task or world of this mission — did you "
        "mean 'pos_error'? valid: heading_error, pos_error, speed; `taskflow describe TASK` lists a task's metrics",
        "toy.yaml:14:8: property 'p3': after 'event(operator_k)': unknown event 'operator_k': no world, sensor, action "
        "or task of this mission emits it, nor does its `events:` list declare it — did you mean 'operator_ok'? valid: "
        "operator_ok; `taskflow describe NAME` lists a world's or task's events",
        "toy.yaml:14:36: property 'p3': within 0.1 needs a time unit — write e.g. '0.1 s' or '0.1 ms'",
        "toy.yaml:14:49: property 'p3': then 'state(dne) or outcome(succeeded)': unknown state 'dne' — did you mean "
        "'done'? valid: done, move",
        "toy.yaml:15:35: property 'p4': occurs 'outcome(won)': unknown outcome 'won' — valid: aborted, failed, "
        "succeeded, timeout",
    ]


def test_wrong_units_and_a_within_that_is_no_time() -> None:
    out = problems(TOY.replace("pos_error >= 0 m", "pos_error >= 0 deg").replace("within: 100 ms", "within: 2 m"))
    assert out == [
        "toy.yaml:13:8: property 'p2': always 'pos_error >= 0 deg': '0 deg' is an angle, but pos_error is a length — "
        "use a length unit such as 'm'",
        "toy.yaml:14:37: property 'p3': within: '2 m' is a length, expected a time (e.g. 's') — write a time such as "
        "'0.05 s' or '50 ms'",
    ]


def test_unknown_keys_and_mixed_patterns_are_refused() -> None:
    assert problems(TOY.replace("  p2: {always:", "  p2: {alway:")) == [
        "toy.yaml:13:8: unknown key 'alway' — did you mean 'always'? valid: after, always, description, never, occurs, "
        "only_after, then, while, within"]
    out = problems(TOY.replace("  p2: {always:", '  p2: {never: "pos_error > 1 m", always:'))
    assert out == ["toy.yaml:13:3: a property in the form 'never': 'always' does not belong to it — one pattern per "
                   "property: never [+ while] | always | after + within + then | only_after + occurs"]
    out = problems(TOY.replace("within: 100 ms, ", ""))
    assert out == ["toy.yaml:14:3: a property in the form 'after': missing 'within' — one pattern per property: "
                   "never [+ while] | always | after + within + then | only_after + occurs"]


def test_a_transition_guard_refuses_the_property_atoms() -> None:
    out = problems(TOY.replace('when: "pos_error < 1 cm"', 'when: "state(move)"'))
    assert out == ["toy.yaml:21:32: guard 'state(move)': state( ) is an atom of a mission property, not of a "
                   "transition's guard (at character 1) — a guard compares metrics (e.g. 'pos_error < 1 cm'); use "
                   "`on: EVENT` for an event"]
    with pytest.raises(GuardSyntaxError):
        parse_guard("event(x)")
    assert parse_guard("not (event(x) or state(a.b)) and y > 1", atoms=True).atoms()[1].name == "a.b"


def test_the_json_schema_knows_the_block() -> None:
    schema = mission_json_schema()
    assert "properties" in schema["properties"]
    prop = schema["$defs"]["Property"]
    assert {"never", "while", "always", "after", "within", "then", "only_after", "occurs"} <= set(prop["properties"])
    assert prop["additionalProperties"] is False
