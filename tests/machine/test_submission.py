"""Sub-missions (``use:`` + ``with:``, :mod:`taskflow.mission.submission`) on the toy robot, world and task: the used
machine runs with the remapped parameters, its problems are reported in its own file with where it was used
from, cycles are refused, and graphs draw it as a cluster."""

from __future__ import annotations

from pathlib import Path

import pytest

from taskflow.catalogue.graph import to_dot, to_mermaid
from taskflow.errors import MissionError
from taskflow.execution.runtime import run_mission
from taskflow.mission.loader import load_mission
from taskflow.testing import Script, assert_outcome, assert_path, drive

HEAD = """\
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
"""

# a reusable "go to a target, then visit each via point" machine (line numbers matter to the tests)
GOTO = """\
submission: goto_and_visit
description: go to $target, then to each of $vias
parameters:
  target: ~
  reach: 1 cm
  vias: [0.25]
profiles:
  gains: {soft: {kp: 2.0}}
machine:
  bind: {gains: soft}
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: $target}}
      transitions: [{to: vias, when: "pos_error < $reach"}]
    vias:
      foreach: {in: vias, as: via}
      initial: step
      transitions: [{to: arrived, done: true}]
      states:
        step:
          task: {name: toy_goto, params: {target: $via}}
          transitions: [{to: ok, when: "pos_error < $reach"}]
        ok: {final: succeeded}
    arrived: {final: succeeded}
"""


