"""Compile pass: the machine's shape — every composite that can finish has a ``done`` transition for
each outcome it can finish with, the machine can end, every state is reachable and no leaf is a trap."""

from __future__ import annotations

from taskflow.mission.compile.context import Compilation
from taskflow.mission.model import DoneTransition, StateNode


def check_structure(c: Compilation, root: StateNode) -> None:
    _check_done_coverage(c, root)
    _check_done_cascades(c, root)
    if not any(ch.final for ch in root.children.values()):
        c.err(("machine",), "the machine has no final state, so a run can only end by timeout",
              "add e.g. `done: {final: succeeded}`")
    _check_reachable(c, root)
    for n in c.states.values():  # ways out: a non-final leaf with no transition on itself or any ancestor
        if n.is_leaf and not n.final and not any(not isinstance(t, DoneTransition) for a in n.ancestors()
                                                 for t in a.transitions):
            c.err(n.ypath, f"state {n.path!r} has no way out: neither it nor a parent has a transition that can fire "
                  "while it is active", "add a transition, or mark it `final`")


def finishing_outcomes(n: StateNode) -> dict[str, str]:
    """The outcomes composite ``n`` can finish with, each with why (for messages)."""
    if n.parallel:
        return _parallel_outcomes(n)
    finals = [ch for ch in n.children.values() if ch.final]
    out: dict[str, str] = {}
    for f in finals:
        out.setdefault(f.final or "succeeded", f"its sub-state {f.name!r} is final: {f.final}")
    if n.loop and n.loop.on_failure == "continue":
        # failed items are recorded and the loop goes on; at its end the `require` rule decides
        failing = [f.name for f in finals if f.final != "succeeded"]
        out = {k: v for k, v in out.items() if k == "succeeded"}
        if failing:
            out["failed"] = f"when fewer than {n.loop.rule} items succeed: an item can end in {failing[0]!r}"
    return out


def _parallel_outcomes(n: StateNode) -> dict[str, str]:
    """A parallel state finishes with an ``outcome_map`` rule's outcome, with the outcome of a region that
    finishes other than ``succeeded`` (it pre-empts the rest), or ``succeeded`` when every region succeeds."""
    out: dict[str, str] = {}
    for outcome, need in n.outcome_map:
        out.setdefault(outcome, f"its outcome_map gives {outcome} when " +
                       " and ".join(f"{r!r} finishes {o}" for r, o in need.items()))
    every: list[dict[str, str]] = [finishing_outcomes(r) for r in n.children.values()]
    for region, outcomes in zip(n.children.values(), every):
        for outcome, why in outcomes.items():
            if outcome != "succeeded":
                out.setdefault(outcome, f"its region {region.name!r} can finish {outcome} ({why})")
    if every and all("succeeded" in o for o in every):
        out.setdefault("succeeded", "every region can finish succeeded")
    return out


def _check_done_coverage(c: Compilation, root: StateNode) -> None:
    for n in root.walk():
        if n.owns is not None:  # a region finishes into its parallel state, which has the `done` transitions
            continue
        finals = [ch for ch in n.children.values() if ch.final] or ([n] if n.parallel and finishing_outcomes(n) else [])
        dones = [t for t in n.transitions if isinstance(t, DoneTransition)]
        if n.parent is not None and n.children and (finals or n.loop) and not dones:
            c.err(n.ypath, f"state {n.path!r} can finish (it has final sub-states) but has no `done` transition",
                  "add e.g. `- {to: NEXT, done: true}`")
        elif n.parent is not None and finals:
            for outcome, why in finishing_outcomes(n).items():
                if not any(t.handles(outcome) for t in dones):
                    c.err(n.ypath, f"state {n.path!r} can finish {outcome} ({why}) but no `done` transition handles "
                          "that outcome", f"add `- {{to: NEXT, done: {outcome}}}`, or make one `done: true`")
        if n.children and not finals and dones:
            c.err(n.ypath, f"state {n.path!r} waits for `done` but none of its sub-states is final",
                  "mark the last sub-state `final: succeeded`")


def _check_done_cascades(c: Compilation, root: StateNode) -> None:
    """A `done` transition must not lead, at the same instant, back to its own firing: into a final state that
    finishes its source again (directly, or through further `done` transitions) — the run would never leave that
    instant.  Followed as the engine follows it: entering a final leaf finishes its parent (a plain composite: the
    first `done` transition that handles the outcome fires)."""
    for n in root.walk():
        for k, tr in enumerate(n.transitions):
            if not isinstance(tr, DoneTransition):
                continue
            seen: list[DoneTransition] = []
            cur: DoneTransition | None = tr
            while cur is not None and cur not in seen:
                seen.append(cur)
                leaf = cur.target.entry_point()
                parent = leaf.parent
                if not leaf.final or parent is None or parent.parent is None or parent.loop or parent.owns is not None:
                    cur = None  # the cascade ends: a state to wait in, the run's end, a loop's next item, a region
                    break
                outcome = leaf.final
                cur = next((t for t in parent.transitions if isinstance(t, DoneTransition) and t.handles(outcome)),
                           None)
            if cur is not None and cur is tr:
                via = "" if len(seen) == 1 else f" (through {', '.join(t.source.path for t in seen[1:])})"
                c.err(n.ypath + ("transitions", k), f"this `done` transition enters {tr.target.path!r}, a final state "
                      f"that finishes {n.path!r} again at once{via}: the run would never leave that instant",
                      "target a state that is not final, or a final state outside the composite it finishes")
                return


def _check_reachable(c: Compilation, root: StateNode) -> None:
    reached: set[str] = set()
    frontier: list[StateNode] = []

    def enter(target: StateNode) -> None:
        for s in [*target.ancestors()[1:], *_initial_chain(target)]:
            if s.path not in reached:
                reached.add(s.path)
                frontier.append(s)

    enter(root.initial_child())
    while frontier:
        s = frontier.pop()
        for t in s.transitions:
            enter(t.target)
        if s.final and s.parent is not None and s.parent.loop:
            enter(s.parent)
    for path, n in c.states.items():
        if path not in reached:
            c.err(n.ypath, f"state {path!r} is unreachable: no transition leads to it", "add a transition to it, or remove it")


def _initial_chain(n: StateNode) -> list[StateNode]:
    """The states entering ``n`` enters below it (every region's chain under a parallel state)."""
    chain: list[StateNode] = []
    for child in (n.children.values() if n.parallel else [n.initial_child()] if n.children else []):
        chain += [child, *_initial_chain(child)]
    return chain
