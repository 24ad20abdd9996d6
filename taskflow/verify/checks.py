"""The checks of ``taskflow verify``, answered by Storm on the model of :mod:`taskflow.verify.model`.

The model goes to Storm as PRISM text (:mod:`taskflow.verify.export`; the same text ``--export prism``
writes), twice: as it is, and under sensor loss (only the steps that need no guard and no event, every
configuration initial).  Storm computes, for every configuration, the probabilities and expected times the
checks ask for (the MDP's nondeterminism resolved for the best or the worst, as each check says); the verdicts
are read off those values and, where a check fails, a counterexample is a shortest path of the model to the
configuration that fails it.

* ``no_trap`` — from every reachable configuration some final state is reachable (``Pmax>0 [F final]``: a
  cooperative environment can always end the run);
* ``timed_exit`` — with every guard false and no event, every reachable configuration still reaches a final state
  through its timers (``Pmin=1 [F final]`` under sensor loss); the states that would wait forever are named;
* ``duration`` — the longest time to a final state when only timers fire (``Rmax=? [F final]`` under sensor loss,
  the time reward), from the start and from the worst reachable configuration;
* ``outcomes`` — each outcome of a final state under the root is reachable (``Pmax>0 [F outcome]``), with the
  guards and events its shortest witness needs;
* ``region_conflicts`` — no reachable configuration has two regions' tasks both commanding the robot where a
  region owns no command part (its task's command would be dropped).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from taskflow.mission.model import CompiledMission
from taskflow.mission.yamlsrc import gc_paused
from taskflow.verify.counterexample import Counterexample, describe_step
from taskflow.verify.export import label_name
from taskflow.verify.model import DEFAULT_BUDGET, TICK, Model, Step, build_model
from taskflow.verify.properties import check_properties
from taskflow.verify.results import FAILS, HOLDS, CheckResult
from taskflow.verify.storm import StormModel

__all__ = ["FAILS", "HOLDS", "CheckResult", "StormModel", "Verification", "verify_mission"]

EPS = 1e-9


@dataclass
class Verification:
    """Every check of one mission, and the model they were answered on."""

    mission: CompiledMission
    model: Model
    checks: list[CheckResult]
    build_seconds: float

    @property
    def ok(self) -> bool:
        """Every check holds (a property the model cannot decide — it compares metrics — is left to the runs)."""
        return all(c.verdict != FAILS for c in self.checks)

    def check(self, name: str) -> CheckResult:
        """The check called ``name`` (``property:NAME`` for a declared property); a :class:`KeyError` naming the
        checks there are otherwise."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"{name!r} — valid: {', '.join(c.name for c in self.checks)}")

    def render(self) -> str:
        m = self.model
        lines = [f"{self.mission.file}: {m.n_states} configurations, {m.n_steps} steps, a tick is {m.quantum:g} s "
                 f"(built in {self.build_seconds:.2f} s)"]
        width = max(len(c.name) for c in self.checks)
        for c in self.checks:
            lines.append(f"  {c.name:{width}s}  {c.verdict:5s}  {c.seconds * 1000:7.1f} ms  {c.detail}")
            if c.counterexample is not None:
                lines.append("    counterexample:")
                lines.append(c.counterexample.render(indent="      "))
        return "\n".join(lines)

    def as_dict(self) -> dict[str, Any]:
        m = self.model
        return {"mission": self.mission.name, "file": self.mission.file, "ok": self.ok,
                "model": {"configurations": m.n_states, "steps": m.n_steps, "tick_s": m.quantum,
                          "clocks": [c.name for c in m.clocks], "build_s": round(self.build_seconds, 4)},
                "checks": [c.as_dict() for c in self.checks]}


def _leaves_named(model: Model, configs: set[int] | list[int]) -> list[str]:
    return sorted({leaf for s in configs for leaf in model.configs[s].leaves})


def _cex(model: Model, path: list[tuple[int, Any]] | None, ending: str, highlight: list[str]) -> Counterexample | None:
    return None if path is None else Counterexample(model, path, ending, highlight)


def check_no_trap(model: Model, pmax: list[float]) -> CheckResult:
    traps = [s for s, v in enumerate(pmax) if v <= EPS]
    if not traps:
        return CheckResult("no_trap", HOLDS, f"a final state is reachable from each of the {model.n_states} configurations")
    path = model.path_to(traps)
    end = path[-1][1].target if path else model.initial
    caught = model.reachable(end)
    leaves = _leaves_named(model, caught)
    only_ticks = all(st.cause == TICK and st.target == end for st in model.steps[end])
    ending = (f"it waits in {' | '.join(model.configs[end].leaves)} forever: nothing can fire there" if only_ticks else
              f"no final state can be reached from here: the machine can only move among {', '.join(leaves)}")
    return CheckResult("no_trap", FAILS, f"{len(traps)} of {model.n_states} configurations cannot reach a final state "
                       f"(states: {', '.join(_leaves_named(model, traps))})", _cex(model, path, ending, leaves),
                       data={"trapped": len(traps)})