def write(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return tmp_path / "m.yaml"


def problems(path: Path) -> list[str]:
    with pytest.raises(MissionError) as exc:
        load_mission(path)
    return [str(p) for p in exc.value.problems]


MAIN = HEAD + """\
parameters:
  spots: [1.0, 0.5]
  tol: 2 cm
machine:
  initial: pick
  states:
    pick:
      foreach: {in: spots, as: spot}
      use: lib/goto.yaml
      with: {target: $spot, reach: $tol}
      transitions: [{to: fin, done: true}]
    fin: {final: succeeded}
"""


def test_the_used_machine_runs_with_the_remapped_parameters_and_its_defaults(tmp_path: Path) -> None:
    m = load_mission(write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": GOTO}))
    assert list(m.states) == ["pick", "pick.go", "pick.vias", "pick.vias.step", "pick.vias.ok", "pick.arrived", "fin"]
    r = run_mission(m, record=False)  # the real toy world and task
    assert_outcome(r, "succeeded")
    # $target ← the outer loop's $spot; $vias ← its default [0.25], once per spot
    assert r.executor.memory["toy.entries"] == [1.0, 0.25, 0.5, 0.25]
    # $reach ← $tol (2 cm): the guard reads the outer parameter, as written in the label
    labels = {(t.source.path, t.label) for t in m.transitions}
    assert ("pick.go", "pos_error < $tol") in labels
    # the used file's profile joined the mission's and its machine-level bind reached the leaves
    assert m.states["pick.go"].profiles["gains"].kp == 2.0  # type: ignore[attr-defined]


def test_a_value_given_at_the_point_of_use_overrides_the_default(tmp_path: Path) -> None:
    main = MAIN.replace("reach: $tol}", "reach: $tol, vias: [0.75, 0.5]}")
    m = load_mission(write(tmp_path, {"m.yaml": main, "lib/goto.yaml": GOTO}))
    r = run_mission(m, record=False)
    assert r.executor.memory["toy.entries"] == [1.0, 0.75, 0.5, 0.5, 0.75, 0.5]
    # the value and the default got scoped names: the outer mission's own names are untouched
    assert m.spec.parameters["pick__vias"] == [0.75, 0.5] and m.spec.parameters["spots"] == [1.0, 0.5]


def test_names_inside_cannot_collide_with_the_outer_missions(tmp_path: Path) -> None:
    # the outer mission has its own `reach` and `vias` (other values): the used file still sees its own
    main = MAIN.replace("tol: 2 cm", "tol: 2 cm\n  reach: 3 m\n  vias: [9.0]").replace(", reach: $tol", "")
    m = load_mission(write(tmp_path, {"m.yaml": main, "lib/goto.yaml": GOTO}))
    r = run_mission(m, record=False)
    assert r.executor.memory["toy.entries"] == [1.0, 0.25, 0.5, 0.25]
    assert m.spec.parameters["reach"] == "3 m" and m.spec.parameters["pick__reach"] == "1 cm"


def test_drive_walks_the_used_states(tmp_path: Path) -> None:
    m = load_mission(write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": GOTO}))
    r = drive(m, Script(metrics=lambda s: {"pos_error": 0.0 if s.time_in_state > 0.2 else 1.0}))
    assert_outcome(r, "succeeded")
    assert_path(r, ["pick.go", "pick.vias.step", "pick.vias.ok", "pick.go", "pick.vias.step", "pick.vias.ok", "fin"],
                exact=False)


def test_nested_use(tmp_path: Path) -> None:
    twice = """\
submission: twice
parameters: {first: ~, second: 0.5, vias: [0.25]}
machine:
  initial: one
  states:
    one:
      use: goto.yaml
      with: {target: $first, vias: $vias}
      transitions: [{to: two, done: true}]
    two:
      use: goto.yaml
      with: {target: $second, vias: [0.75]}
      transitions: [{to: end, done: true}]
    end: {final: succeeded}
"""
    main = HEAD + """\
parameters: {where: 1.5}
machine:
  initial: job
  states:
    job:
      use: lib/twice.yaml
      with: {first: $where}
      transitions: [{to: fin, done: true}]
    fin: {final: succeeded}
"""
    m = load_mission(write(tmp_path, {"m.yaml": main, "lib/twice.yaml": twice,
                                      "lib/goto.yaml": GOTO.replace("vias: [0.25]", "vias: ~")}))
    assert "job.two.vias.step" in m.states and m.states["job.two"].use == "goto.yaml"
    r = run_mission(m, record=False)
    assert_outcome(r, "succeeded")
    # one: $target ← twice's $first ← the mission's $where, $vias ← twice's default; two: its own values
    assert r.executor.memory["toy.entries"] == [1.5, 0.25, 0.5, 0.75]
    assert m.spec.parameters["job__vias"] == [0.25] and m.spec.parameters["job__two__vias"] == [0.75]


def test_a_with_value_is_a_value_or_one_name(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN.replace("reach: $tol}", "reach: $tol, vias: [$spot]}"), "lib/goto.yaml": GOTO})
    (msg,) = problems(main)
    assert msg.startswith(f"{main}:15:42: `with:` gives a value or one $name, not a value holding $names"), msg


# -- errors ------------------------------------------------------------------------------------------


def test_a_problem_inside_the_used_file_names_that_file_and_where_it_was_used(tmp_path: Path) -> None:
    bad = GOTO.replace("{name: toy_goto, params: {target: $via}}", "{name: toy_gogo, params: {target: $via}}")
    main = write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": bad})
    lib = tmp_path / "lib" / "goto.yaml"
    (msg,) = problems(main)
    assert msg.startswith(f"{lib}:22:18: unknown task 'toy_gogo' — did you mean 'toy_goto'?"), msg
    assert msg.endswith(f"(used from {main}:14:7)"), msg


def test_an_unknown_reference_in_the_used_file_is_its_error(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": GOTO.replace("< $reach\"}]\n    vias", "< $rech\"}]\n    vias")})
    (msg,) = problems(main)
    lib = tmp_path / "lib" / "goto.yaml"
    assert msg.startswith(f"{lib}:15:32: $rech is not a parameter of this sub-mission"), msg
    assert "did you mean 'reach'?" in msg and msg.endswith(f"(used from {main}:14:7)")


def test_nested_errors_give_the_whole_chain(tmp_path: Path) -> None:
    inner = "submission: c\nmachine:\n  initial: x\n  states:\n    x: {final: maybe}\n"
    middle = "submission: b\nmachine:\n  initial: y\n  states:\n    y:\n      use: c.yaml\n"
    main = HEAD + "machine:\n  initial: a\n  states:\n    a: {use: lib/b.yaml}\n"
    path = write(tmp_path, {"m.yaml": main, "lib/b.yaml": middle, "lib/c.yaml": inner})
    msgs = problems(path)
    assert msgs and all(m.startswith(f"{tmp_path / 'lib' / 'c.yaml'}:5:9: ") for m in msgs), msgs
    assert msgs[0].endswith(f"(used from {tmp_path / 'lib' / 'b.yaml'}:6:7, itself used from {path}:9:9)"), msgs


def test_unknown_with_key_lists_the_valid_ones(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN.replace("reach: $tol}", "reech: $tol}"), "lib/goto.yaml": GOTO})
    (msg,) = problems(main)
    assert msg == (f"{main}:15:29: 'reech' is not a parameter of sub-mission 'goto_and_visit' — did you mean "
                   "'reach'? valid: reach, target, vias")


