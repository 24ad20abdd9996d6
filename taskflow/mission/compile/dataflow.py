"""Compile pass: mission data — the keys the mission's tasks declare, the mission's ``data:`` defaults,
and a must-be-written analysis over the compiled machine's transition graph.

:func:`data_catalogue` (after ``tree``) collects every :class:`~taskflow.api.MemoryKey` the tasks of the
mission declare in ``writes`` / ``reads`` (one key object per name) and checks the mission's ``data:``
block against them; ``bindings`` and ``transitions`` then know which ``$data.<key>`` parameters and
``data.<key>`` guard names exist.  :func:`check_dataflow` (last) checks that every key a state reads is
written on every path into it, or has a default.

The analysis runs on leaves, where tasks run.  A leaf *writes* the keys its task declares in ``writes``
(declared, not observed: a write the task might skip still counts).  The keys written on entry to a
leaf are the intersection, over every way into it, of what is written when that way is taken; what is
written when a leaf is left is what was written on its entry plus its own writes.  The ways in:

* the run's start (into the first initial leaf, or every region's when it is a parallel state), with the defaults only;
* every non-``done`` transition that can fire while a leaf is active (its own and its ancestors'), into
  the target's initial leaf — or, when the target is a composite with ``history`` and the transition
  resumes, into every leaf below it (any may be the one resumed; keys are never unwritten, so a resume
  sees at least what was written when it was left);
* a final leaf finishing its parent: into the parent's initial leaf for a ``foreach``'s next item, and
  through each ``done`` transition of the parent that handles an outcome the parent can finish with.

Loops need nothing more: a cycle only adds ways in, and the fixed point (every leaf starts from "all
keys" and shrinks) keeps what holds on every iteration.  Reads are a task's ``reads`` and its
``$data.<key>`` parameters (resolved on entry: written before the state is entered), and the keys a
guard compares, which must be written on entry to each leaf where the guard is evaluated or by that
leaf's own task (until it writes the value the comparison is false, as for a metric not yet published).
"""

from __future__ import annotations

from collections import deque
from typing import Any

from taskflow.mission.compile.context import Compilation
from taskflow.mission.compile.structure import finishing_outcomes
from taskflow.mission.data import DataCatalogue, from_yaml, guard_names
from taskflow.mission.guards import DATA_PREFIX
from taskflow.mission.model import DoneTransition, EventTransition, GuardTransition, StateNode, data_refs
from taskflow.registry import describe_choices


def data_catalogue(c: Compilation, root: StateNode) -> DataCatalogue:
    """Every key the mission's tasks declare, and the defaults (the keys' own, the mission's ``data:`` over
    them); sets ``c.mission_data``."""
    cat = DataCatalogue()
    owner: dict[str, str] = {}
    for n in root.walk():
        cls = n.task_cls
        if cls is None:
            continue
        for metric in cls.metrics:
            if metric.startswith(DATA_PREFIX):
                c.err(n.task_ypath, f"task {cls.name!r} publishes metric {metric!r}, but guard names starting "
                      f"with {DATA_PREFIX!r} read mission data", "rename the metric")
        for key in (*cls.writes, *cls.reads):
            known = cat.keys.setdefault(key.name, key)
            if known is not key:
                c.err(n.task_ypath, f"task {cls.name!r} declares mission data {key.name!r} with another MemoryKey "
                      f"than task {owner[key.name]!r}", "define each key once, in the module that owns it, and "
                      "import it where it is used")
            owner.setdefault(key.name, cls.name)
            if key.has_default:
                cat.defaults[key.name] = key.default
    for name, value in c.spec.data.items():
        if name not in cat.keys:
            c.err(("data", name), f"no task of this mission declares mission data {name!r}",
                  describe_choices(name, list(cat.keys)))
            continue
        try:
            cat.defaults[name] = from_yaml(cat.keys[name].spec, value)
        except ValueError as exc:
            c.err(("data", name), f"mission data {name!r} {exc}")
    c.mission_data = cat
    return cat


def data_hint(c: Compilation, name: str) -> str:
    """What a guard may write instead of the unknown ``data.…`` name ``name``."""
    key = c.mission_data.keys.get(name[len(DATA_PREFIX):].split("[")[0])
    if key is not None:
        names = guard_names(key)
        if names:
            return f"{key.name!r} holds {key.spec}: compare one of {', '.join(names)}"
        return f"{key.name!r} holds {key.spec}; guards read scalar, flag and fixed-length 1-D array keys only"
    return describe_choices(name, list(c.mission_data.guard_units()))


# -- the must-be-written analysis ---------------------------------------------------------------------

def _writes(n: StateNode) -> frozenset[str]:
    if n.task_cls is None or n.final:
        return frozenset()
    return frozenset(k.name for k in n.task_cls.writes)


def _into(target: StateNode, resume: bool) -> list[StateNode]:
    """The leaves a transition into ``target`` can enter."""
    if target.children and target.history and resume:
        return [d for d in target.walk() if d.is_leaf]
    return target.entry_leaves()  # every region's initial leaf below a parallel state


