"""Random but valid missions, and random scripts to drive them: the material of the abstraction test
(``test_abstraction.py``) and of ``benchmarks/verify.py``.

:func:`generate` writes a mission YAML text from a seed: a machine on the toy robot ``toy_pair`` and the toy
world ``toy_line`` (``tests/toys.py``; the scripted backend replaces both when it drives the machine, but the
mission must load, so every name is a registered one) with nested composites, ``history: true``, ``foreach``
loops (``require`` rules, ``on_failure: continue|stop``, ``retry``), parallel ``regions`` (``owns``, ``outcome_map``),
guards (``when``, some with ``for:`` dwells), ``after`` timeouts (``since:`` an enclosing state or
``first_entry``), ``on:`` events (the world's, the mission's declared ones, an action's end), ``done``
transitions by outcome, and finals with several outcomes.  Every state is reachable (each composite's
children form a chain from its initial state) and every composite that can finish has a ``done``
transition for each outcome it can finish with, as the loader requires.

:func:`random_script` draws a :class:`~taskflow.testing.Script` for a loaded mission: metric values on
either side of the thresholds its guards compare them with, redrawn per active state and time window;
the world's and the mission's events at random times; the world's actions ending after random delays
with a random one of their end events.  Only events that can arrive in any configuration are scheduled
(a task's events come from its task, an action's from the world when the action runs).
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import yaml

from taskflow.mission.model import CompiledMission, EventTransition, GuardTransition
from taskflow.testing import Script, ScriptState

OUTCOMES = ("succeeded", "failed", "aborted")
WORLD_EVENTS = ("target_lost", "target_found")  # toy_line's
MISSION_EVENTS = ("go_on", "halt")  # declared by every generated mission (`events:`)
ACTION, ACTION_ENDS = "tool", ("tool_done", "tool_failed")  # toy_line's one action
PARTS = ("v", "w")  # toy_pair's command parts
ITEMS = {"items1": [1], "items2": [1, 2], "items3": [1, 2, 3]}
AFTERS = (0.5, 1.0, 1.5, 2.0, 3.0)
DWELLS = (0.1, 0.25, 0.5, 1.0)


@dataclass
class _Node:
    name: str
    kind: str  # leaf | final | plain | foreach | parallel | region
    parent: _Node | None = None
    children: list[_Node] = field(default_factory=list)
    outcome: str = "succeeded"  # a final's
    history: bool = False
    loop: dict[str, Any] | None = None
    owns: list[str] = field(default_factory=list)
    outcome_map: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    task: bool = False  # runs toy_goto (publishes pos_error)
    action: bool = False
    transitions: list[dict[str, Any]] = field(default_factory=list)

    @property
    def composite(self) -> bool:
        return self.kind in ("plain", "foreach", "parallel", "region")

    def path(self) -> str:
        names: list[str] = []
        n: _Node | None = self
        while n is not None and n.parent is not None:
            names.append(n.name)
            n = n.parent
        return ".".join(reversed(names))

    def ancestors(self) -> list[_Node]:
        out: list[_Node] = []
        n = self.parent
        while n is not None:
            out.append(n)
            n = n.parent
        return out

    def walk(self) -> list[_Node]:
        out = [self]
        for c in self.children:
            out += c.walk()
        return out

    def in_region(self) -> bool:
        return any(a.kind == "region" for a in self.ancestors())

    def regions_above(self) -> set[int]:
        return {id(a) for a in [self, *self.ancestors()] if a.kind == "region"}


class _Generator:
    def __init__(self, seed: int, size: int | None, p_parallel: float, p_history: float, p_foreach: float,
                 p_since: float, p_retry: float) -> None:
        self.rng = random.Random(seed)
        self.retry_rng = random.Random(f"retry {seed}")  # its own stream: the machines without retry stay as they were
        self.p_retry = p_retry
        self.p_foreach = p_foreach
        self.p_since = p_since
        self.p_parallel = p_parallel
        self.p_history = p_history
        self.seed = seed
        self.size = size if size is not None else self.rng.randint(3, 50)
        self.count = 0

    def name(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}{self.count}"

    # -- the tree --------------------------------------------------------------------------------------------
    def fill(self, node: _Node, budget: int, depth: int) -> None:
        """Give composite ``node`` children using about ``budget`` states."""
        rng = self.rng
        if node.kind == "parallel":
            self.fill_parallel(node, budget, depth)
            return
        if node.parent is None or node.kind == "foreach":
            n_finals = rng.randint(1, 3)
        else:
            n_finals = rng.choice((0, 1, 1, 2, 2, 3))
        remaining = max(1, budget - n_finals)
        width = max(6, budget // 8)
        nonfinal: list[_Node] = []
        while remaining > 0 and len(nonfinal) < width:
            if remaining >= 3 and depth < 5 and rng.random() < 0.4:
                sub = rng.randint(2, max(2, min(remaining - 1, max(3, int(budget * 0.6)))))
                child = _Node(self.name("s"), self.composite_kind(node), node)
                self.fill(child, sub, depth + 1)
                used = len(child.walk())
            else:
                child = _Node(self.name("s"), "leaf", node)
                child.task = not node.in_region() and node.kind != "region" and rng.random() < 0.3
                child.action = not child.task and not node.in_region() and node.kind != "region" and rng.random() < 0.15
                used = 1
            nonfinal.append(child)
            remaining -= used
        finals = [_Node(self.name("f"), "final", node, outcome=rng.choice(OUTCOMES)) for _ in range(n_finals)]
        if node.parent is None and not any(f.outcome == "succeeded" for f in finals) and rng.random() < 0.7:
            finals[0].outcome = "succeeded"
        node.children = nonfinal + finals
        if node.kind in ("plain", "foreach") and rng.random() < self.p_history:
            node.history = True
        if node.kind == "foreach":
            items = rng.choice(sorted(ITEMS))
            loop: dict[str, Any] = {"in": items, "as": f"it{self.count}"}
            if rng.random() < 0.6:
                loop["on_failure"] = "continue"
                n = len(ITEMS[items])
                loop["require"] = rng.choice(["all", rng.randint(1, n), f"{rng.choice((34, 50, 100))} %"])
            elif rng.random() < 0.5:
                loop["on_failure"] = "stop"
            failing = [f.name for f in finals if f.outcome != "succeeded"]
            if failing and self.retry_rng.random() < self.p_retry:
                times = self.retry_rng.randint(1, 2)
                named = self.retry_rng.random() < 0.5
                loop["retry"] = {"times": times, "on": self.retry_rng.sample(failing, self.retry_rng.randint(1, len(failing)))} \
                    if named else times
            node.loop = loop

    def composite_kind(self, parent: _Node) -> str:
        r = self.rng.random()
        inside = parent.kind == "region" or parent.in_region()
        if r < self.p_parallel and not inside:
            return "parallel"
        return "foreach" if r < self.p_parallel + self.p_foreach else "plain"

    def fill_parallel(self, node: _Node, budget: int, depth: int) -> None:
        rng = self.rng
        k = rng.randint(2, 3)
        parts = list(PARTS)
        rng.shuffle(parts)
        regions = []
        for _ in range(k):
            region = _Node(self.name("r"), "region", node)
            if parts and rng.random() < 0.7:
                region.owns = [parts.pop()]
            self.fill(region, max(2, (budget - 1) // k), depth + 1)
            regions.append(region)
        node.children = regions
        with_finals = [r for r in regions if any(c.kind == "final" for c in r.children)]
        if with_finals and rng.random() < 0.6:
            r = rng.choice(with_finals)
            f = rng.choice([c for c in r.children if c.kind == "final"])
            node.outcome_map.append((rng.choice(OUTCOMES), {r.name: f.outcome}))

    # -- the outcomes a composite can finish with (taskflow.mission.compile.structure.finishing_outcomes) -----
    def finishing(self, n: _Node) -> set[str]:
        if n.kind == "parallel":
            out = {o for o, _ in n.outcome_map}
            every = [self.finishing(r) for r in n.children]
            for outcomes in every:
                out |= {o for o in outcomes if o != "succeeded"}
            if every and all("succeeded" in o for o in every):
                out.add("succeeded")
            return out
        out = {c.outcome for c in n.children if c.kind == "final"}
        if n.loop is not None and n.loop.get("on_failure") == "continue":
            out = ({"succeeded"} & out) | ({"failed"} if out - {"succeeded"} else set())
        return out

    # -- transitions -----------------------------------------------------------------------------------------
    def targets(self, root: _Node, source: _Node) -> list[_Node]:
        """States ``source`` may target: not a region, not inside a region ``source`` is not in."""
        mine = source.regions_above()
        return [n for n in root.walk()[1:] if n.kind != "region" and n.regions_above() <= mine]

    def guard(self, node: _Node) -> str:
        rng = self.rng
        atoms = [f"visible {rng.choice(('>', '<', '>=', '<='))} {rng.choice((0.2, 0.5, 0.8))}"]
        if node.task and rng.random() < 0.6:
            atoms.append(f"pos_error {rng.choice(('<', '>'))} {rng.choice((1, 2, 5))} cm")
        if len(atoms) == 2 and rng.random() < 0.5:
            return f"{atoms[0]} {rng.choice(('and', 'or'))} {atoms[1]}"
        if rng.random() < 0.15:
            return f"not ({atoms[-1]})"
        return atoms[-1]

    def trigger(self, node: _Node) -> dict[str, Any]:
        rng = self.rng
        r = rng.random()
        if r < 0.4:
            tr: dict[str, Any] = {"when": self.guard(node)}
            if rng.random() < 0.25:
                tr["for"] = f"{rng.choice(DWELLS)} s"
            return tr
        if r < 0.7:
            tr = {"after": f"{rng.choice(AFTERS)} s"}
            enclosing = [a for a in node.ancestors() if a.parent is not None and a.kind != "region"]
            s = rng.random()
            if s < self.p_since:  # (a first_entry clock runs on while its state is left: it multiplies the model most)
                tr["since"] = "first_entry"
            elif s < 2 * self.p_since and enclosing:
                tr["since"] = rng.choice(enclosing).name
            return tr
        tr = {"on": rng.choice(WORLD_EVENTS + MISSION_EVENTS)}
        if rng.random() < 0.2:
            tr["when"] = self.guard(node)
        return tr

    def wire(self, root: _Node) -> None:
        rng = self.rng
        for n in root.walk():
            if not n.composite:
                continue
            if n.kind != "parallel":
                nonfinal = [c for c in n.children if c.kind != "final"]
                finals = [c for c in n.children if c.kind == "final"]
                chain = nonfinal + finals[:1]
                for a, b in zip(chain, chain[1:]):  # reachability: a chain from the initial state
                    a.transitions.append({"to": b.path(), **self.trigger(a)})
                for f in finals[1:]:
                    src = rng.choice(nonfinal)
                    src.transitions.append({"to": f.path(), **self.trigger(src)})
            if n.parent is not None and n.kind != "region":
                outcomes = sorted(self.finishing(n))
                # a sibling, or a state outside ``n`` that is not final: entering a final state elsewhere could
                # finish a composite whose `done` leads back into ``n``'s (an instantaneous cycle, which the
                # loader accepts and the engine recurses on until Python's limit)
                siblings = [c for c in n.parent.children if c is not n] if n.parent.kind != "parallel" else []
                inside = n.path() + "."
                choices = siblings + [t for t in self.targets(root, n) if t.kind != "final" and t is not n
                                      and not t.path().startswith(inside) and t not in siblings]
                if outcomes:
                    if rng.random() < 0.4:
                        n.transitions.append({"to": rng.choice(choices).path(), "done": True})
                    else:
                        for o in outcomes:
                            n.transitions.append({"to": rng.choice(choices).path(), "done": o})
        for n in root.walk()[1:]:
            if n.kind in ("final", "region"):
                continue
            if n.action:
                for ev in ACTION_ENDS:
                    if rng.random() < 0.8:
                        n.transitions.append({"to": rng.choice(self.targets(root, n)).path(), "on": ev})
            for _ in range(rng.choice((0, 0, 1, 1, 2))):
                n.transitions.append({"to": rng.choice(self.targets(root, n)).path(), **self.trigger(n)})
            if not n.transitions and not n.composite:  # a leaf with no way out of its own: leave somewhere
                n.transitions.append({"to": rng.choice(self.targets(root, n)).path(), **self.trigger(n)})
            rng.shuffle(n.transitions)

    # -- the YAML --------------------------------------------------------------------------------------------
    def spec(self, n: _Node) -> dict[str, Any]:
        if n.kind == "final":
            return {"final": n.outcome}
        out: dict[str, Any] = {}
        if n.kind == "region" and n.owns:
            out["owns"] = list(n.owns)
        if n.task:
            out["task"] = {"name": "toy_goto", "params": {"target": 1.0}}
            out["bind"] = {"gains": {"kp": 1.0}}
        if n.action:
            out["action"] = {"name": ACTION}
        if n.history:
            out["history"] = True
        if n.loop is not None:
            out["foreach"] = dict(n.loop)
        if n.kind == "parallel":
            out["regions"] = {c.name: self.spec(c) for c in n.children}
            if n.outcome_map:
                out["outcome_map"] = {o: dict(need) for o, need in n.outcome_map}
        elif n.children:
            out["initial"] = n.children[0].name
            out["states"] = {c.name: self.spec(c) for c in n.children}
        if n.transitions:
            out["transitions"] = n.transitions
        return out

    def text(self) -> str:
        root = _Node("machine", "plain")
        self.fill(root, self.size, 0)
        self.wire(root)
        doc = {
            "mission": f"generated_{self.seed}",
            "description": f"tests/verify/machines.py generate(seed={self.seed}, size={self.size})",
            "robot": "toy_pair",
            "world": "toy_line",
            "rate_hz": 20,
            "max_time": "120 s",
            "events": list(MISSION_EVENTS),
            "parameters": {k: list(v) for k, v in ITEMS.items()},
            "machine": {"initial": root.children[0].name, "states": {c.name: self.spec(c) for c in root.children}},
        }
        return yaml.safe_dump(doc, sort_keys=False, width=200)


def generate(seed: int, size: int | None = None, *, p_parallel: float = 0.15, p_history: float = 0.3,
             p_foreach: float = 0.25, p_since: float = 0.1, p_retry: float = 0.25) -> str:
    """A valid mission YAML text drawn from ``seed``: about ``size`` states (default: 3 to 50, drawn).  A composite
    is a parallel state with probability ``p_parallel`` (outside regions), a ``foreach`` with ``p_foreach``, and
    has ``history: true`` with ``p_history``; a ``foreach`` with a final that does not succeed retries with
    ``p_retry`` (``retry: N`` or ``retry: {times: N, on: [...]}``, N of 1 or 2; drawn from a stream of its own, so
    ``p_retry=0`` gives the machines of before retry existed); a timeout counts ``since: first_entry`` with ``p_since`` (and since an
    enclosing state with ``p_since`` again).  Those multiply the model's configurations (a region's clocks and
    leaves, a history's resume point, a loop's counters, a first-entry clock: each is kept while its state is
    not active), so a large machine keeps them rare."""
    return _Generator(seed, size, p_parallel, p_history, p_foreach, p_since, p_retry).text()


def generate_large(size: int, seed: int = 0) -> str:
    """A machine of about ``size`` states for timing the load path at scale (``benchmarks/loading.py``,
    ``benchmarks/lsp.py``): nested composites, guards, timeouts and events, but no parallel, history, foreach or
    ``since`` clocks (which only multiply a verification model's configurations)."""
    return generate(seed, size, p_parallel=0.0, p_history=0.0, p_foreach=0.0, p_since=0.0)


# -- driving a generated (or any) machine at random ------------------------------------------------------------
def thresholds(mission: CompiledMission) -> dict[str, list[float]]:
    """Each metric the mission's guards compare, with the values (base units) they compare it with."""
    out: dict[str, set[float]] = {}
    for tr in mission.transitions:
        guard = tr.guard if isinstance(tr, (GuardTransition, EventTransition)) else None
        if guard is None:
            continue
        for c in guard.comparisons():
            value = c.value
            if value is None and c.param is not None:
                raw = mission.spec.parameters.get(c.param)
                value = float(raw) if isinstance(raw, (int, float)) else None
            out.setdefault(c.metric, set()).update(() if value is None else (value,))
    return {k: sorted(v) for k, v in out.items()}


def random_script(mission: CompiledMission, rng: random.Random, horizon: float) -> Script:
    """A random environment for ``mission`` over ``horizon`` simulated seconds (module docstring)."""
    table = thresholds(mission)
    values = {m: sorted({v + d for v in vs for d in (-1e-3, 0.0, 1e-3)} | {-1e3, 1e3}) for m, vs in table.items()}
    window = rng.choice((0.05, 0.1, 0.25, 0.5, 1.0, 2.0))
    present = rng.uniform(0.3, 1.0)  # how often a metric has a value at all (a missing one makes comparisons false)
    cache: dict[tuple[str, int], dict[str, float]] = {}

    def metrics(s: ScriptState) -> Mapping[str, float]:
        key = (s.state, int(math.floor(s.t / window + 1e-9)))
        got = cache.get(key)
        if got is None:
            got = cache[key] = {m: rng.choice(vs) for m, vs in values.items() if rng.random() < present}
        return got

    always = sorted(set(mission.world_cls.events) | set(mission.spec.events))
    n_events = rng.randint(0, max(1, int(horizon)))
    events = sorted((round(rng.uniform(0.0, horizon), 3), rng.choice(always)) for _ in range(n_events)) if always else []

    def action(ends: tuple[str, ...]) -> Any:
        def end(params: Mapping[str, Any]) -> tuple[float, str]:
            return rng.choice((0.05, 0.2, 0.5, 1.0, 3.0)), rng.choice(ends)
        return end

    actions = {name: action(tuple(ends)) for name, ends in mission.world_cls.actions.items() if ends}
    return Script(metrics=metrics, events=events, actions=actions)
