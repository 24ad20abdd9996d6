"""The engine state: `transitions`' HierarchicalMachine, extended in its own style for what missions need.

The machine is the only place the active configuration lives: the model's ``state`` attribute is the
active leaf's dotted path, and the library runs the exit and entry callbacks of every state a
transition leaves and enters.  taskflow extends it the way the library is meant to be extended — by
its ``state_cls`` and ``transition_cls`` hooks — rather than keeping a parallel copy:

* :class:`MissionState` is the library's ``NestedState`` carrying what a mission state adds at run
  time: its compiled :class:`~taskflow.mission.model.StateNode`, its sim-clock entry times (the clocks of
  ``after … since``), the leaf it was left in (``history: true``) and its ``foreach`` position.
* :class:`ExternalTransition` is the library's ``NestedTransition`` with UML *external* semantics.
  The library exits and enters only below the deepest state the source and destination leaves share,
  which leaves a state un-exited when a transition declared on a composite targets the composite
  itself or one of its own descendants (``retry: {to: approach}`` from inside ``approach``), or when a
  ``foreach`` moves to its next item.  An :class:`ExternalTransition` is told its *domain* — how many
  levels of the destination path stay active — and exits and re-enters everything below it.
* :meth:`MissionMachine.go` executes a cached transition to a leaf directly, as the library's own
  ``to_state`` helper does, instead of dispatching a trigger through the state tree: guards are
  evaluated by the executor's per-leaf tables, so the library is asked only to change state.

This is the one module that imports `transitions` (the adapter: the rest of taskflow sees only
:class:`MissionMachine`'s ``go``, ``active``, ``active_leaves`` and ``by_path``).  Beyond the library's
documented hooks it relies on these members, each named, signed and exercised by
``tests/machine/test_transitions_contract.py`` (``.ci/run-latest`` runs it on the newest release; the
bound in ``pyproject.toml`` is where it passes): ``NestedTransition._change_state`` calling, in order,
``_resolve_transition`` (overridden), the exits, the model update, the entries and ``_final_check``
(overridden to do nothing); ``NestedTransition._enter_nested``, ``NestedState.scoped_exit``,
``HierarchicalMachine.build_state_tree`` and ``nesting.resolve_order`` (called); ``NestedEventData``'s
``source_name`` / ``source_path`` and ``Event(name, machine)`` (built by :meth:`MissionMachine.go`).

What was tried and left unused: the library's ``final`` states and ``on_final`` callbacks (0.9.3) fire
on the parent of a final leaf, but a ``foreach`` parent must decide between its next item and its
``require`` rule, and the callback runs inside the transition that entered the final leaf (so a
transition started from it would nest inside the first).  The executor therefore finishes a parent
after the transition into its final leaf has completed; :class:`MissionState` still carries the
library's ``final`` flag so that the machine describes the mission.

Parallel regions are the library's parallel states (a state whose children are all entered with it;
the model's ``state`` is then a list of leaf paths).  The library enters every region only when a
transition targets the parallel state itself, so the compiler refuses a transition from outside a
region into a state inside it, and :meth:`MissionMachine.go` is given the parallel state as the
destination; a transition inside one region exits and enters below its domain, which lies inside that
region, so the other regions stay as they are.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from functools import partial
from typing import Any

from transitions.core import Event
from transitions.extensions.nesting import (
    HierarchicalMachine,
    NestedEventData,
    NestedState,
    NestedTransition,
    resolve_order,
)

from taskflow.mission.model import CompiledMission, StateNode

StateTree = OrderedDict[str, Any]
"""The library's model state as a tree: state name → the tree of its active sub-states."""

START = "__start__"
"""The pseudo-state the model is in before the run starts."""


