"""The model as text a model checker reads: PRISM (Storm's and PRISM's own language) and JANI (JSON).

Both texts hold the same explicit MDP: one integer variable ``s`` numbering the configurations of
:class:`~taskflow.verify.model.Model` (0: the configuration after the start), one command (PRISM) or edge
(JANI) per step, the action ``tick`` on the steps in which time passes, labels for what the checks ask
(``final``, ``outcome_NAME``, ``active_STATE`` for each state a configuration has active) and the time reward
(``q`` seconds per tick).  ``timed_only=True`` writes the model under sensor loss: only the steps that need
no guard and no event (ticks, timeouts, the max time), every configuration initial.

Open them with Storm's command line (``storm --prism model.prism --prop 'Pmax=? [F "final"]'``, ``storm
--jani model.jani``) or PRISM (``prism model.prism``): the configuration a state number stands for is listed in
the comment above its commands.
"""

from __future__ import annotations

import json
import re
from typing import Any

from taskflow.verify.model import TICK, Model

__all__ = ["jani_text", "label_name", "labels", "prism_text"]


def label_name(kind: str, name: str) -> str:
    """A PRISM/JANI identifier for a label: ``active_cell__operation__searching`` for ``cell.operation.searching``."""
    return f"{kind}_" + re.sub(r"[^A-Za-z0-9_]", "_", name.replace(".", "__"))


def labels(model: Model) -> dict[str, list[int]]:
    """Label → the configurations it holds in: ``final``, ``outcome_NAME`` per outcome, ``active_PATH`` per state
    (computed once per model)."""
    if model._labels:
        return model._labels
    out = model._labels
    out["final"] = model.finals()
    for o in model.outcomes():
        out[label_name("outcome", o)] = [i for i, c in enumerate(model.configs) if c.outcome == o]
    active: dict[str, list[int]] = {}
    for i in range(model.n_states):
        for path in model.active_states(i):
            active.setdefault(path, []).append(i)
    for path in model.mission.states:
        out[label_name("active", path)] = active.get(path, [])
    return out


def _steps(model: Model, s: int, timed_only: bool) -> list[tuple[int, bool]]:
    """(target, is a tick) of each step kept; a final configuration (or one with nothing left) loops on itself."""
    out = [(st.target, st.cause == TICK) for st in (model.timed_steps(s) if timed_only else model.steps[s])]
    return out or [(s, False)]


def _set_expr(states: list[int]) -> str:
    """A PRISM condition on ``s`` true exactly in ``states`` (runs of consecutive numbers as ranges)."""
    if not states:
        return "false"
    parts, run = [], [states[0], states[0]]
    for x in sorted(states)[1:]:
        if x == run[1] + 1:
            run[1] = x
        else:
            parts.append(run)
            run = [x, x]
    parts.append(run)
    return " | ".join(f"s={a}" if a == b else f"(s>={a} & s<={b})" for a, b in parts)


def prism_text(model: Model, *, timed_only: bool = False) -> str:
    n = model.n_states
    m = model.mission
    lines = [f"// taskflow verify: {m.name} ({m.file}); {n} configurations, a tick is {model.quantum:g} s",
             "// " + ("under sensor loss: only ticks, timeouts and the max time; every configuration initial"
                      if timed_only else "every step the machine can take (guards and events: the environment's choice)"),
             "mdp", "", "module machine", f"  s : [0..{max(n - 1, 0)}]{'' if timed_only else ' init 0'};"]
    for s, c in enumerate(model.configs):
        clocks = ", ".join(f"{k.name}={v}" for k, v in zip(model.clocks, c.clocks) if v >= 0)
        lines.append(f"  // {s}: {c.describe()}{'  (clocks: ' + clocks + ')' if clocks else ''}")
        for target, tick in _steps(model, s, timed_only):
            lines.append(f"  [{'tick' if tick else ''}] s={s} -> (s'={target});")
    lines.append("endmodule")
    if timed_only:
        lines += ["", "init true endinit"]
    lines.append("")
    for name, states in labels(model).items():
        lines.append(f'label "{name}" = {_set_expr(states)};')
    lines += ["", 'rewards "time"', f"  [tick] true : {model.quantum!r};", "endrewards", ""]
    return "\n".join(lines)


def _jani_set(states: list[int]) -> Any:
    """A JANI condition on ``s`` true exactly in ``states``: ranges of consecutive numbers, joined as a balanced
    tree of disjunctions (so that a long list does not nest deeply)."""
    if not states:
        return False
    runs: list[list[int]] = []
    for x in sorted(states):
        if runs and x == runs[-1][1] + 1:
            runs[-1][1] = x
        else:
            runs.append([x, x])
    terms: list[Any] = [{"op": "=", "left": "s", "right": a} if a == b else
                        {"op": "∧", "left": {"op": "≥", "left": "s", "right": a}, "right": {"op": "≤", "left": "s", "right": b}}
                        for a, b in runs]
    while len(terms) > 1:
        terms = [{"op": "∨", "left": terms[k], "right": terms[k + 1]} if k + 1 < len(terms) else terms[k]
                 for k in range(0, len(terms), 2)]
    return terms[0]


def jani_text(model: Model, *, timed_only: bool = False) -> str:
    """The model as a JANI document (JSON), with the checks' questions as its properties."""
    n = model.n_states
    edges = []
    for s in range(n):
        for target, tick in _steps(model, s, timed_only):
            dest: dict[str, Any] = {"location": "l", "assignments": [{"ref": "s", "value": target}]}
            if tick:
                dest["assignments"].append({"ref": "time", "value": model.quantum})
            edge: dict[str, Any] = {"location": "l", "guard": {"exp": {"op": "=", "left": "s", "right": s}},
                                    "destinations": [dest]}
            if tick:
                edge["action"] = "tick"
            edges.append(edge)
    lab = labels(model)
    final = _jani_set(lab["final"])

    def reach(op: str, goal: Any) -> Any:
        return {"op": "filter", "fun": "values", "states": {"op": "initial"},
                "values": {"op": op, "exp": {"op": "U", "left": True, "right": goal}}}

    props = [{"name": "reach_final_max", "expression": reach("Pmax", final)},
             {"name": "reach_final_min", "expression": reach("Pmin", final)},
             {"name": "time_to_final_max", "expression": {
                 "op": "filter", "fun": "values", "states": {"op": "initial"},
                 "values": {"op": "Emax", "exp": "time", "accumulate": ["steps"], "reach": final}}}]
    for o in model.outcomes():
        name = label_name("outcome", o)
        props.append({"name": f"reach_{name}", "expression": reach("Pmax", _jani_set(lab[name]))})
    doc: dict[str, Any] = {
        "jani-version": 1, "name": re.sub(r"\W", "_", model.mission.name), "type": "mdp",
        "features": ["derived-operators"],
        "actions": [{"name": "tick"}],
        "variables": [{"name": "s", "type": {"kind": "bounded", "base": "int", "lower-bound": 0,
                                             "upper-bound": max(n - 1, 0)}, **({} if timed_only else {"initial-value": 0})},
                      {"name": "time", "type": "real", "transient": True, "initial-value": 0.0}],
        "properties": props,
        "automata": [{"name": "machine", "locations": [{"name": "l"}], "initial-locations": ["l"], "edges": edges}],
        "system": {"elements": [{"automaton": "machine"}]},
    }
    if timed_only:
        doc["restrict-initial"] = {"exp": True}
    return json.dumps(doc, indent=1, ensure_ascii=False)

