"""The outcome rules of the statechart: how a parallel state and a ``foreach`` finish, what an operator
pre-emption records of a rule it left undecided, and how the run's end weighs those verdicts.

* a parallel state finishes by the first ``outcome_map`` rule whose regions have all finished so, else at once
  with a region's outcome other than ``succeeded``, else ``succeeded`` once every region has (SMACH's
  Concurrence, with the statechart rule): :func:`parallel_outcome`;
* a ``foreach`` succeeds when its items so far meet its ``require`` rule: :func:`loop_verdict`;
* an operator pre-emption (:class:`Preemption`) that leaves a ``foreach`` or parallel state before its own rule
  decided it records what that rule gives at that moment (:class:`SkippedRule`); a run that then reaches a
  ``succeeded`` final ends with the first such verdict that is not ``succeeded`` (:func:`end_verdict`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from taskflow.mission.model import Loop, StateNode

__all__ = ["Preemption", "SkippedRule", "end_verdict", "loop_verdict", "parallel_outcome", "parallel_verdict"]


def parallel_outcome(parallel: StateNode, finished: dict[str, str]) -> str | None:
    """How the parallel state finishes given the outcomes of the regions that have (region name → outcome):
    the first ``outcome_map`` rule whose regions all finished so, else a region's outcome other than
    ``succeeded``, else ``succeeded`` once every region has finished; None while it goes on."""
    result = next((out for out, need in parallel.outcome_map if all(finished.get(r) == o for r, o in need.items())),
                  None)
    if result is None:
        result = next((o for o in finished.values() if o != "succeeded"), None)
    if result is None and len(finished) == len(parallel.children):
        result = "succeeded"
    return result


def loop_verdict(loop: Loop, succeeded: int, n: int) -> tuple[str, str]:
    """What a ``foreach`` over ``n`` items of which ``succeeded`` did gives by its rule, and why."""
    return ("succeeded" if succeeded >= loop.required else "failed",
            f"{succeeded} of {n} items succeeded, its rule requires {loop.required} ({loop.rule})")


def parallel_verdict(parallel: StateNode, finished: dict[str, str]) -> tuple[str, str]:
    """What the rule of a parallel state gives now, its unfinished regions counted ``aborted`` (how a region
    pre-empted mid-way ends), and why."""
    result = parallel_outcome(parallel, {r: finished.get(r, "aborted") for r in parallel.children})
    assert result is not None  # every region has an outcome
    running = [r for r in parallel.children if r not in finished]
    return result, f"regions {', '.join(map(repr, running))} had not finished (counted aborted): {result}"


@dataclass(frozen=True)
class Preemption:
    """One operator pre-emption: sim time ``t``, ``who`` asked, the state path it went ``to`` (None: the run
    was aborted) and the active configuration it left (``source``) — the summary's ``preempted`` list."""

    t: float
    who: str
    to: str | None
    source: str

    def as_dict(self) -> dict[str, Any]:
        return {"t": round(self.t, 9), "who": self.who, "to": self.to, "from": self.source}


@dataclass(frozen=True)
class SkippedRule:
    """A ``foreach`` or parallel state a pre-emption left before its success rule decided it: the outcome
    that rule gives at that moment (``verdict``) and why, in words, naming the pre-emption."""

    verdict: str
    why: str
    by: Preemption


def end_verdict(outcome: str, why: str, skipped: Iterable[SkippedRule],
                preemptions: Iterable[Preemption]) -> tuple[str, str]:
    """The run's outcome and reason when the machine ends it with ``outcome`` (because ``why``): a ``succeeded``
    one stands only if no rule a pre-emption skipped gives otherwise; the reason names every pre-emption."""
    bad = None
    if outcome == "succeeded":
        bad = next((s for s in skipped if s.verdict != "succeeded"), None)
        if bad is not None:
            outcome, why = bad.verdict, f"{why}, but the mission's success rule does not hold: {bad.why}"
    for p in preemptions:
        if p.to is not None and (bad is None or p is not bad.by):
            why += f"; pre-empted by {p.who} (operator) to {p.to!r} at t = {p.t:g} s"
    return outcome, why