def _stuck(model: Model, start: int, pmin: list[float]) -> tuple[list[tuple[int, Any]] | None, list[str], str]:
    """Under sensor loss from ``start`` (which fails): the timed path to where it stays, the leaves it waits in."""
    region = model.reachable(start, timed_only=True)
    bad = {s for s in region if pmin[s] < 1.0 - EPS and not model.configs[s].final}
    # a configuration whose only timed step is a tick to itself waits forever; else a cycle of timeouts
    waiting = [s for s in bad if all(st.target == s for st in model.timed_steps(s))]
    if waiting:
        path = model.path_to(waiting, start, timed_only=True)
        end = path[-1][1].target if path else start
        leaves = list(model.configs[end].leaves)
        return path, leaves, f"with every guard false and no event it waits in {' | '.join(leaves)} forever"
    # a cycle: follow timed steps within ``bad`` until a configuration repeats
    s, seen, path = start, {start: 0}, []
    while True:
        step = next(st for st in model.timed_steps(s) if st.target in bad)
        path.append((s, step))
        s = step.target
        if s in seen:
            cycle = _leaves_named(model, [a for a, _ in path[seen[s]:]])
            return path, cycle, f"with every guard false and no event it cycles through {', '.join(cycle)} forever"
        seen[s] = len(path)


def check_timed_exit(model: Model, pmin_loss: list[float]) -> CheckResult:
    failing = [s for s, v in enumerate(pmin_loss) if v < 1.0 - EPS]
    if not failing:
        return CheckResult("timed_exit", HOLDS, "every reachable configuration reaches a final state through its timers "
                           "with every guard false and no event")
    names: set[str] = set()
    for s in failing:
        if all(st.target == s for st in model.timed_steps(s)):
            names.update(model.configs[s].leaves)
    lead = model.path_to(failing) or []
    start = lead[-1][1].target if lead else model.initial
    tail, leaves, ending = _stuck(model, start, pmin_loss)
    names.update(leaves)
    path = lead + (tail or [])
    return CheckResult("timed_exit", FAILS, f"would wait forever with the sensors lost: {', '.join(sorted(names))} "
                       f"({len(failing)} configurations have no timed way out)",
                       Counterexample(model, path, ending, sorted(names)), data={"waits_forever": sorted(names)})


def check_duration(model: Model, rmax_loss: list[float], pmin_loss: list[float]) -> CheckResult:
    start = rmax_loss[model.initial]
    finite = [(v, s) for s, v in enumerate(rmax_loss) if math.isfinite(v)]
    worst_v, worst_s = max(finite) if finite else (math.inf, model.initial)
    if all(math.isfinite(v) for v in rmax_loss):
        return CheckResult("duration", HOLDS, f"with only timers firing the run ends within {start:g} s of the start; "
                           f"from any reachable configuration within {worst_v:g} s (from {model.configs[worst_s].describe()})",
                           data={"from_start_s": start, "worst_s": worst_v})
    unbounded = [s for s, v in enumerate(rmax_loss) if not math.isfinite(v)]
    lead: list[tuple[int, Step]] = [] if math.isinf(start) else (model.path_to(unbounded) or [])
    s0 = lead[-1][1].target if lead else model.initial
    tail, leaves, ending = _stuck(model, s0, pmin_loss) if pmin_loss[s0] < 1.0 - EPS else (None, [], "")
    if tail is None:
        ending = "the worst order of simultaneous timeouts never reaches a final state"
    return CheckResult("duration", FAILS, f"unbounded: {len(unbounded)} configurations never end with only timers firing"
                       + ("" if math.isfinite(start) else ", the start among them"),
                       Counterexample(model, lead + (tail or []), ending, leaves),
                       data={"from_start_s": start if math.isfinite(start) else None})


def declared_outcomes(mission: CompiledMission) -> list[str]:
    """The outcomes of the final states directly under the root, in the order declared."""
    out: list[str] = []
    for n in mission.root.children.values():
        if n.final and n.final not in out:
            out.append(n.final)
    return out


def _needs(model: Model, steps: list[Any]) -> str:
    """What a witness path needs from the environment, in brief: its events by name, its guards by state."""
    events = list(dict.fromkeys(st.event for st in steps if st.cause == "event"))
    guards = list(dict.fromkeys(model.mission.transitions[st.transition].source.path for st in steps
                                if st.cause == "guard" and st.transition is not None))
    parts = ([f"events {', '.join(events)}"] if events else []) + ([f"guards on {', '.join(guards)}"] if guards else [])
    timed = sum(1 for st in steps if st.cause == "timeout")
    if timed:
        parts.append(f"{timed} timeout{'s' if timed != 1 else ''}")
    return "; ".join(parts) if parts else "nothing from the environment"