def _edges(root: StateNode, leaves: list[StateNode]) -> dict[str, set[str]]:
    """Leaf path → the leaf paths it can be entered from (see the module's docstring)."""
    preds: dict[str, set[str]] = {leaf.path: set() for leaf in leaves}
    for s in leaves:
        if s.final:
            parent = s.parent
            if parent is not None and parent.owns is not None:  # a region finishes into its parallel state
                parent = parent.parent
            if parent is None or parent.parent is None:
                continue
            targets = parent.entry_leaves() if parent.loop else []
            outcomes = finishing_outcomes(parent)
            for tr in parent.transitions:
                if isinstance(tr, DoneTransition) and any(tr.handles(o) for o in outcomes):
                    targets += _into(tr.target, tr.resume)
        else:
            targets = [d for a in s.ancestors() for tr in a.transitions if not isinstance(tr, DoneTransition)
                       for d in _into(tr.target, tr.resume)]
        for d in targets:
            preds[d.path].add(s.path)
    return preds


def _written_on_entry(starts: set[str], leaves: list[StateNode], preds: dict[str, set[str]],
                      defaults: frozenset[str], universe: frozenset[str]) -> dict[str, frozenset[str]]:
    """Leaf path → the keys written on every path into it (greatest fixed point; unreachable leaves keep all)."""
    by_path = {leaf.path: leaf for leaf in leaves}
    written = {leaf.path: universe for leaf in leaves}
    if not universe:  # nothing is written or read: every leaf's set is empty already
        return written
    writes = {p: _writes(leaf) for p, leaf in by_path.items()}  # once per leaf, not once per edge and pass
    succs: dict[str, set[str]] = {p: set() for p in by_path}
    for d, ps in preds.items():
        for p in ps:
            succs[p].add(d)
    work = deque(by_path)
    while work:
        p = work.popleft()
        ins = [written[q] | writes[q] for q in preds[p]]
        if p in starts:
            ins.append(defaults)
        new = frozenset.intersection(*ins) if ins else universe
        if new != written[p]:
            written[p] = new
            work.extend(succs[p])
    return written


def _witness(key: str, leaf: StateNode, starts: set[str], preds: dict[str, set[str]],
             by_path: dict[str, StateNode], written: dict[str, frozenset[str]]) -> list[str]:
    """A shortest path of leaves from the start to ``leaf`` on which no state writes ``key``."""
    back: dict[str, str | None] = {leaf.path: None}
    queue = deque([leaf.path])
    while queue:
        p = queue.popleft()
        if p in starts:
            out: list[str] = []
            cur: str | None = p
            while cur is not None:
                out.append(cur)
                cur = back[cur]
            return out
        for q in sorted(preds[p]):
            if q not in back and key not in written[q] and key not in _writes(by_path[q]):
                back[q] = p
                queue.append(q)
    return [leaf.path]


def check_dataflow(c: Compilation, root: StateNode) -> None:
    """Every key a state reads is written on every path into it, or has a default (a problem at the reading
    task or guard naming a path on which it is not)."""
    cat = c.mission_data
    leaves = [n for n in root.walk() if n.is_leaf and n is not root]
    if not leaves or root.initial is None:
        return
    starts = {leaf.path for leaf in root.children[root.initial].entry_leaves()}
    preds = _edges(root, leaves)
    by_path = {leaf.path: leaf for leaf in leaves}
    universe = frozenset(cat.keys)
    written = _written_on_entry(starts, leaves, preds, frozenset(cat.defaults), universe)
    writers = {name: sorted({n.task_cls.name for n in leaves if name in _writes(n) and n.task_cls is not None})
               for name in cat.keys}

    def missing(key: str, leaf: StateNode, what: str, where: tuple[Any, ...]) -> None:
        path = " → ".join(["(start)", *_witness(key, leaf, starts, preds, by_path, written)])
        by = ", ".join(writers[key]) or "no task of this mission"
        c.err(where, f"{what} reads mission data {key!r}, which is not written on every path into state "
              f"{leaf.path!r}: not on {path}",
              f"it is written by {by}: enter this state only after a state that writes it, or give it a value "
              f"in the mission's `data:` block")

    for leaf in leaves:
        if leaf.final or leaf.task_cls is None:
            continue
        task = f"task {leaf.task_cls.name!r} of state {leaf.path!r}"
        named = leaf.task_ypath + ("name",)  # `task: {name: …}`, else `task: NAME`
        for key in leaf.task_cls.reads:
            if key.name not in written[leaf.path]:
                missing(key.name, leaf, task, named if named in c.smap.marks else leaf.task_ypath)
        for name, sub in data_refs(leaf.task_params):
            if name in cat.keys and name not in written[leaf.path]:
                missing(name, leaf, f"{task} (parameter $data.{name})", leaf.task_ypath + ("params",) + sub)
    for n in root.walk():
        for i, tr in enumerate(n.transitions):
            guard = tr.guard if isinstance(tr, (GuardTransition, EventTransition)) else None
            if guard is None:
                continue
            for name in sorted(guard.data):
                for leaf in (d for d in n.walk() if d.is_leaf and not d.final):
                    if name not in written[leaf.path] and name not in _writes(leaf):
                        missing(name, leaf, f"the guard {guard.text!r} of state {n.path!r}",
                                n.ypath + ("transitions", i, "when"))
                        break