class MissionState(NestedState):
    """A state of the mission machine with the run-time data taskflow adds to the library's state."""

    separator = "."

    def __init__(self, name: str, node: StateNode | None = None, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.node = node
        self.entered_at = 0.0  # sim time of the last entry
        self.first_entered: float | None = None  # first entry since the enclosing state was entered afresh
        self.held_at_entry = 0.0  # the run's time under operator hold (s) when it was last entered
        self.held_at_first = 0.0  # ... and when it was first entered (the clock of `after … since: first_entry`)
        self.last_leaf: str | None = None  # history: the leaf that was active when this state was last left
        self.item = 0  # foreach: index of the current item
        self.item_started = 0.0  # foreach: sim time the current item started
        self.items_succeeded = 0  # foreach: items that succeeded in this run of the loop
        self.attempt = 1  # foreach: the current item's attempt (1: the first; `retry` runs it again)
        self.retried: list[str] = []  # foreach: the final states the current item's earlier attempts ended in

    def operating_time(self, t: float, held_s: float, first: bool = False) -> float:
        """Seconds of operating time from this state's last entry (``first``: its first entry, when it has one)
        to sim time ``t``, the run having spent ``held_s`` under operator hold so far: what ``after`` compares
        (time under hold does not count)."""
        if first and self.first_entered is not None:
            return (t - self.first_entered) - (held_s - self.held_at_first)
        return (t - self.entered_at) - (held_s - self.held_at_entry)


class ExternalTransition(NestedTransition):
    """A transition to a leaf that exits and re-enters every state below its domain (UML external).

    ``keep`` is the number of leading names of the destination path that stay active (the domain's
    depth: 0 exits everything).  The library's resolution keeps every state the source and
    destination share; this one keeps only the domain, which is at most that."""

    def __init__(self, source: str, dest: str, keep: int) -> None:
        super().__init__(source, dest)
        self.keep = keep
        path = dest.split(MissionState.separator)
        self.kept, self.entered = path[:keep], path[keep:]

    def _resolve_transition(self, event_data: NestedEventData) -> tuple[StateTree, list[Callable[[], None]],
                                                                         list[Callable[[], Any]]]:
        machine = event_data.machine
        state = getattr(event_data.model, machine.model_attribute)  # a leaf's path, or a list with regions
        tree = machine.build_state_tree(state if isinstance(state, list) else [state], MissionState.separator)
        kept = self.kept
        below = tree  # the active states below the domain (one region)
        for name in kept:
            below = below[name]
        exits: list[Callable[[], None]] = [
            partial(machine.get_state(kept + path).scoped_exit, event_data, kept + path[:-1])
            for path in resolve_order(below)]
        new_states, enters = self._enter_nested(list(kept), list(self.entered), list(kept), event_data)
        below.clear()
        below.update(new_states)
        return tree, exits, enters

    def _final_check(self, event_data: NestedEventData, state_tree: StateTree,
                     enter_partials: list[Callable[[], Any]]) -> tuple[list[Callable[[], Any]], bool]:
        """The library's search for states that have just become final, skipped: taskflow finishes parents itself
        (module docstring) and has no ``on_final`` callbacks.  The library's own (0.9.3) raises
        ``AttributeError: 'scoped_enter'`` after a transition in one parallel region while the last region sits
        in its final state (it takes the last region's finality for the parallel state's)."""
        return [], False


def leaf_paths(state: Any) -> list[str]:
    """The library's model state with parallel states active (nested lists of leaf paths), flattened."""
    return [state] if isinstance(state, str) else [leaf for s in state for leaf in leaf_paths(s)]


class Model:
    """The model object the library sets ``state`` on."""

    state: str = START


class MissionMachine(HierarchicalMachine):
    """The compiled mission's state tree as a HierarchicalMachine of :class:`MissionState` (separator ``.``)."""

    state_cls = MissionState

    def __init__(self, mission: CompiledMission, on_enter: Callable[[StateNode], None],
                 on_exit: Callable[[StateNode], None]) -> None:
        self.mission_model = Model()
        self._go_cache: dict[tuple[str, int], ExternalTransition] = {}
        self._go_event: Event | None = None

        def dicts(node: StateNode) -> list[dict[str, Any]]:
            out = []
            for child in node.children.values():
                d: dict[str, Any] = {"name": child.name, "node": child, "final": bool(child.final),
                                     "on_enter": [lambda n=child: on_enter(n)], "on_exit": [lambda n=child: on_exit(n)]}
                if child.parallel:  # the library's parallel state: every region is entered with it
                    d["parallel"] = dicts(child)
                elif child.children:
                    d["children"] = dicts(child)
                    d["initial"] = child.initial
                out.append(d)
            return out

        super().__init__(model=self.mission_model, states=[START, *dicts(mission.root)], initial=START,
                         auto_transitions=False, send_event=False)
        self.by_path: dict[str, MissionState] = {n.path: self._mission_state(n.path)
                                                 for n in mission.states.values() if n.parent is not None}

    def _mission_state(self, path: str) -> MissionState:
        st = self.get_state(path)
        assert isinstance(st, MissionState)  # the machine's state_cls
        return st

    @property
    def active(self) -> str:
        """The active leaf's path (:data:`START` before the run starts); with parallel regions active, the
        first region's leaf (see :meth:`active_leaves`)."""
        state = self.mission_model.state
        return state if isinstance(state, str) else leaf_paths(state)[0]

    def active_leaves(self) -> list[str]:
        """Every active leaf's path: one, or one per active parallel region (in the order declared)."""
        state = self.mission_model.state
        return [state] if isinstance(state, str) else leaf_paths(state)

    def go(self, leaf: str, keep: int) -> None:
        """Make ``leaf`` active, exiting and re-entering every state below the first ``keep`` names of its path."""
        key = (leaf, keep)
        tr = self._go_cache.get(key)
        if tr is None:
            tr = self._go_cache[key] = ExternalTransition("*", leaf, keep)
        if self._go_event is None:
            self._go_event = Event("go", self)
        source = self.active
        event_data = NestedEventData(self.by_path.get(source) or self.get_state(source), self._go_event, self, self.mission_model, args=(), kwargs={})
        event_data.source_name = source
        event_data.source_path = source.split(MissionState.separator)
        tr.execute(event_data)
