"""Sub-missions as hostile input: expansion has a budget (depth of ``use:``, distinct files, states spliced
in), answered in one line and well under a second; states nested hundreds of levels deep get a depth error,
not a ``RecursionError``; a huge used file is refused; the source map finds a graft without scanning every
one.  (Cycles, paths outside the mission's folder, directories and missing files are in ``tests/broken/seam_*``.)"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission, load_mission_text
from taskflow.mission.statetree import MAX_STATE_DEPTH
from taskflow.mission.submission import MAX_EXPANDED_STATES, MAX_USE_DEPTH, MAX_USE_FILES
from taskflow.mission.yamlsrc import MAX_BYTES, Graft, SourceMap

MISSION = """\
mission: m
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
machine:
  initial: a
  states:
    a:
      use: l0.yaml
      transitions: [{to: fin, done: true}]
    fin: {final: succeeded}
"""

LEAF = """\
submission: leaf
profiles:
  gains: {soft: {kp: 2.0}}
machine:
  bind: {gains: soft}
  initial: go
  states:
    go:
      task: {name: toy_goto, params: {target: 1.0}}
      transitions: [{to: ok, when: "GUARD"}]
    ok: {final: succeeded}
"""


def ladder(tmp: Path, depth: int, fan_out: int, guard: str = "pos_error < 1 cm", files: int | None = None) -> Path:
    """``m.yaml`` using ``l0.yaml``, each ``l{i}`` using ``l{i+1}`` ``fan_out`` times, ``l{depth}`` a leaf.
    With ``files``, level ``i`` of the ladder uses ``fan_out`` distinct copies instead (``l{i}_{k}.yaml``)."""
    (tmp / "m.yaml").write_text(MISSION)
    for i in range(depth):
        nxt = [f"l{i + 1}.yaml"] * fan_out
        states = "".join(f"    u{k}:\n      use: {nxt[k]}\n      transitions: [{{to: {f'u{k + 1}' if k + 1 < fan_out else 'ok'}"
                         f", done: true}}]\n" for k in range(fan_out))
        (tmp / f"l{i}.yaml").write_text(f"submission: l{i}\nmachine:\n  initial: u0\n  states:\n{states}"
                                        "    ok: {final: succeeded}\n")
    (tmp / f"l{depth}.yaml").write_text(LEAF.replace("GUARD", guard))
    return tmp / "m.yaml"


def refused(path: Path) -> tuple[MissionError, float]:
    t0 = time.perf_counter()
    with pytest.raises(MissionError) as exc:
        load_mission(path)
    return exc.value, time.perf_counter() - t0


def test_files_that_each_use_the_next_twice_are_refused_by_the_state_budget_at_once(tmp_path: Path) -> None:
    """Fan-out 3 over 7 levels would splice in thousands of states (on main: minutes, then loaded)."""
    err, took = refused(ladder(tmp_path, 7, 3))
    assert len(err.problems) == 1, err
    p = err.first
    assert f"expand to more than {MAX_EXPANDED_STATES} states" in p.message and "at most" in p.hint, p
    assert p.file.endswith(".yaml") and p.line > 0 and p.col > 0
    assert took < 1.0, took


def test_use_nested_past_the_depth_budget_is_refused_with_the_chain(tmp_path: Path) -> None:
    err, took = refused(ladder(tmp_path, MAX_USE_DEPTH + 2, 1))
    assert len(err.problems) == 1, err
    p = err.first
    assert f"sub-missions nest more than {MAX_USE_DEPTH} deep here" in p.message, p
    assert "m.yaml → l0.yaml → l1.yaml" in p.message and p.file == str(tmp_path / f"l{MAX_USE_DEPTH - 1}.yaml")
    assert took < 1.0, took


def test_the_deepest_allowed_ladder_loads(tmp_path: Path) -> None:
    """At the budget (8 levels of use, fan-out 2: 639 states) the mission loads — the budget refuses only past it."""
    m = load_mission(ladder(tmp_path, MAX_USE_DEPTH - 1, 2))
    assert len([s for s in m.states if s.endswith(".go")]) == 2 ** (MAX_USE_DEPTH - 1)


def test_more_distinct_files_than_the_budget_are_refused(tmp_path: Path) -> None:
    (tmp_path / "leaf.yaml").write_text(LEAF.replace("GUARD", "pos_error < 1 cm"))
    n = MAX_USE_FILES + 1
    for k in range(n):
        (tmp_path / f"f{k}.yaml").write_text((tmp_path / "leaf.yaml").read_text())
    states = "".join(f"    u{k}:\n      use: f{k}.yaml\n      transitions: [{{to: {f'u{k + 1}' if k + 1 < n else 'fin'}"
                     ", done: true}]\n" for k in range(n))
    (tmp_path / "m.yaml").write_text(MISSION.split("machine:")[0] + f"machine:\n  initial: u0\n  states:\n{states}"
                                     "    fin: {final: succeeded}\n")
    err, _ = refused(tmp_path / "m.yaml")
    assert len(err.problems) == 1 and f"at most {MAX_USE_FILES} sub-mission files" in err.first.message, err
    assert (err.first.file, err.first.line) == (str(tmp_path / "m.yaml"), 8 + 3 * MAX_USE_FILES + 2)


def test_a_problem_in_a_file_used_many_times_is_reported_once(tmp_path: Path) -> None:
    """One wrong guard in a leaf used 8 times through a ladder: one line (main printed it 8 times)."""
    err, _ = refused(ladder(tmp_path, 3, 2, guard="pos_eror < 1 cm"))
    assert len(err.problems) == 1, err
    assert err.first.file == str(tmp_path / "l3.yaml") and "'pos_eror'" in err.first.message


@pytest.mark.parametrize("levels", [MAX_STATE_DEPTH + 1, 200])
def test_states_nested_hundreds_deep_get_a_depth_error_not_a_recursion_error(levels: int) -> None:
    text = "mission: m\nrobot: toy_point\nworld: {name: toy_line, params: {start: 0.0}}\nrate_hz: 20\nmachine:\n"
    text += "  initial: s1\n  states:\n"
    ind = "    "
    for i in range(1, levels):
        text += f"{ind}s{i}:\n{ind}  initial: s{i + 1}\n{ind}  states:\n"
        ind += "    "
    text += f"{ind}s{levels}: {{final: true}}\n"
    t0 = time.perf_counter()
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "deep.yaml")
    p = exc.value.first
    assert f"states nest more than {MAX_STATE_DEPTH} levels deep here" in p.message, p
    assert (p.line, p.col) == (8 + 3 * MAX_STATE_DEPTH, 5 + 4 * MAX_STATE_DEPTH), p
    assert time.perf_counter() - t0 < 1.0


def test_a_huge_used_file_is_refused_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(MISSION)
    with open(tmp_path / "l0.yaml", "w") as f:
        f.write(LEAF.replace("GUARD", "pos_error < 1 cm"))
        f.write("# padding\n" * (MAX_BYTES // 10 + 1))
    err, took = refused(tmp_path / "m.yaml")
    assert len(err.problems) == 1, err
    assert f"larger than {MAX_BYTES} bytes" in err.first.message
    assert err.first.via == (f"{tmp_path / 'm.yaml'}:10:7",)
    assert took < 1.0


def test_a_graft_is_found_without_scanning_every_graft() -> None:
    """5000 grafts, 5000 look-ups: a scan of every graft per look-up (main) takes seconds."""
    inner = SourceMap("lib.yaml")
    inner.marks[("machine", "states", "go")] = (7, 5)
    outer = SourceMap("m.yaml")
    n = 5000
    for i in range(n):
        outer.graft(Graft(("machine", "states", f"s{i}", "states"), inner, ("machine", "states"), (f"m.yaml:{i}:1",)))
    t0 = time.perf_counter()
    found = [outer.problem(("machine", "states", f"s{i}", "states", "go", "task"), "x") for i in range(n)]
    took = time.perf_counter() - t0
    assert [(p.file, p.line, p.col, p.via) for p in found[:2]] == [("lib.yaml", 7, 5, ("m.yaml:0:1",)),
                                                                   ("lib.yaml", 7, 5, ("m.yaml:1:1",))]
    assert took < 0.5, took


def test_a_symbolic_link_out_of_the_missions_folder_is_refused(tmp_path: Path) -> None:
    """The rule is on the resolved path: a link in lib/ to a file elsewhere is outside the folder too."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "leaf.yaml").write_text(LEAF.replace("GUARD", "pos_error < 1 cm"))
    mission = tmp_path / "mission"
    (mission / "lib").mkdir(parents=True)
    (mission / "lib" / "leaf.yaml").symlink_to(elsewhere / "leaf.yaml")
    (mission / "m.yaml").write_text(MISSION.replace("use: l0.yaml", "use: lib/leaf.yaml"))
    err, _ = refused(mission / "m.yaml")
    assert len(err.problems) == 1 and (err.first.line, err.first.col) == (10, 7), err
    assert f"resolves to {elsewhere / 'leaf.yaml'}, outside the mission's folder {mission}" in err.first.message


def test_a_file_in_lib_may_use_a_sibling_folder_inside_the_mission(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "leaf.yaml").write_text(LEAF.replace("GUARD", "pos_error < 1 cm"))
    (tmp_path / "lib" / "l0.yaml").write_text("submission: l0\nmachine:\n  initial: u\n  states:\n"
                                              "    u:\n      use: ../other/leaf.yaml\n"
                                              "      transitions: [{to: ok, done: true}]\n    ok: {final: succeeded}\n")
    (tmp_path / "m.yaml").write_text(MISSION.replace("use: l0.yaml", "use: lib/l0.yaml"))
    assert "a.u.go" in load_mission(tmp_path / "m.yaml").states
