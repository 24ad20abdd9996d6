"""The contract between taskflow's engine and `transitions`: every member of the library the engine relies on
that its documentation does not promise, named, with its signature and the behaviour the engine needs.

``taskflow/execution/engine.py`` is the one module that imports the library (the last test checks it).  It
extends ``HierarchicalMachine`` by its documented hooks (``state_cls``, dict states with ``children``,
``parallel``, ``initial``, ``final``, ``on_enter``/``on_exit``), and beyond them it

* overrides ``NestedTransition._resolve_transition`` (UML external semantics: exit and re-enter below a
  domain) and ``NestedTransition._final_check`` (disabled: taskflow finishes parents itself),
* calls ``NestedTransition._enter_nested`` (the entry chain of a destination and its initial states),
  ``NestedState.scoped_exit``, ``HierarchicalMachine.build_state_tree`` and ``nesting.resolve_order``
  (the exit order), and
* builds a ``NestedEventData`` itself (with ``source_name`` / ``source_path``) for an ``Event`` it creates,
  to ``execute`` a cached transition directly (as the library's ``to_state`` does),

all of it relying on ``NestedTransition._change_state`` calling them in the order resolve → exits →
model update → entries → final check.  A release that renames, re-signs or reorders any of these fails here,
by name, before a mission runs wrong.  ``.ci/run-latest`` runs this file on the newest release; the bound in
``pyproject.toml`` (``transitions>=0.9.1,<0.10``) is where it passes (0.9.0 lacks ``final`` states and
``_final_check``).
"""

from __future__ import annotations

import ast
import inspect
from collections import OrderedDict
from pathlib import Path
from typing import Any

import transitions
from transitions.core import Event, listify
from transitions.extensions.nesting import (
    HierarchicalMachine,
    NestedEventData,
    NestedState,
    NestedTransition,
    resolve_order,
)

from taskflow.execution.engine import START, ExternalTransition, MissionMachine
from taskflow.mission.loader import load_mission_text

ROOT = Path(__file__).resolve().parents[2]


def params(fn: Any) -> list[str]:
    return list(inspect.signature(fn).parameters)


class Logged(HierarchicalMachine):
    """A machine that logs every entry and exit (``+path`` / ``-path``)."""

    log: list[str]


def machine() -> Logged:
    """``a`` (initial ``b`` → ``c``) with a sibling ``d`` (initial ``e``); every entry and exit logged."""
    hm = Logged(states=[
        {"name": "a", "initial": "b", "children": [
            {"name": "b", "initial": "c", "children": ["c"]}, {"name": "d", "initial": "e", "children": ["e"]}]}],
        initial="a", auto_transitions=False)
    hm.log = []
    for path in ("a", "a_b", "a_b_c", "a_d", "a_d_e"):
        st = hm.get_state(path)
        st.on_enter.append(lambda p=path: hm.log.append(f"+{p}"))
        st.on_exit.append(lambda p=path: hm.log.append(f"-{p}"))
    return hm


def event_data(hm: HierarchicalMachine, source: str) -> NestedEventData:
    """What the engine builds to execute a transition without a trigger (``MissionMachine.go``)."""
    ed = NestedEventData(hm.get_state(source), Event("go", hm), hm, hm, args=(), kwargs={})
    ed.source_name = source
    ed.source_path = source.split(hm.state_cls.separator)
    return ed


def test_the_version_installed_is_within_the_bound_pyproject_states() -> None:
    text = (ROOT / "pyproject.toml").read_text()
    assert '"transitions>=0.9.1,<0.10"' in text  # 0.9.0 has no `final` states nor `_final_check`
    version = tuple(int(x) for x in transitions.__version__.split(".")[:3])
    assert version >= (0, 9, 1)  # .ci/run-latest runs this file on a newer one on purpose


def test_change_state_resolves_then_exits_updates_the_model_enters_and_checks_finality() -> None:
    """``_change_state`` is the engine's one entry into the library's state change: it calls the overridden
    ``_resolve_transition`` and ``_final_check`` and runs the partials they return, in this order."""
    assert params(NestedTransition._change_state) == ["self", "event_data"]
    calls: list[str] = []

    class Spy(NestedTransition):
        def _resolve_transition(self, event_data: Any) -> Any:
            calls.append("resolve")
            tree, exits, enters = super()._resolve_transition(event_data)
            return (tree, [lambda: calls.append("exit")] + exits, [lambda: calls.append("enter")] + enters)

        def _final_check(self, event_data: Any, state_tree: Any, enter_partials: Any) -> Any:
            calls.append(f"final:{event_data.model.state}")
            return [], False

    hm = machine()
    Spy("a_b_c", "a_d_e").execute(event_data(hm, "a_b_c"))
    assert calls == ["resolve", "exit", "enter", "final:a_d_e"]  # the model is updated before the entries
    assert getattr(hm, hm.model_attribute) == "a_d_e"


def test_resolve_transition_returns_the_tree_the_exits_and_the_entries() -> None:
    assert params(NestedTransition._resolve_transition) == ["self", "event_data"]
    hm = machine()
    tree, exits, enters = NestedTransition("a_b_c", "a_d_e")._resolve_transition(event_data(hm, "a_b_c"))
    assert isinstance(tree, dict) and list(tree) == ["a"]
    for f in exits:
        f()
    for f in enters:
        f()
    assert hm.log == ["-a_b_c", "-a_b", "+a_d", "+a_d_e"]


