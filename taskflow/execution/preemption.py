"""What an operator's pre-emption does to the statechart (``taskflow ctl preempt``, :mod:`taskflow.execution.control`).

It leaves every active state for the state it names — its initial leaf, or its history — as a transition
with cause ``operator``, or ends the run ``aborted``.  Every active ``foreach`` or parallel state it leaves
for good before that state's own success rule decided it records what the rule gives at that moment
(:class:`~taskflow.execution.outcomes.SkippedRule`); a run that then reaches a ``succeeded`` final ends with
the first such verdict that is not ``succeeded``.  A pre-emption into a state that reads, on entry, mission
data the run has not written is refused (:meth:`Preemptible.preempt_problem`).
"""

from __future__ import annotations

from taskflow.execution.outcomes import Preemption, SkippedRule, loop_verdict, parallel_verdict
from taskflow.execution.records import OPERATOR
from taskflow.execution.statechart import Statechart
from taskflow.mission.model import StateNode, data_refs

__all__ = ["Preemptible"]


class Preemptible(Statechart):
    """The statechart with the operator's pre-emption."""

    def preempt(self, target: str | None, who: str, t: float) -> None:
        """Operator pre-emption at sim time ``t``: leave every active state (their exits cancel running world
        actions) for the state path ``target`` — its initial leaf, or its history — recorded with cause
        ``operator``; or, with ``target=None``, end the run ``aborted`` (the runtime then stops the robot).

        Every active ``foreach`` or parallel state the pre-emption leaves for good (not the target nor on the
        way into it) has its success rule evaluated now (:meth:`_rule_verdict`); until that state is entered
        afresh or finishes by its own rule, a ``succeeded`` end of the run yields to the first verdict that is
        not (:meth:`_end`)."""
        self.t = t
        by = Preemption(t, who, target, self.state)
        self.preemptions.append(by)
        if target is None:
            self.outcome, self.reason = "aborted", f"pre-empted by {who} (operator)"
            return
        leaf, resumed = self._destination(self.mission.states[target], True, 0)
        staying = {a.path for entered in leaf.entry_leaves() for a in entered.ancestors()}
        for node in self._rule_states():
            if node.path not in staying:
                verdict, why = self._rule_verdict(node)
                self.skipped_rules[node.path] = SkippedRule(
                    verdict, f"{node.path!r} had not finished when {who} (operator) pre-empted the run to {target!r} "
                    f"at t = {t:g} s: {why}", by)
        self._preempting()
        self._go(leaf, OPERATOR, resume=resumed, keep=0, label=f"preempt --to {target}", who=who)

    def _preempting(self) -> None:
        """An operator pre-emption is about to leave the active states: the tick's hook (it drops the blends)."""

    def _rule_states(self) -> list[StateNode]:
        """The active ``foreach`` and parallel states (each once, outermost first)."""
        seen: dict[str, StateNode] = {}
        for leaf in self.leaves:
            for a in leaf.ancestors():
                if a.loop or a.parallel:
                    seen.setdefault(a.path, a)
        return sorted(seen.values(), key=lambda n: n.depth)

    def _rule_verdict(self, node: StateNode) -> tuple[str, str]:
        """What the success rule of the active ``foreach`` or parallel ``node`` gives now, and why."""
        if node.loop is not None:
            return loop_verdict(node.loop, self._states[node.path].items_succeeded, len(self.params[node.loop.items]))
        return parallel_verdict(node, self._region_outcomes.get(node.path, {}))

    def preempt_problem(self, target: str) -> str | None:
        """Why a pre-emption to ``target`` cannot be taken now, or None: a leaf it would enter reads, on
        entry, mission data this run has not written (its task's ``reads``, its ``$data`` parameters)."""
        leaf, _ = self._destination(self.mission.states[target], True, 0)
        data = self.mission.data
        for entered in leaf.entry_leaves():
            if entered.final or entered.task_cls is None:
                continue
            needed = [k.name for k in entered.task_cls.reads]
            needed += [name for name, _ in data_refs(entered.task_params) if name in data.keys]
            for key in needed:
                if key not in self.memory:
                    writers = [n.path for n in self.mission.leaves() if not n.final and n.task_cls is not None
                               and any(k.name == key for k in n.task_cls.writes)]
                    via = f" (entered as {entered.path!r})" if entered is not self.mission.states[target] else ""
                    return (f"preempt: {target!r}{via} reads mission data {key!r} on entry, which this run has "
                            f"not written yet — it is written by {', '.join(map(repr, writers)) or 'no state'}: "
                            "pre-empt to one of those first")
        return None
