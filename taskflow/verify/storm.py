"""The model of :mod:`taskflow.verify.model` in Storm's sparse engine (``stormpy``)."""

from __future__ import annotations

from taskflow.verify.export import labels
from taskflow.verify.model import TICK, Model

__all__ = ["StormModel"]


class StormModel:
    """The model in Storm's sparse engine: an MDP with one row group per configuration (Storm state ``i`` is
    configuration ``i``), one row per step (``timed_only``: per step that needs no guard and no event; a
    configuration left with none loops on itself), the labels of :func:`~taskflow.verify.export.labels` and the
    time reward (``quantum`` seconds on every tick).  The same MDP as the PRISM text of
    :func:`~taskflow.verify.export.prism_text` (``tests/verify/test_export.py`` checks that Storm gives the same
    values on both); built here directly, because Storm's PRISM builder evaluates every command's guard in every
    state, which is quadratic in an explicit model's size."""

    def __init__(self, model: Model, *, timed_only: bool = False, extra_labels: dict[str, list[int]] | None = None) -> None:
        import stormpy
        import stormpy.developer as dev

        st = dev.storage
        n = model.n_states
        rows = model._storm_rows.get(timed_only)  # the same for every property checked on the model: built once
        if rows is None:
            builder = st.SparseMatrixBuilder(rows=0, columns=0, entries=0, force_dimensions=False,
                                             has_custom_row_grouping=True, row_groups=0)
            reward: list[float] = []
            row = 0
            for s in range(n):
                builder.new_row_group(row)
                kept = [(x.target, x.cause == TICK) for x in (model.timed_steps(s) if timed_only else model.steps[s])] or [(s, False)]
                for target, tick in sorted(set(kept)):
                    builder.add_next_value(row, target, 1.0)
                    reward.append(model.quantum if tick else 0.0)
                    row += 1
            rows = model._storm_rows[timed_only] = (builder.build(row, n, n), reward)
        matrix, reward = rows
        labeling = st.StateLabeling(n)
        labeling.add_label("init")
        for s in (range(n) if timed_only else [model.initial]):
            labeling.add_label_to_state("init", s)
        for name, states in {**labels(model), **(extra_labels or {})}.items():
            labeling.add_label(name)
            labeling.set_states(name, st.BitVector(n, list(states)))
        components = st.SparseModelComponents(
            transition_matrix=matrix, state_labeling=labeling,
            reward_models={"time": st.SparseRewardModel(optional_state_action_reward_vector=reward)})
        self.model = model
        self.sparse = st.SparseMdp(components)
        self._stormpy = stormpy

    def values(self, formula: str) -> list[float]:
        """Storm's value of ``formula`` (a PRISM property over the labels) in every configuration."""
        prop = self._stormpy.parse_properties(formula)[0]
        result = self._stormpy.model_checking(self.sparse, prop, only_initial_states=False)
        return [float(v) for v in result.get_value_vector()]