def test_enter_nested_enters_the_destination_chain_and_its_initial_states() -> None:
    """``_enter_nested(root, dest, prefix_path, event_data)`` → (new state tree below ``root``, entry partials);
    an empty ``dest`` enters ``root``'s initial chain."""
    assert params(NestedTransition._enter_nested) == ["self", "root", "dest", "prefix_path", "event_data"]
    hm = machine()
    ed = event_data(hm, "a_b_c")
    tr = NestedTransition("a_b_c", "a_d")
    new_states, enters = tr._enter_nested(["a"], ["d"], ["a"], ed)
    assert new_states == OrderedDict([("d", OrderedDict([("e", OrderedDict())]))])
    for f in enters:
        f()
    assert hm.log == ["+a_d", "+a_d_e"]


def test_final_check_takes_the_tree_and_the_entries_and_returns_callbacks_and_finality() -> None:
    """The engine overrides ``_final_check`` to do nothing; the library's still has this signature and result."""
    assert params(NestedTransition._final_check) == ["self", "event_data", "state_tree", "enter_partials"]
    assert "_final_check" in inspect.getsource(NestedTransition._change_state)
    hm = machine()
    ed = event_data(hm, "a_b_c")
    with hm():
        cbs, final = NestedTransition("a_b_c", "a_d_e")._final_check(ed, OrderedDict(), [])
    assert (cbs, final) == ([], False)
    assert ExternalTransition._final_check(ExternalTransition("*", "a", 0), ed, OrderedDict(), []) == ([], False)


def test_scoped_exit_runs_a_states_exit_callbacks_under_its_scope() -> None:
    assert params(NestedState.scoped_exit) == ["self", "event_data", "scope"]
    hm = machine()
    seen: list[str] = []
    st = hm.get_state("a_b")
    st.on_exit.append(lambda: seen.append(st.name))
    st.scoped_exit(event_data(hm, "a_b_c"), ["a"])
    assert seen == ["a_b"] and st.name == "b"  # the scope names it while its callbacks run, then is reset


def test_build_state_tree_and_resolve_order_give_the_exit_order_children_first() -> None:
    assert params(HierarchicalMachine.build_state_tree) == ["self", "model_states", "separator", "tree"]
    assert params(resolve_order) == ["state_tree"]
    hm = machine()
    tree = hm.build_state_tree(listify("a_b_c"), "_")
    assert tree == {"a": {"b": {"c": {}}}}
    assert [list(p) for p in resolve_order(tree["a"])] == [["b", "c"], ["b"]]
    par = hm.build_state_tree(listify(["x_r1_s", "x_r2_t"]), "_")
    assert [list(p) for p in resolve_order(par["x"])] == [["r1", "s"], ["r2", "t"], ["r1"], ["r2"]]


def test_event_data_carries_the_source_the_engine_sets() -> None:
    assert params(NestedEventData.__init__) == ["self", "state", "event", "machine", "model", "args", "kwargs"]
    assert params(Event.__init__) == ["self", "name", "machine"]
    ed = event_data(machine(), "a_b_c")
    assert (ed.source_name, ed.source_path) == ("a_b_c", ["a", "b", "c"])


def test_dict_states_pass_their_own_keys_to_the_state_class() -> None:
    """The engine's ``state_cls`` receives the mission node through the state dict (``node``) and the
    library's ``final`` flag, and a ``parallel`` dict enters every region with its state."""

    class Carrying(NestedState):
        def __init__(self, name: str, node: Any = None, **kwargs: Any) -> None:
            super().__init__(name, **kwargs)
            self.node = node

    class M(HierarchicalMachine):
        state_cls = Carrying

    m = M(states=["s", {"name": "f", "final": True}, {"name": "p", "node": 7, "parallel": [{"name": "r1", "initial": "x", "children": ["x"]},
                                                              {"name": "r2", "initial": "y", "children": ["y"]}]}],
          initial="s", auto_transitions=False)
    p = m.get_state("p")
    assert isinstance(p, Carrying) and p.node == 7
    assert m.get_state("f").final and not p.final  # the library's `final` flag (0.9.1 on), which the engine sets
    m.add_transition("go", "s", "p")
    m.trigger_event(m, "go")
    assert getattr(m, m.model_attribute) == ["p_r1_x", "p_r2_y"]


def test_the_engine_exits_and_reenters_below_its_domain_through_these_members() -> None:
    """End to end through :class:`MissionMachine`: the overridden members are the ones the library calls."""
    m = load_mission_text("""
mission: m
robot: toy_point
world: toy_line
rate_hz: 20
machine:
  initial: a
  states:
    a:
      initial: b
      transitions: [{to: a.b, on: target_lost}, {to: done, done: true}]
      states:
        b: {transitions: [{to: d, after: 1 s}]}
        d: {final: succeeded}
    done: {final: succeeded}
""", "c.yaml")
    log: list[str] = []
    engine = MissionMachine(m, lambda n: log.append(f"+{n.path}"), lambda n: log.append(f"-{n.path}"))
    assert engine.active == START
    engine.go("a.b", 0)
    engine.go("a.b", 0)  # a self-transition of the composite: external, everything below the root re-entered
    assert log == ["+a", "+a.b", "-a.b", "-a", "+a", "+a.b"]
    assert engine.active_leaves() == ["a.b"]


def test_no_other_framework_module_imports_transitions() -> None:
    """Every use of the library sits in the engine, so this file is its whole contract."""
    users = []
    for path in sorted((ROOT / "taskflow").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            if any(n == "transitions" or n.startswith("transitions.") for n in names):
                users.append(path.relative_to(ROOT).as_posix())
    assert sorted(set(users)) == ["taskflow/execution/engine.py"]
