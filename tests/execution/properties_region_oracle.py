"""The oracle of tests/execution/test_properties_regions.py: a small, separate implementation of the
documented semantics of parallel regions, blends and history (docs/missions.md) that reads only the
generated document."""

from __future__ import annotations

import math
from typing import Any

from properties_machines import GUARDS, RATE_HZ


class _ONode:
    """The oracle's view of one state, read from the generated document."""

    def __init__(self, name: str, path: str, parent: _ONode | None, spec: dict[str, Any]) -> None:
        self.name, self.path, self.parent, self.spec = name, path, parent, spec
        self.depth = 0 if parent is None else parent.depth + 1
        self.final: str | None = None
        if "final" in spec:
            self.final = "succeeded" if spec["final"] is True else spec["final"]
        self.children: dict[str, _ONode] = {}
        self.parallel = "regions" in spec
        self.history = bool(spec.get("history"))
        self.owns: tuple[str, ...] | None = None  # a region's parts (None: not a region)
        self.initial: str | None = spec.get("initial")
        kids = spec.get("regions") or spec.get("states") or {}
        for nm, sub in kids.items():
            child = _ONode(nm, f"{path}.{nm}" if path else nm, self, sub)
            if self.parallel:
                child.owns = tuple(sub.get("owns", ()))
            self.children[nm] = child
        self.transitions: list[dict[str, Any]] = list(spec.get("transitions", []))

    def walk(self) -> list[_ONode]:
        return [self] + [d for c in self.children.values() for d in c.walk()]

    def chain(self) -> list[_ONode]:
        """Root first, down to this state."""
        return ([] if self.parent is None else self.parent.chain()) + [self]

    def inside(self, other: _ONode) -> bool:
        return self.path == other.path or other.parent is None or self.path.startswith(other.path + ".")


def _o_weight(tau: float, duration: float) -> float:
    """h(τ) = ½(1 − cos(π τ / T)), 0 before the switch, 1 after T (docs/missions.md, `blend`)."""
    if tau >= duration:
        return 1.0
    return 0.0 if tau <= 0.0 else 0.5 * (1.0 - math.cos(math.pi * tau / duration))