def test_a_parameter_without_default_must_be_given(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN.replace("target: $spot, ", ""), "lib/goto.yaml": GOTO})
    (msg,) = problems(main)
    assert msg == (f"{main}:14:7: sub-mission 'goto_and_visit' needs parameter 'target' (it has no default) — "
                   "give it in `with:`")


def test_a_with_reference_must_exist_in_the_using_file(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN.replace("target: $spot", "target: $spott"), "lib/goto.yaml": GOTO})
    (msg,) = problems(main)
    assert msg.startswith(f"{main}:15:14: $spott is not a parameter or loop item here — did you mean 'spot'?"), msg


def test_a_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN})
    (msg,) = problems(main)
    assert msg == (f"{main}:14:7: sub-mission 'lib/goto.yaml': no such file ({tmp_path / 'lib' / 'goto.yaml'}) — "
                   "the path is relative to the file that uses it")


def test_a_mission_file_is_not_a_sub_mission(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": MAIN})
    (msg,) = problems(main)
    assert msg.startswith(f"{tmp_path / 'lib' / 'goto.yaml'}:1:1: a used file is a sub-mission, not a mission"), msg


def test_a_target_outside_the_used_machine_must_be_declared_an_exit(tmp_path: Path) -> None:
    leaving = GOTO.replace("[{to: arrived, done: true}]", "[{to: arrived, done: succeeded}, {to: fin, done: failed}]")
    main = write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": leaving})
    (msg,) = problems(main)
    assert msg.startswith(f"{tmp_path / 'lib' / 'goto.yaml'}:19:54: target 'fin' is not a state of this sub-mission")
    declared = leaving.replace("machine:\n", "exits: [fin]\nmachine:\n")
    m = load_mission(write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": declared}))
    assert any(t.source.path == "pick.vias" and t.target.path == "fin" for t in m.transitions)


def test_a_state_that_uses_a_file_has_no_states_of_its_own(tmp_path: Path) -> None:
    main = MAIN.replace("      transitions: [{to: fin", "      initial: x\n      transitions: [{to: fin")
    (msg,) = problems(write(tmp_path, {"m.yaml": main, "lib/goto.yaml": GOTO}))
    assert "a state that uses a sub-mission has no `initial` of its own" in msg


def test_a_profile_defined_twice_with_other_values_is_refused(tmp_path: Path) -> None:
    main = MAIN.replace("machine:", "profiles:\n  gains: {soft: {kp: 9.0}}\nmachine:")
    (msg,) = problems(write(tmp_path, {"m.yaml": main, "lib/goto.yaml": GOTO}))
    assert msg.startswith(f"{tmp_path / 'lib' / 'goto.yaml'}:8:11: profile gains.soft is also defined by the using "
                          "mission, with other values"), msg


@pytest.mark.parametrize("files, chain", [
    ({"lib/a.yaml": "submission: a\nmachine:\n  initial: x\n  states:\n    x: {use: a.yaml}\n"}, ["a", "a"]),
    ({"lib/a.yaml": "submission: a\nmachine:\n  initial: x\n  states:\n    x: {use: b.yaml}\n",
      "lib/b.yaml": "submission: b\nmachine:\n  initial: y\n  states:\n    y: {use: a.yaml}\n"}, ["a", "b", "a"]),
])
def test_cycles_of_use_are_refused_with_the_chain(tmp_path: Path, files: dict[str, str], chain: list[str]) -> None:
    main = write(tmp_path, {"m.yaml": HEAD + "machine:\n  initial: s\n  states:\n    s: {use: lib/a.yaml}\n", **files})
    (msg,) = problems(main)
    names = " → ".join(str(tmp_path / "lib" / f"{n}.yaml") for n in chain)
    assert f"5:9: a cycle of sub-missions: {names}" in msg, msg
    assert msg.endswith(f"{main}:9:9)"), msg


def test_a_mission_can_use_itself_only_by_a_cycle_error(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": HEAD + "machine:\n  initial: s\n  states:\n    s: {use: m.yaml}\n"})
    (msg,) = problems(main)
    assert msg.startswith(f"{main}:9:9: a cycle of sub-missions: {main} → {main}"), msg


# -- graphs ------------------------------------------------------------------------------------------


def test_graphs_draw_the_used_machine_as_a_cluster_labelled_with_its_file(tmp_path: Path) -> None:
    m = load_mission(write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": GOTO}))
    dot = to_dot(m)
    assert 'subgraph "cluster_pick" {\n        label="pick (use lib/goto.yaml,\\nforeach spot in spots)";' in dot
    assert '"pick__go" [label="go\\n(toy_goto)"' in dot
    assert 'state "pick [foreach spot in spots] [use lib/goto.yaml]" as pick {' in to_mermaid(m)


def test_an_outer_name_a_loop_item_of_the_used_file_would_hide_is_refused(tmp_path: Path) -> None:
    # the mission passes its loop item `via` as $target, and the used file's own loop item is also `via`:
    # inside that loop `$via` would be the inner item, not the value passed in
    lib = GOTO.replace("params: {target: $via}", "params: {target: $target}")
    main = MAIN.replace("as: spot", "as: via").replace("target: $spot", "target: $via")
    (msg,) = problems(write(tmp_path, {"m.yaml": main, "lib/goto.yaml": lib}))
    assert msg.startswith(f"{tmp_path / 'lib' / 'goto.yaml'}:22:43: $target is the using file's $via, which the loop "
                          "item 'via' here hides — rename that loop item"), msg


def test_the_worked_example_of_docs_missions_md_loads(tmp_path: Path) -> None:
    import re

    text = (Path(__file__).parents[2] / "docs" / "missions.md").read_text()
    start = text.index("## Sub-missions")
    section = text[start:text.index("\n## ", start + 1)]
    lib, main = re.findall(r"```yaml\n(.*?)```", section, re.S)
    head = ("mission: my_mission\nrobot: racecar\nworld: {name: flat_ground}\nrate_hz: 20\n"
            "profiles:\n  gains:\n    cruise: {k1: [0.6, 0.6], d: 0.3}\n")
    m = load_mission(write(tmp_path, {"m.yaml": head + main, "lib/approach.yaml": lib}))
    assert list(m.states) == ["drive", "drive.approach", "drive.settle", "drive.reached", "done"]
    assert list(m.spec.parameters) == ["waypoints", "tight"]  # both parameters passed as outer names
    assert any(t.label == "pos_error < $tight for 0.3 s" for t in m.transitions)


def test_malformed_yaml_in_the_used_file_is_located_there(tmp_path: Path) -> None:
    main = write(tmp_path, {"m.yaml": MAIN, "lib/goto.yaml": "submission: g\nmachine: {initial: a\n"})
    (msg,) = problems(main)
    assert msg.startswith(f"{tmp_path / 'lib' / 'goto.yaml'}:3:1: YAML error"), msg
    assert msg.endswith(f"(used from {main}:14:7)"), msg


# -- shipped sub-missions by name (`use: taskflow:PATH`) ------------------------------------------------------------
def _copied_screw_mission(tmp_path: Path, use: str | None) -> Path:
    """The shipped screw mission copied alone into a folder of its own, its `use:` rewritten to ``use``."""
    from taskflow_missions import DIR

    text = (DIR / "screw_fastening.yaml").read_text()
    assert "use: lib/screw_operation.yaml" in text
    if use is not None:
        text = text.replace("use: lib/screw_operation.yaml", f"use: {use}")
    out = tmp_path / "mine" / "screw_fastening.yaml"
    out.parent.mkdir()
    out.write_text(text)
    return out


def test_a_copied_shipped_mission_names_its_sub_mission_and_runs_the_same_machine(tmp_path: Path) -> None:
    from taskflow_missions import DIR

    copy = load_mission(_copied_screw_mission(tmp_path, "taskflow:lib/screw_operation.yaml"))
    shipped = load_mission(DIR / "screw_fastening.yaml")
    assert list(copy.states) == list(shipped.states)
    assert [t.label for t in copy.transitions] == [t.label for t in shipped.transitions]
    assert copy.spec.parameters == shipped.spec.parameters


def test_a_copy_that_kept_the_relative_use_is_told_the_shipped_name(tmp_path: Path) -> None:
    path = _copied_screw_mission(tmp_path, None)
    with pytest.raises(MissionError) as err:
        load_mission(path)
    [problem] = err.value.problems
    assert problem.file == str(path) and "no such file" in problem.message
    assert "write `use: taskflow:lib/screw_operation.yaml` to use it from anywhere" in problem.hint


@pytest.mark.parametrize("use, says", [
    ("taskflow:../pyproject.toml", "outside the shipped missions' folder"),
    ("taskflow:/etc/passwd", "is an absolute path"),
    ("taskflow:lib/screw_operatin.yaml", "did you mean 'screw_operation.yaml'"),
])
def test_a_shipped_name_stays_inside_the_missions_package(tmp_path: Path, use: str, says: str) -> None:
    with pytest.raises(MissionError) as err:
        load_mission(_copied_screw_mission(tmp_path, use))
    [problem] = err.value.problems
    assert says in problem.message + problem.hint
