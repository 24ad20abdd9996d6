"""Property-based tests of the engine under an operator (hypothesis).

The machines of tests/execution/test_properties_machines.py with a random *operator script* (pause, hold, resume, pre-empt, abort, inject) against
an independent tick-by-tick oracle (`_OperatedOracle`, in properties_operated_oracle.py): every tick's active
leaf, every transition, the entry and operating clocks (hold does not count toward `after`/`for`),
history, the outcome (a pre-emption past a loop's rule cannot succeed), `preempted` and `held_s`.
"""

from __future__ import annotations

from typing import Any

import yaml
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st
from properties_machines import MAX_TIME, machines, scripts
from properties_operated_oracle import _busy_ticks, check_operated_run, operator_scripts

from taskflow.mission.loader import load_mission_text
from taskflow.testing import Script, drive

# -- random operator scripts: an independent oracle of the whole run, tick by tick (issue 20) -----------
#
# The same random machines and scripts, now with a random operator script (pause, hold, resume, preempt to
# any state or abort, inject, at random ticks).  `_OperatedOracle` runs the machine itself from the
# machine's declarations, the script and the operator actions — written from docs/missions.md, not from
# taskflow/execution/ — and must agree with the engine on every tick's active leaf and its entry time, on
# every transition (tick, source, target, cause, resumed), the entry clocks and operating clocks at the end
# (time under hold does not count toward `after` and `for`), the history of every composite, the outcome
# (a pre-emption that leaves a loop before its rule held cannot end the run `succeeded`) and the summary's
# `preempted` and `held_s`.
#
# A transition or pre-emption into a `history` composite that is active at that moment resumes the leaf that
# exit leaves (UML: exit first, then resolve history; it used to resume an older record).


@settings(max_examples=250, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(doc=machines(), script=scripts(), data=st.data())
def test_random_operator_scripts_agree_with_an_independent_oracle(doc: dict[str, Any], script: Script, data: Any) -> None:
    text = yaml.safe_dump(doc, sort_keys=False)
    note(text)
    m = load_mission_text(text, "generated.yaml")
    base = drive(m, script, max_time=MAX_TIME)  # undisturbed: where operator actions would matter
    busy = _busy_ticks(m, script, base.executor.transitions_fired, base.summary["sim_time_s"])
    preferred = sorted(p for p, n in m.states.items() if n.history or (n.final == "succeeded" and n.depth == 1))
    ops = data.draw(operator_scripts(sorted(m.outside_regions), busy, preferred), label="operator script")
    seen: list[tuple[str, float]] = []
    metrics = script.metrics

    def watched(s: Any) -> dict[str, float]:  # the state each observation is taken in (before the tick)
        seen.append((s.state, s.t - s.time_in_state))
        return dict(metrics(s))

    watched_script = Script(metrics=watched, events=script.events, actions=script.actions)
    result = drive(m, watched_script, max_time=MAX_TIME, operator=ops)
    note(str([(r.t, r.source, r.target, r.cause, r.resumed) for r in result.executor.transitions_fired]))
    oracle = check_operated_run(m, result, script, ops, seen)
    event(f"outcome {result.outcome}")
    if oracle.into_active_history:
        event("a transition into an active history composite")
    actions = {a["action"] for a in ops}
    for a in sorted(actions):
        event(f"operator {a}")
    if result.summary.get("held_s", 0) > 0 and any(r.cause == "timeout" for r in result.executor.transitions_fired):
        event("a timeout fired after a hold")
    if any(r.cause == "operator" for r in result.executor.transitions_fired) and result.outcome == "failed":
        event("failed after a pre-emption")
