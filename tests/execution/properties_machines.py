"""Random valid missions for the property tests of tests/execution/test_properties_*.py (hypothesis):
the toy machines and scripts, the guards with their Python oracles, and the state-tree helpers the
oracles share."""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

from taskflow.mission.model import StateNode
from taskflow.testing import Script

TOY = Path(__file__).parents[1] / "machine" / "missions" / "toy_full.yaml"
RATE_HZ = 20
MAX_TIME = 12.0
EVENTS = ["target_lost", "target_found", "arrived", "tool_done", "tool_failed"]
TOL = 0.04  # the `tol` parameter (4 cm)
# every guard the generator uses, with an independent Python oracle over base-unit metrics
GUARDS: dict[str, Any] = {
    "pos_error < 5 cm": lambda m: m["pos_error"] < 0.05,
    "pos_error >= 0.15 m": lambda m: m["pos_error"] >= 0.15,
    "feature_error > 20 px": lambda m: m["feature_error"] > 20,
    "abs(yaw_error) < 3 deg": lambda m: abs(m["yaw_error"]) < math.radians(3),
    "yaw_error <= -0.1 rad": lambda m: m["yaw_error"] <= -0.1,
    "visible < 50 %": lambda m: m["visible"] < 0.5,
    "visible == 1": lambda m: m["visible"] == 1,
    "pos_error < $tol": lambda m: m["pos_error"] < TOL,
    "not (feature_error > 10 px) or visible != 1": lambda m: not m["feature_error"] > 10 or m["visible"] != 1,
    "(pos_error < 8 cm and abs(yaw_error) < 0.1 rad) or feature_error < 2 px":
        lambda m: (m["pos_error"] < 0.08 and abs(m["yaw_error"]) < 0.1) or m["feature_error"] < 2,
}


# -- generating valid machines ------------------------------------------------------------------------


class _Gen:
    """Builds one machine from hypothesis draws; every state gets a globally unique name."""

    def __init__(self, draw: Any) -> None:
        self.draw = draw
        self.k = 0
        self.items = 0
        self.paths: list[str] = []  # every state path, for random extra transitions
        self.pending: list[dict[str, Any]] = []  # transitions whose target is chosen at the end

    def name(self, prefix: str) -> str:
        self.k += 1
        return f"{prefix}{self.k}"

    def trigger(self, slow: bool = False) -> dict[str, Any]:
        """A random trigger; ``slow`` ones (on composites, into root finals) give inner states time."""
        if slow:
            if self.draw(st.booleans()):
                return {"after": f"{self.draw(st.integers(1, 5))} s"}
            return {"on": self.draw(st.sampled_from(EVENTS))}
        kind = self.draw(st.sampled_from(["after", "on", "when", "when"]))
        if kind == "after":
            return {"after": f"{self.draw(st.integers(1, 40)) * 50} ms"}
        if kind == "on":
            return {"on": self.draw(st.sampled_from(EVENTS))}
        tr: dict[str, Any] = {"when": self.draw(st.sampled_from(sorted(GUARDS)))}
        if self.draw(st.booleans()):
            tr["for"] = f"{self.draw(st.integers(1, 10)) * 0.05:.2f} s"
        return tr

    def transition(self, to: str, slow: bool = False) -> dict[str, Any]:
        tr = {"to": to, **self.trigger(slow)}
        if self.draw(st.integers(0, 5)) == 0:
            tr["resume"] = False
        if self.draw(st.integers(0, 5)) == 0:
            tr["blend"] = "0.2 s"
        return tr

    def extra(self, state: dict[str, Any], slow: bool) -> None:
        """0-2 transitions to any state of the machine (chosen once all states exist)."""
        for _ in range(self.draw(st.integers(0, 2))):
            tr = self.transition("?", slow)
            state.setdefault("transitions", []).append(tr)
            self.pending.append(tr)

    def children(self, path: str, depth: int, in_foreach: list[str]) -> tuple[dict[str, Any], str]:
        """The ``states`` mapping of a machine/composite at ``path`` and its initial state."""
        n_work = self.draw(st.integers(1, 3))
        n_final = self.draw(st.integers(1, 4 - n_work if n_work < 3 else 1))  # 2-4 children
        work = [self.name("s") for _ in range(n_work)]
        finals = [self.name("f") for _ in range(n_final)]
        full = lambda nm: f"{path}.{nm}" if path else nm
        states: dict[str, Any] = {}
        order = work + finals
        for i, nm in enumerate(work):
            self.paths.append(full(nm))
            composite = depth < 3 and self.draw(st.integers(0, depth)) == 0
            st_: dict[str, Any] = {}
            if composite:
                # its `done` transition leads to the next sibling (filled in by `machines`)
                st_ = self.composite(full(nm), depth + 1, in_foreach)
            else:
                if in_foreach and self.draw(st.booleans()):
                    st_["task"] = {"name": "toy_goto", "params": {"target": "$" + in_foreach[-1]}}
                if self.draw(st.integers(0, 4)) == 0:
                    st_["action"] = {"name": "tool"}
                # chain to the next sibling: every state is reachable, every leaf has a way out
                into_root_final = depth == 1 and i + 1 >= len(work)
                st_["transitions"] = [self.transition(full(order[i + 1]), slow=into_root_final)]
            self.extra(st_, slow=composite and self.draw(st.booleans()))
            states[nm] = st_
        # finals beyond the first are reached from a random working sibling
        for nm in finals[1:]:
            src = self.draw(st.sampled_from(work))
            states[src]["transitions"].append(self.transition(full(nm), slow=depth == 1 or "states" in states[src]))
        for nm in finals:
            self.paths.append(full(nm))
            states[nm] = {"final": self.draw(st.sampled_from([True, "succeeded", "failed", "aborted"]))}
        return states, work[0]

    def composite(self, path: str, depth: int, in_foreach: list[str]) -> dict[str, Any]:
        st_: dict[str, Any] = {}
        if self.draw(st.booleans()):
            self.items += 1
            item = f"item{self.items}"
            st_["foreach"] = {"in": "goals", "as": item,
                              "on_failure": self.draw(st.sampled_from(["stop", "continue"]))}
            if st_["foreach"]["on_failure"] == "continue":
                st_["foreach"]["require"] = self.draw(st.sampled_from(["all", 1, "50 %"]))
            in_foreach = [*in_foreach, item]
        if self.draw(st.booleans()):
            st_["history"] = True
        states, initial = self.children(path, depth, in_foreach)
        st_["initial"] = initial
        st_["states"] = states
        # a way to finish, to the next sibling via the chain target: `done: true`, or one `done` per outcome
        # (the loader refuses a composite that can finish with an outcome no `done` handles)
        if self.draw(st.booleans()):
            st_["transitions"] = [{"to": "?done", "done": True}]
        else:
            outcomes = self.draw(st.permutations(["succeeded", "failed", "aborted"]))
            st_["transitions"] = [{"to": "?done", "done": o} for o in outcomes]
        return st_