def check_outcomes(model: Model, reach: dict[str, float]) -> CheckResult:
    lines, missing = [], []
    data: dict[str, Any] = {}
    for o in declared_outcomes(model.mission):
        if reach.get(o, 0.0) <= EPS:
            missing.append(o)
            data[o] = None
            continue
        path = model.path_to([i for i, c in enumerate(model.configs) if c.outcome == o]) or []
        needs = [describe_step(model, st) for _, st in path if st.environment]
        data[o] = needs
        lines.append(f"{o}: {_needs(model, [st for _, st in path])}")
    extra = [o for o in model.outcomes() if o not in declared_outcomes(model.mission)]
    tail = f"; the run can also end {', '.join(extra)} (a composite's outcome no `done` transition handles)" if extra else ""
    if missing:
        reached = ", ".join(model.outcomes()) or "none"
        return CheckResult("outcomes", FAILS, f"never reached: {', '.join(missing)} (reachable: {reached}){tail}",
                           data={"reachable": data})
    return CheckResult("outcomes", HOLDS, "every declared outcome is reachable — " + " | ".join(lines) + tail,
                       data={"reachable": data})


def check_region_conflicts(model: Model) -> CheckResult:
    states = model.mission.states
    seen: set[tuple[str, str]] = set()
    for s, c in enumerate(model.configs):
        driving = []
        for leaf in c.leaves:
            node = states[leaf]
            region = node.region
            if region is None or node.task_cls is None or node.final or not node.task_cls.command_interface:
                continue
            driving.append((node, region))
        for i, (a, ra) in enumerate(driving):
            for b, rb in driving[i + 1:]:
                if ra is rb or (ra.owns and rb.owns):
                    continue
                key = (a.path, b.path)
                if key in seen:
                    continue
                seen.add(key)
                idle = ra if not ra.owns else rb
                task = a if idle is ra else b
                path = model.path_to([s])
                ending = (f"{a.path} ({a.task_cls.__name__ if a.task_cls else ''}) and {b.path} "
                          f"({b.task_cls.__name__ if b.task_cls else ''}) both command the robot's "
                          f"{a.task_cls.command_interface if a.task_cls else ''} interface; region {idle.path!r} owns no "
                          f"command part, so {task.path}'s command is dropped")
                return CheckResult("region_conflicts", FAILS, ending, _cex(model, path, ending, [a.path, b.path]))
    return CheckResult("region_conflicts", HOLDS, "no configuration has two regions' tasks commanding the robot where a "
                       "region owns no part")


def verify_mission(mission: CompiledMission, max_time: float | None = None, *, operator: bool = False,
                   budget: int = DEFAULT_BUDGET, extra: list[Callable[[Model], CheckResult]] | None = None) -> Verification:
    """Build the model of ``mission`` (at most ``budget`` configurations; ``operator``: with the operator's
    pre-emptions and abort as steps) and answer every check (module docstring) with Storm.  Python's collector is
    held off meanwhile (:func:`~taskflow.mission.yamlsrc.gc_paused`, as a load is): the model's configurations and
    steps, by the ten thousand, live until the end, and each collection walked them all again."""
    with gc_paused():
        return _verify(mission, max_time, operator, budget, extra)


def _verify(mission: CompiledMission, max_time: float | None, operator: bool, budget: int,
            extra: list[Callable[[Model], CheckResult]] | None) -> Verification:
    t0 = time.perf_counter()
    model = build_model(mission, max_time, operator=operator, budget=budget)
    build_s = time.perf_counter() - t0
    outcomes = model.outcomes()
    checks: list[CheckResult] = []

    t = time.perf_counter()
    full = StormModel(model)
    pmax = full.values('Pmax=? [F "final"]')
    res = check_no_trap(model, pmax)
    res.seconds = time.perf_counter() - t
    checks.append(res)

    t = time.perf_counter()
    loss = StormModel(model, timed_only=True)
    pmin = loss.values('Pmin=? [F "final"]')
    res = check_timed_exit(model, pmin)
    res.seconds = time.perf_counter() - t
    checks.append(res)
    t = time.perf_counter()
    res = check_duration(model, loss.values('R{"time"}max=? [F "final"]'), pmin)
    res.seconds = time.perf_counter() - t
    checks.append(res)

    t = time.perf_counter()
    reach = {o: full.values(f'Pmax=? [F "{label_name("outcome", o)}"]')[model.initial] for o in outcomes}
    res = check_outcomes(model, reach)
    res.seconds = time.perf_counter() - t
    checks.append(res)

    t = time.perf_counter()
    res = check_region_conflicts(model)
    res.seconds = time.perf_counter() - t
    checks.append(res)
    for res in check_properties(model):
        checks.append(res)
    for fn in extra or ():
        t = time.perf_counter()
        res = fn(model)
        res.seconds = time.perf_counter() - t
        checks.append(res)
    return Verification(mission, model, checks, build_s)