class _Oracle:
    """The semantics of docs/missions.md for the generated machines, written apart from the executor."""

    def __init__(self, doc: dict[str, Any]) -> None:
        self.root = _ONode("", "", None, doc["machine"])
        self.nodes = {n.path: n for n in self.root.walk() if n.parent is not None}
        self.order = {p: i for i, p in enumerate(self.nodes)}  # declaration order
        self.consts = {p: float(i + 1) for i, p in enumerate(sorted(p for p, n in self.nodes.items()
                                                                      if not n.children and n.final is None))}
        self.active: set[str] = set()  # active leaf paths
        self.entered: dict[str, float] = {}  # active state → sim time of its last entry
        self.history: dict[str, str] = {}
        self.finished: dict[str, dict[str, str]] = {}  # parallel state → region → outcome
        self.blends: dict[str | None, tuple[float, float, dict[str, float], tuple[str, ...] | None]] = {}
        self.last = {"v": 0.0, "w": 0.0}
        self.outcome: str | None = None
        self.fired: list[tuple[int, str, str, bool]] = []  # (tick, destination, cause, resumed)
        self.tick_no = 0
        self.seen: set[str] = set()  # which crossings the run exercised (hypothesis events)

    # -- structure
    def target(self, source: _ONode, to: str) -> _ONode:
        if "." in to:
            return self.nodes[to]
        scope: _ONode | None = source.parent
        while scope is not None:
            if to in scope.children:
                return scope.children[to]
            scope = scope.parent
        raise KeyError(to)

    def domain(self, source: _ONode, target: _ONode) -> _ONode:
        common = self.root
        for a, b in zip(source.chain(), target.chain()):
            if a is not b:
                break
            common = a
        if (common is source or common is target) and common.parent is not None:
            return common.parent
        return common

    def region_of(self, n: _ONode) -> _ONode | None:
        m: _ONode | None = n
        while m is not None and m.owns is None:
            m = m.parent
        return m

    def entry(self, n: _ONode) -> _ONode:
        while n.children and not n.parallel:
            n = n.children[n.initial]  # type: ignore[index]
        return n

    def leaves(self) -> list[str]:
        return sorted(self.active, key=self.order.__getitem__)

    def is_active(self, n: _ONode) -> bool:
        return any(self.nodes[leaf].inside(n) for leaf in self.active)

    def resume_point(self, n: _ONode) -> str:
        return next(leaf for leaf in self.leaves() if self.nodes[leaf].inside(n))

    # -- changing state
    def go(self, domain: _ONode, dest: _ONode, t: float, cause: str, resumed: bool) -> None:
        leaving = [leaf for leaf in self.leaves() if self.nodes[leaf].inside(domain) and leaf != domain.path]
        for leaf in leaving:  # each history state left records the leaf it is left in
            for a in self.nodes[leaf].chain()[domain.depth + 1:]:
                if a.history:
                    self.history[a.path] = self.resume_point(a)
        self.active.difference_update(leaving)
        for p in [p for p in self.entered if self.nodes[p].inside(domain) and p != domain.path]:
            del self.entered[p]
        for a in dest.chain()[domain.depth + 1:]:
            self.entered[a.path] = t
        entered = [dest]
        if dest.parallel:
            self.finished.pop(dest.path, None)
            entered = []
            for region in dest.children.values():
                self.entered[region.path] = t
                leaf = region
                while leaf.children:
                    leaf = leaf.children[leaf.initial]  # type: ignore[index]
                    self.entered[leaf.path] = t
                entered.append(leaf)
        for leaf in entered:
            self.active.add(leaf.path)
        self.fired.append((self.tick_no, dest.path, cause, resumed))
        if dest.final is not None:
            self.on_final(dest, t)

    def fire(self, source: _ONode, tr: dict[str, Any], t: float, cause: str) -> None:
        target = self.target(source, tr["to"])
        domain = self.domain(source, target)
        dest, resumed = self.entry(target), False
        if target.history and tr.get("resume", True):
            if target.depth > domain.depth and self.is_active(target):  # exit first, then resolve the history
                point = self.nodes[self.resume_point(target)]
                if point.final is None:
                    dest, resumed = point, True
                    self.seen.add("resumed an active history state")
            elif target.path in self.history:
                dest, resumed = self.nodes[self.history[target.path]], True
        if "blend" in tr and cause != "done":
            region = self.region_of(domain)
            if region is None:
                self.blends.clear()
            else:
                self.blends.pop(region.path, None)
            duration = float(tr["blend"].split()[0])
            self.blends[None if region is None else region.path] = (
                t, duration, dict(self.last), None if region is None else region.owns)
            if sum(key is not None for key in self.blends) >= 2:
                self.seen.add("two regions blending at once")
        self.go(domain, dest, t, cause, resumed)

    def on_final(self, leaf: _ONode, t: float) -> None:
        parent, outcome = leaf.parent, leaf.final
        assert parent is not None and outcome is not None
        if parent.owns is not None:  # a region finished
            parallel = parent.parent
            assert parallel is not None
            done = self.finished.setdefault(parallel.path, {})
            done[parent.name] = outcome
            result = None
            for out, need in parallel.spec.get("outcome_map", {}).items():
                if all(done.get(r) == o for r, o in need.items()):
                    result = out
                    break
            if result is None and outcome != "succeeded":
                result = outcome
            if result is None and len(done) == len(parallel.children):
                result = "succeeded"
            if result is not None:
                self.complete(parallel, result, t)
        elif parent.parent is None:
            self.outcome = outcome
        else:
            self.complete(parent, outcome, t)

    def complete(self, node: _ONode, outcome: str, t: float) -> None:
        for tr in node.transitions:
            if "done" in tr and (tr["done"] is True or tr["done"] == outcome):
                self.fire(node, tr, t, "done")
                return
        self.outcome = outcome

    # -- a tick
    def holds(self, source: _ONode, tr: dict[str, Any], t: float, metrics: dict[str, float], events: set[str]) -> bool:
        if "when" in tr:
            return bool(GUARDS[tr["when"]](metrics))
        if "on" in tr:
            return tr["on"] in events
        if "after" in tr:
            after = float(tr["after"].split()[0]) / 1000.0
            return t - self.entered[source.path] + 1e-9 >= after
        return False

    def command(self, t: float) -> dict[str, float]:
        leaves = self.leaves()
        if len(leaves) == 1 and self.region_of(self.nodes[leaves[0]]) is None:
            c = self.consts.get(leaves[0], 0.0)
            cmd = {"v": c, "w": c}
        else:
            cmd = {"v": 0.0, "w": 0.0}
            for leaf in leaves:
                region = self.region_of(self.nodes[leaf])
                assert region is not None and region.owns is not None
                for k in region.owns:
                    if leaf in self.consts:
                        cmd[k] = self.consts[leaf]
        for key, (t0, duration, old, parts) in list(self.blends.items()):
            h = _o_weight(t - t0, duration)
            if h >= 1.0:
                del self.blends[key]
                continue
            for k in cmd:
                if parts is None or k in parts:
                    cmd[k] = h * cmd[k] + (1.0 - h) * old[k]
        self.last = cmd
        return cmd

    def step(self, k: int, metrics: dict[str, float], events: set[str]) -> dict[str, float]:
        t = k * (1.0 / RATE_HZ)  # the scripted world's clock: ticks times the period
        self.tick_no = k
        cmd = self.command(t)
        seen: set[tuple[str, int]] = set()
        for leaf in self.leaves():
            if self.outcome is not None:
                break
            if leaf not in self.active:
                continue  # a transition this tick left it
            for a in self.nodes[leaf].chain()[1:]:
                fired = False
                for i, tr in enumerate(a.transitions):
                    if "done" in tr or (a.path, i) in seen:
                        continue
                    seen.add((a.path, i))
                    if self.holds(a, tr, t, metrics, events):
                        self.fire(a, tr, t, "guard" if "when" in tr else "event" if "on" in tr else "timeout")
                        fired = True
                        break
                if fired:
                    break
        return cmd

    def start(self) -> None:
        first = self.root.children[self.root.initial]  # type: ignore[index]
        self.go(self.root, self.entry(first), 0.0, "start", False)