@st.composite
def machines(draw: Any) -> dict[str, Any]:
    g = _Gen(draw)
    states, initial = g.children("", 1, [])
    # a composite's `done` goes to its next sibling
    def fix(states: dict[str, Any], path: str) -> None:
        names = list(states)
        for i, (nm, s) in enumerate(states.items()):
            for t in s.get("transitions", []):
                if t["to"] == "?done":
                    t["to"] = f"{path}.{names[i + 1]}" if path else names[i + 1]
            fix(s.get("states", {}), f"{path}.{nm}" if path else nm)
    fix(states, "")
    for tr in g.pending:
        tr["to"] = draw(st.sampled_from(g.paths))
    n_goals = draw(st.integers(1, 3))
    return {
        "mission": "prop",
        "robot": "toy_point",
        "world": {"name": "toy_line", "params": {"start": 0.0}},
        "rate_hz": RATE_HZ,
        "max_time": f"{MAX_TIME} s",
        "parameters": {"goals": [float(i + 1) for i in range(n_goals)], "tol": f"{TOL * 100:g} cm"},
        "profiles": {"gains": {"g": {"kp": 1.0}}},
        "machine": {"initial": initial, "task": {"name": "toy_goto", "params": {"target": 0.5}},
                    "bind": {"gains": "g"}, "states": states},
    }


@st.composite
def scripts(draw: Any) -> Script:
    seed = draw(st.integers(0, 2**31 - 1))
    events = draw(st.lists(st.tuples(st.integers(0, int(MAX_TIME * RATE_HZ)).map(lambda k: k / RATE_HZ),
                                     st.sampled_from(EVENTS)), max_size=20))
    tool = (draw(st.sampled_from([0.05, 0.3, 1.0])), draw(st.sampled_from(["tool_done", "tool_failed"])))

    def metrics(s: Any) -> dict[str, float]:  # a function of the tick only, so the checker can replay it
        rng = random.Random(seed * 1_000_003 + round(s.t * RATE_HZ))
        return {"pos_error": rng.uniform(0.0, 0.2), "feature_error": rng.uniform(0.0, 40.0),
                "yaw_error": rng.uniform(-0.2, 0.2), "visible": float(rng.random() < 0.7)}

    return Script(metrics=metrics, events=events, actions={"tool": tool})


# -- invariants ----------------------------------------------------------------------------------------

def _is_under(node: StateNode, ancestor: StateNode) -> bool:
    return ancestor in node.ancestors()


def _metrics_at(script: Script, tick: int) -> dict[str, float]:
    return dict(script.metrics(type("S", (), {"t": tick / RATE_HZ})()))  # type: ignore[arg-type]


def _script_events_at(script: Script, tick: int) -> set[str]:
    """Script events the executor sees at ``tick`` (those due in (t - dt, t]; at t = 0, those due
    at 0 or earlier: test_event_at_time_zero_is_seen)."""
    lo, hi = (tick - 1) / RATE_HZ, tick / RATE_HZ
    return {name for when, name in script.events if lo + 1e-9 < when <= hi + 1e-9}


def _domain_of(tr: Any) -> Any:
    """UML external-transition domain: the common ancestor of source and target, or its parent when
    one contains the other (written here independently of `Transition.domain` in taskflow/mission/model.py)."""
    src, dst = tr.source.ancestors(), tr.target.ancestors()
    common = [a for a, b in zip(src, dst) if a is b][-1]
    if common is tr.source or common is tr.target:
        return common.parent if common.parent is not None else common
    return common
