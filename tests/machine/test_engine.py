"""The engine (`taskflow/execution/engine.py`): `transitions`' HierarchicalMachine holds the active state and runs every
exit and entry, for the configurations missions need — transitions into a composite's own descendants,
history into nested states, the next item of a foreach — and the library alone would get them wrong.
The library members it relies on beyond its documented hooks: test_transitions_contract.py."""

from __future__ import annotations

from transitions.extensions.nesting import HierarchicalMachine

from taskflow.execution.engine import MissionMachine
from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, assert_outcome, drive

HEAD = """
mission: m
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 60 s
"""

RETRY = HEAD + """
machine:
  initial: approach
  states:
    approach:
      initial: far
      transitions: [{to: approach.far, on: target_lost}, {to: done, done: true}]
      states:
        far: {transitions: [{to: near, after: 1 s}]}
        near: {transitions: [{to: ok, after: 1 s}]}
        ok: {final: succeeded}
    done: {final: succeeded}
"""


def _log(machine: MissionMachine) -> list[str]:
    log: list[str] = []
    for path, st in machine.by_path.items():
        st.on_enter.append(lambda p=path: log.append(f"+{p}"))
        st.on_exit.append(lambda p=path: log.append(f"-{p}"))
    return log


def test_a_transition_declared_on_a_composite_into_its_own_child_leaves_and_reenters_it() -> None:
    m = load_mission_text(RETRY, "r.yaml")
    machine = MissionMachine(m, lambda n: None, lambda n: None)
    log = _log(machine)
    machine.go("approach.far", 0)
    machine.go("approach.near", 1)  # sibling step: `approach` stays active
    assert log == ["+approach", "+approach.far", "-approach.far", "+approach.near"]
    log.clear()
    retry = next(t for t in m.states["approach"].transitions if t.label == "on target_lost")
    assert retry.domain is m.root and retry.domain_depth == 0  # external: the composite is left and re-entered
    machine.go("approach.far", retry.domain_depth)
    assert log == ["-approach.near", "-approach", "+approach", "+approach.far"]
    assert machine.mission_model.state == "approach.far"

    # the library alone keeps the shared `approach` active: that is what the extension is for
    plain = HierarchicalMachine(states=[{"name": "approach", "initial": "far", "children": ["far", "near"]}],
                                initial="approach")
    seen: list[str] = []
    plain.on_enter_approach(lambda: seen.append("+approach"))
    plain.on_exit_approach(lambda: seen.append("-approach"))
    plain.to_approach_near()
    plain.to_approach_far()
    assert seen == []


def test_the_active_leaf_and_its_clocks_live_in_the_engine() -> None:
    m = load_mission_text(RETRY, "r.yaml")
    r = drive(m, Script(events=[(1.5, "target_lost")]))
    ex = r.executor
    assert_outcome(r, "succeeded")
    assert ex.state == ex.engine.mission_model.state == "done"
    # lost at 1.5 s (in `near`): `approach` re-entered at 1.5 s, far → near at 2.5 s, ok at 3.5 s
    assert [(rec.target, round(rec.t, 6)) for rec in ex.transitions_fired] == [
        ("approach.far", 0.0), ("approach.near", 1.0), ("approach.far", 1.5), ("approach.near", 2.5),
        ("approach.ok", 3.5), ("done", 3.5)]
    assert ex.entered_at(m.states["approach"]) == 1.5


def test_history_resumes_a_leaf_two_levels_down_and_reenters_every_level() -> None:
    m = load_mission_text(HEAD + """
machine:
  initial: job
  states:
    job:
      history: true
      initial: a
      transitions: [{to: pause, on: target_lost}, {to: done, done: true}]
      states:
        a: {transitions: [{to: b, after: 1 s}]}
        b:
          initial: b1
          transitions: [{to: fin, done: true}]
          states:
            b1: {transitions: [{to: b2, after: 1 s}]}
            b2: {transitions: [{to: b3, after: 2 s}]}
            b3: {final: succeeded}
        fin: {final: succeeded}
    pause: {transitions: [{to: job, after: 1 s}]}
    done: {final: succeeded}
""", "h.yaml")
    r = drive(m, Script(events=[(2.5, "target_lost")]))
    ex = r.executor
    assert_outcome(r, "succeeded")
    targets = [(rec.target, round(rec.t, 6), rec.resumed) for rec in ex.transitions_fired]
    assert targets[:6] == [("job.a", 0.0, False), ("job.b.b1", 1.0, False), ("job.b.b2", 2.0, False),
                           ("pause", 2.5, False), ("job.b.b2", 3.5, True), ("job.b.b3", 5.5, False)]
    assert ex.history == {"job": "job.fin"}  # left for `done` from its final leaf
    assert ex.entered_at(m.states["job.b"]) == 3.5  # every level on the way down was entered again


def test_the_next_foreach_item_reenters_the_items_states_but_not_the_loop() -> None:
    m = load_mission_text(HEAD + """
parameters: {xs: [1, 2, 3]}
machine:
  initial: loop
  states:
    loop:
      foreach: {in: xs, as: x}
      initial: work
      transitions: [{to: done, done: succeeded}]
      states:
        work: {transitions: [{to: ok, after: 1 s}]}
        ok: {final: succeeded}
    done: {final: succeeded}
""", "f.yaml")
    r = drive(m, Script())
    ex = r.executor
    assert_outcome(r, "succeeded")
    assert ex.entered_at(m.states["loop"]) == 0.0  # entered once: its clock runs across items
    assert [rec.cause for rec in ex.transitions_fired] == ["start", "timeout", "next_item", "timeout", "next_item",
                                                          "timeout", "done"]
    assert ex.iteration == {"loop": 2}

