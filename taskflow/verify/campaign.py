"""From a campaign to a prediction: the machine's configurations as an absorbing Markov chain estimated from a
campaign's records, solved with Storm, set beside the campaign's measured rates.

**The chain.** Its states are the configurations the runs' ``transitions.jsonl`` records pass through
(:func:`configuration_of`: the active leaves, one per active region, each active ``foreach``'s item index,
count of items that succeeded and the item's attempt, and the resume point of each history state that is not active — the parts of
the finite model's configuration (:mod:`taskflow.verify.model`) a record determines; the model's clocks are
replaced by the measured times).  Records of one instant that finish what the step before entered (``done``,
``next_item``, ``retry``) are one step, as in the model: a final leaf that is finished at once is no state of the chain,
and a run that the machine ended goes from its last configuration straight to its outcome.  The absorbing
states are the runs' outcomes (``summary.json``: ``succeeded``, ``failed``, ``timeout``, ``aborted`` …).

**Estimate.** ``P(next | current)`` is the count of the step over all runs divided by the visits; each
configuration's time is the mean time between the record that entered it and the one that left it, kept per
successor (a timeout's 45 s and a guard's 5 s are not averaged into one figure: the chain is semi-Markov).
Uncertainty is a posterior, sampled: each row is Dirichlet(count + ½) over the successors seen (Jeffreys'
prior), each mean time a Bayesian bootstrap of its observations (Dirichlet(1, …, 1) weights; Rubin 1981).
Rows, not runs, are resampled because the chain's premise is that a step depends on the configuration only.
A prediction's interval is the posterior's central ``confidence`` interval.  What the campaign has not
explored is reported beside it: ``unseen``, the probability of taking a step no run took when every row
also gives Dirichlet weight ½ to one more successor — not folded into the interval, since where such a step
leads the campaign cannot say, and as a worst case on every row it swamps a 25-step chain (the trolley's
``failed`` would read [15, 100] %).

**Solve.** ``P(outcome)`` is ``P=? [F "outcome_o"]`` and the expected time to it ``R{"time"}=? [F "outcome_o"]``
on the chain conditioned on reaching it (Doob's h-transform: ``P'(i,j) = P(i,j)·h(j)/h(i)``), both answered by
Storm on the estimated chain (:func:`storm_solve`); the posterior samples are solved with the fundamental
matrix ``N = (I − Q)⁻¹`` in numpy (:func:`absorption`; a test checks both give the same values).

**What a comparison can show.** On the runs it was estimated from, the chain's ``P(outcome)`` from the start
equals the measured rate, whatever the machine does: every entry into a configuration is a start or a counted
step, so the visit counts solve ``v = start + v·Q̂`` and the absorption counts are ``v·R̂`` (flow conservation).
That line checks the bookkeeping, and its two intervals say how much 20 runs pin down.  What tests the chain's
premise is the same comparison from every configuration: under the Markov property the runs that once entered
configuration ``c`` end in ``o`` at rate ``h(c)``; when ``c``'s future depends on how the run got there (a
history the abstraction drops), the rate measured over those runs leaves ``h(c)``'s interval.  A disagreement
— the prediction's interval and the measured Wilson interval disjoint — is reported for each configuration and
for each outcome's mean time.  The chain has no clocks: a run cut by ``max_time`` ends by its elapsed time, which
no configuration holds, so the time to ``timeout`` is where a campaign with cut runs disagrees first.
"""

from __future__ import annotations

import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from taskflow.campaigns.campaign import Campaign, CampaignError, Condition
from taskflow.campaigns.stats import mean_interval, wilson_interval
from taskflow.errors import MissionError, Problem
from taskflow.execution.record_io import RunDirError
from taskflow.execution.records import DONE, NEXT_ITEM, RETRY, START_CAUSE, TransitionRecord
from taskflow.mission.data import clean_floats
from taskflow.mission.model import CompiledMission, StateNode
from taskflow.readers.run_files import read_transitions

__all__ = ["CampaignDataError", "CampaignPrediction", "Chain", "Configuration", "absorption", "configuration_of",
           "estimate_chain", "predict", "storm_solve"]

PRIOR = 0.5  # Jeffreys' prior on each successor of a row (the seen ones and one unseen)
SAMPLES = 2000
UNSEEN = "(unseen)"


class CampaignDataError(MissionError):
    """A campaign directory or record the prediction cannot use; each problem names the file (and line)."""


def _problem(text: str, hint: str = "") -> Problem:
    """``FILE[:LINE]: message`` (a reader's one-line error) as a :class:`Problem`."""
    m = re.match(r"^(.*?):(\d+): (.*)$", text, re.S)
    if m:
        return Problem(m.group(1), int(m.group(2)), 1, m.group(3), hint)
    file, _, message = text.partition(": ")
    return Problem(file, 0, 0, message or text, hint)


def _fail(text: str, hint: str = "") -> CampaignDataError:
    return CampaignDataError([_problem(text, hint)])


# -- configurations ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Configuration:
    """What the records say the machine holds: ``leaves`` (one per active region, declaration order),
    ``loops`` (each ``foreach`` that is active or that a history state will resume into: path, item index, items
    succeeded, the item's attempt — 1 but after a ``retry``) and ``history`` (history state not active → where
    it resumes)."""

    leaves: tuple[str, ...]
    loops: tuple[tuple[str, int, int, int], ...] = ()
    history: tuple[tuple[str, str], ...] = ()
    _positions: tuple[tuple[str, int, int, int], ...] = field(default=(), compare=False, repr=False)  # every loop's

    @property
    def label(self) -> str:
        """The leaves as the records join them (`` | ``), then ``{loop: item i, k ok}`` (``, attempt a`` after a
        retry) and ``(history → leaf)``."""
        text = " | ".join(self.leaves)
        if self.loops:
            text += " {" + ", ".join(f"{p.rsplit('.', 1)[-1]}: item {i}, {k} ok" + (f", attempt {a}" if a > 1 else "")
                                     for p, i, k, a in self.loops) + "}"
        if self.history:
            text += " (" + ", ".join(f"{h.rsplit('.', 1)[-1]} → {leaf}" for h, leaf in self.history) + ")"
        return text


def _under(path: str, node: str) -> bool:
    return path == node or path.startswith(node + ".")


def _keeps(mission: CompiledMission, leaf: str, target: StateNode) -> bool:
    """Whether ``leaf`` stays active when ``target`` is entered: they lie in different regions of a parallel
    state that stays active (their deepest common ancestor is parallel and is neither of them)."""
    a = mission.states[leaf].ancestors()
    b = target.ancestors()
    k = 0
    while k < min(len(a), len(b)) and a[k] is b[k]:
        k += 1
    common = a[k - 1]
    return common.parallel and common is not target and common is not a[-1]


def configuration_of(mission: CompiledMission, before: Configuration | None, record: TransitionRecord,
                     where: str = "") -> Configuration:
    """The configuration ``record`` leaves the machine in, given the one ``before`` it (None for a run's
    first record).

    A record names one leaf entered (``to``: a leaf, or a parallel state whose regions all start), so the
    configuration needs the one before: the leaves of other regions of a parallel state that stays active are
    kept, every other leaf is left.  A ``next_item`` record gives its loop's item index (and the item's
    ``outcome`` counts as succeeded or not), a ``retry`` record the attempt of the item it runs again; a loop entered afresh starts at item 0, one resumed by history
    (``resumed``) where it was left.  A history state that stops being active remembers the leaf it resumes
    (as the engine does: the active leaf inside it, or the outermost parallel state on the way).  A record the
    configuration before cannot have written (a leaf left that was not active, a state the mission has not)
    is a :class:`CampaignDataError` at ``where``."""
    target = mission.states.get(record.target)
    if target is None:
        raise _fail(f"{where}: state {record.target[:80]!r} is no state of mission {mission.name!r}",
                    "give the mission file the campaign ran (with its --set)")
    if before is None:
        if record.cause != START_CAUSE:
            raise _fail(f"{where}: the first record's cause is {record.cause!r}", "a run's records begin with "
                        "its 'start' record")
        old: tuple[str, ...] = ()
        positions: dict[str, tuple[int, int, int]] = {}
        history: dict[str, str] = {}
    else:
        old = before.leaves
        left = [p for p in record.source.split("|") if p]
        if any(p not in old for p in left):
            raise _fail(f"{where}: the record leaves {record.source[:120]!r}, but the configuration was "
                        f"{before.label[:160]!r}", "records in the order the run wrote them, of one mission")
        positions = {p: (i, k, a) for p, i, k, a in before._positions}
        history = dict(before.history)
    entered = [n.path for n in target.entry_leaves()]
    kept = [p for p in old if _keeps(mission, p, target)]
    new = tuple(sorted(kept + entered, key=list(mission.states).index))
    for path, node in mission.states.items():
        was = any(_under(p, path) for p in old)
        now = any(_under(p, path) for p in new)
        if node.history and was and not now:
            inside = next(p for p in old if _under(p, path))
            par = next((a for a in mission.states[inside].ancestors() if a.parallel and a.depth > node.depth), None)
            history[path] = par.path if par is not None else inside
        if now:
            history.pop(path, None)
        if node.loop is not None and now and not was and not record.resumed:
            positions[path] = (0, 0, 1)
    if record.cause == NEXT_ITEM and record.item is not None:
        _, ok, _ = positions.get(record.state, (0, 0, 1))
        positions[record.state] = (record.item, ok + (record.outcome == "succeeded"), 1)
    elif record.cause == RETRY and record.item is not None:
        _, ok, _ = positions.get(record.state, (0, 0, 1))
        positions[record.state] = (record.item, ok, record.attempt or 2)
    loops = tuple((p, *positions[p]) for p in mission.states if p in positions and (
        any(_under(q, p) for q in new) or any(_under(point, p) and _under(p, h) for h, point in history.items())))
    return Configuration(new, loops, tuple(sorted(history.items())),
                         tuple((p, *v) for p, v in sorted(positions.items())))


# -- the runs ------------------------------------------------------------------------------------------------


@dataclass
class RunPath:
    """One run: the configurations it entered with the sim time of each entry, its outcome and its end time."""

    seed: int
    steps: list[tuple[str, float]]
    outcome: str
    end_s: float


def read_run(mission: CompiledMission, run_dir: Path, seed: int, summary: dict[str, Any]) -> RunPath:
    """The run in ``run_dir`` as a path of configurations (zero-time cascades merged, see the module text)."""
    where = run_dir / "transitions.jsonl"
    if not where.is_file():
        raise _fail(f"{run_dir}: no transitions.jsonl (trial seed {seed})",
                    "a campaign whose run directories were kept: taskflow batch MISSION --keep-runs")
    entries: list[tuple[Configuration, TransitionRecord]] = []
    config: Configuration | None = None
    last_t = -math.inf
    try:
        for rec, n, _ in read_transitions(run_dir, complete_only=True):  # a line cut short by a crash: left out
            if not isinstance(rec, TransitionRecord):
                continue  # an operator's pause, hold or injection changes no configuration
            if rec.t < last_t - 1e-9:
                raise _fail(f"{where}:{n}: t = {rec.t:g} s comes before the record above it ({last_t:g} s)",
                            "records in the order the run wrote them")
            last_t = rec.t
            config = configuration_of(mission, config, rec, f"{where}:{n}")
            entries.append((config, rec))
    except RunDirError as exc:
        raise _fail(str(exc), "a record as taskflow writes it (taskflow batch --keep-runs)") from None
    if not entries:
        raise _fail(f"{where}: no transition records", "a run's records begin with its 'start' record")
    kept: list[tuple[Configuration, float]] = []
    for k, (cfg, rec) in enumerate(entries):
        nxt = entries[k + 1][1] if k + 1 < len(entries) else None
        if nxt is not None and nxt.cause in (DONE, NEXT_ITEM, RETRY) and abs(nxt.t - rec.t) < 1e-9:
            continue  # a final leaf finished at once: part of the step that entered it
        kept.append((cfg, rec.t))
    end = float(summary["sim_time_s"])
    cfg, t_last = kept[-1]
    period = 1.0 / float(mission.spec.rate_hz)
    if len(kept) > 1 and any(mission.states[p].final for p in cfg.leaves) and end - t_last <= period + 1e-9:
        kept.pop()  # the machine ended the run on entering it: the step before leads to the outcome
    return RunPath(seed, [(c.label, t) for c, t in kept], str(summary["outcome"]), end)


# -- the chain -----------------------------------------------------------------------------------------------


@dataclass
class Chain:
    """The estimated chain: ``states`` (configurations, index 0 the runs' start), ``outcomes`` (absorbing,
    indexed after the states), ``counts[i][j]`` steps i → j and ``times[i][j]`` their durations (s)."""

    states: list[str]
    outcomes: list[str]
    counts: dict[int, dict[int, int]]
    times: dict[int, dict[int, list[float]]]
    first: int = 0

    @property
    def n(self) -> int:
        return len(self.states)

    def matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The maximum-likelihood ``P`` (n × (n + m): to states, then to outcomes) and the mean duration of
        each step (0 where none was seen)."""
        n, m = self.n, len(self.outcomes)
        p = np.zeros((n, n + m))
        r = np.zeros((n, n + m))
        for i, row in self.counts.items():
            total = sum(row.values())
            for j, c in row.items():
                p[i, j] = c / total
                r[i, j] = float(np.mean(self.times[i][j]))
        return p, r

    def sojourn(self, i: int) -> float:
        """Mean time of configuration ``i`` over all its visits."""
        d = [x for v in self.times[i].values() for x in v]
        return float(np.mean(d)) if d else 0.0


def estimate_chain(runs: list[RunPath]) -> Chain:
    """Count every step of every run (the last configuration → the run's outcome)."""
    states: dict[str, int] = {}
    outcomes = sorted({r.outcome for r in runs})
    steps: list[tuple[int, str | int, float]] = []
    for run in runs:
        idx = [states.setdefault(label, len(states)) for label, _ in run.steps]
        times = [t for _, t in run.steps] + [run.end_s]
        for k, i in enumerate(idx):
            nxt: str | int = idx[k + 1] if k + 1 < len(idx) else run.outcome
            steps.append((i, nxt, max(0.0, times[k + 1] - times[k])))
    n = len(states)
    counts: dict[int, dict[int, int]] = defaultdict(lambda: defaultdict(int))
    durations: dict[int, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
    for i, nxt, dt in steps:
        j = nxt if isinstance(nxt, int) else n + outcomes.index(nxt)
        counts[i][j] += 1
        durations[i][j].append(dt)
    return Chain(list(states), outcomes, {i: dict(r) for i, r in counts.items()},
                 {i: dict(r) for i, r in durations.items()})


def absorption(p: NDArray[np.float64], r: NDArray[np.float64], m: int
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fundamental-matrix solve, batched over leading axes: ``p`` (…, n, n + m) transition probabilities
    (the last ``m`` columns absorbing), ``r`` (same shape) each step's mean duration.  Returns ``h`` (…, n, m),
    ``P(reach outcome k | start in i)``, and ``t`` (…, n, m), the expected time to outcome ``k`` from ``i`` given
    that the run ends in it (NaN where ``h`` is 0): ``E[T·1{k}] = N·v`` with ``v_i = Σ_j P_ij r_ij h_jk``."""
    n = p.shape[-2]
    q = p[..., :n]
    a = np.eye(n) - q
    h = np.linalg.solve(a, p[..., n:])
    hfull = np.concatenate([h, np.broadcast_to(np.eye(m), p.shape[:-2] + (m, m))], axis=-2)  # (…, n + m, m)
    v = np.einsum("...ij,...jk->...ik", p * r, hfull)
    w = np.linalg.solve(a, v)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(h > 1e-12, w / np.where(h > 1e-12, h, 1.0), np.nan)
    return np.asarray(h, dtype=np.float64), np.asarray(t, dtype=np.float64)


def _label(outcome: str) -> str:
    return "outcome_" + re.sub(r"\W", "_", outcome)


def _storm_dtmc(p: NDArray[np.float64], reward: list[float], labels: dict[str, list[int]]) -> Any:
    import stormpy.developer as dev

    st = dev.storage
    n = p.shape[0]
    builder = st.SparseMatrixBuilder(rows=0, columns=0, entries=0, force_dimensions=False)
    for i in range(n):
        for j in np.nonzero(p[i])[0]:
            builder.add_next_value(i, int(j), float(p[i, j]))
    labeling = st.StateLabeling(n)
    for name, states in labels.items():
        labeling.add_label(name)
        for s in states:
            labeling.add_label_to_state(name, s)
    components = st.SparseModelComponents(transition_matrix=builder.build(n, n), state_labeling=labeling,
                                          reward_models={"time": st.SparseRewardModel(
                                              optional_state_reward_vector=reward)})
    return st.SparseDtmc(components)


def _storm_values(model: Any, formula: str) -> list[float]:
    import stormpy

    result = stormpy.model_checking(model, stormpy.parse_properties(formula)[0], only_initial_states=False)
    return [float(v) for v in result.get_value_vector()]


def storm_solve(p: NDArray[np.float64], r: NDArray[np.float64], outcomes: list[str]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """What :func:`absorption` computes, answered by Storm: the chain as a sparse DTMC (each outcome an
    absorbing state labelled ``outcome_NAME``), ``P=? [F "outcome_NAME"]`` in every state; then per outcome the
    chain conditioned on reaching it, with the state reward ``Σ_j P'_ij r_ij`` (the mean time spent before the
    next step), and ``R{"time"}=? [F "outcome_NAME"]``."""
    n, m = p.shape[0], len(outcomes)
    full = np.zeros((n + m, n + m))
    full[:n] = p
    full[n:, n:] = np.eye(m)
    labels = {_label(o): [n + k] for k, o in enumerate(outcomes)}
    model = _storm_dtmc(full, [0.0] * (n + m), {"init": [0], **labels})
    h = np.array([_storm_values(model, f'P=? [F "{_label(o)}"]') for o in outcomes]).T  # (n + m, m)
    t = np.full((n, m), np.nan)
    for k, o in enumerate(outcomes):
        live = [i for i in range(n + m) if h[i, k] > 1e-12]
        if not any(i < n for i in live):
            continue
        pos = {s: x for x, s in enumerate(live)}
        cond = np.zeros((len(live), len(live)))
        reward = []
        for s in live:
            if s >= n:  # the outcome itself: absorbing
                cond[pos[s], pos[s]] = 1.0
                reward.append(0.0)
                continue
            row = np.array([full[s, j] * h[j, k] / h[s, k] if j in pos else 0.0 for j in live])
            row /= row.sum()
            cond[pos[s]] = row
            reward.append(float(sum(row[pos[j]] * r[s, j] for j in live)))
        values = _storm_values(_storm_dtmc(cond, reward, {"init": [pos[live[0]]], _label(o): [pos[n + k]]}),
                               f'R{{"time"}}=? [F "{_label(o)}"]')
        for s in live:
            if s < n:
                t[s, k] = values[pos[s]]
    return h[:n], t


# -- the posterior -------------------------------------------------------------------------------------------


@dataclass
class Posterior:
    """Samples of the chain's solution: ``h`` (S, n, m), ``unseen`` (S, n) the probability of taking a step no
    run took, ``t`` (S, n, m) the expected time to each outcome given it."""

    h: NDArray[np.float64]
    unseen: NDArray[np.float64]
    t: NDArray[np.float64]


DENSE_MAX = 40
"""Chains of at most this many configurations are solved for all samples at once, densely (:func:`absorption`);
larger ones sample by sample on sparse matrices (:func:`absorption_sparse`): the dense batch is O(S n³) in time and
O(S n²) in memory — a 141-configuration trolley campaign took 2 minutes and 1 GB that way, its chain has ~300
entries."""


def absorption_sparse(rows: NDArray[np.intp], cols: NDArray[np.intp], p: NDArray[np.float64],
                      r: NDArray[np.float64], n: int, m: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`absorption` for chains given by their entries: ``(rows[e], cols[e])`` with probability ``p[s, e]`` and
    mean duration ``r[s, e]`` in sample ``s`` (columns ``n`` and above absorbing), one sparse LU a sample."""
    from scipy.sparse import csc_matrix, identity
    from scipy.sparse.linalg import splu

    samples = p.shape[0]
    inner = cols < n
    q_at = (rows[inner], cols[inner])  # the transient part's entries, and the absorbing ones (row, outcome)
    b_at = (rows[~inner], cols[~inner] - n)
    eye = identity(n, format="csc")
    h = np.zeros((samples, n, m))
    t = np.full((samples, n, m), np.nan)
    for k in range(samples):
        q = csc_matrix((p[k, inner], q_at), shape=(n, n))
        b = np.zeros((n, m))
        np.add.at(b, b_at, p[k, ~inner])
        lu = splu((eye - q).tocsc())
        hk = lu.solve(b)
        hfull = np.vstack([hk, np.eye(m)])
        pr = csc_matrix((p[k] * r[k], (rows, cols)), shape=(n, n + m))
        w = lu.solve(np.asarray(pr @ hfull))
        h[k] = hk
        with np.errstate(invalid="ignore", divide="ignore"):
            t[k] = np.where(hk > 1e-12, w / np.where(hk > 1e-12, hk, 1.0), np.nan)
    return h, t


def sample_posterior(chain: Chain, samples: int = SAMPLES, seed: int = 0) -> Posterior:
    """Draw ``samples`` chains and solve each (:func:`absorption`, :func:`absorption_sparse` past
    :data:`DENSE_MAX` configurations): rows Dirichlet(count + ½) over the successors seen, mean times by Bayesian
    bootstrap; and, from the same draws with one more successor of weight Dirichlet ½ (absorbing), the probability
    of taking a step no run took."""
    rng = np.random.default_rng(seed)
    n, m = chain.n, len(chain.outcomes)
    rows: list[int] = []
    cols: list[int] = []
    p_cols: list[NDArray[np.float64]] = []  # per entry, its value in every sample (the draws in the order of before)
    w_cols: list[NDArray[np.float64]] = []
    r_cols: list[NDArray[np.float64]] = []
    extra_rows: list[int] = []
    extra_cols: list[NDArray[np.float64]] = []
    for i, row in chain.counts.items():
        js = sorted(row)
        g = rng.gamma(np.array([row[j] + PRIOR for j in js]), size=(samples, len(js)))
        extra = rng.gamma(PRIOR, size=samples)
        total = g.sum(axis=1) + extra
        pg, wg = g / g.sum(axis=1, keepdims=True), g / total[:, None]
        for c, j in enumerate(js):
            d = np.asarray(chain.times[i][j])
            w = rng.gamma(1.0, size=(samples, d.size))
            rows.append(i)
            cols.append(j)
            p_cols.append(pg[:, c])
            w_cols.append(wg[:, c])
            r_cols.append((w @ d) / w.sum(axis=1))
        extra_rows.append(i)
        extra_cols.append(extra / total)
    ri, ci = np.asarray(rows, dtype=np.intp), np.asarray(cols, dtype=np.intp)
    pe, we, re_ = (np.stack(x, axis=1) if x else np.zeros((samples, 0)) for x in (p_cols, w_cols, r_cols))
    # the wide chain: the same entries renormalised with an "unseen" absorbing column n + m per drawn row
    wri = np.concatenate([ri, np.asarray(extra_rows, dtype=np.intp)])
    wci = np.concatenate([ci, np.full(len(extra_rows), n + m, dtype=np.intp)])
    wpe = np.concatenate([we, np.stack(extra_cols, axis=1) if extra_cols else np.zeros((samples, 0))], axis=1)
    if n > DENSE_MAX:
        h, t = absorption_sparse(ri, ci, pe, re_, n, m)
        hw, _ = absorption_sparse(wri, wci, wpe, np.zeros_like(wpe), n, m + 1)
        return Posterior(h, hw[..., m], t)
    p = np.zeros((samples, n, n + m))
    r = np.zeros((samples, n, n + m))
    wide = np.zeros((samples, n, n + m + 1))
    p[:, ri, ci] = pe
    r[:, ri, ci] = re_
    wide[:, wri, wci] = wpe
    h, t = absorption(p, r, m)
    hw, _ = absorption(wide, np.zeros_like(wide), m + 1)
    return Posterior(h, hw[..., m], t)


# -- the prediction ------------------------------------------------------------------------------------------


def _disjoint(a: tuple[float, float] | None, b: tuple[float, float] | None) -> bool:
    return a is not None and b is not None and (a[1] < b[0] or b[1] < a[0])


@dataclass(frozen=True)
class OutcomeLine:
    """One outcome from one configuration: the chain's probability with its interval beside the measured rate
    (``k`` of ``n`` runs) with its Wilson interval."""

    outcome: str
    predicted: float
    interval: tuple[float, float]
    k: int
    n: int
    measured_interval: tuple[float, float]

    @property
    def agrees(self) -> bool:
        return not _disjoint(self.interval, self.measured_interval)

    def as_dict(self) -> dict[str, Any]:
        return {"outcome": self.outcome, "predicted": self.predicted, "interval": list(self.interval),
                "measured": self.k / self.n, "k": self.k, "n": self.n,
                "measured_interval": list(self.measured_interval), "agrees": self.agrees}


@dataclass(frozen=True)
class TimeLine:
    """The expected time to one outcome (given the run ends in it): the chain's, with the interval of its
    posterior, beside the mean ``sim_time_s`` of the runs that ended in it (Student's t interval)."""

    outcome: str
    predicted: float | None
    interval: tuple[float, float] | None
    measured: float | None
    measured_interval: tuple[float, float] | None
    n: int

    @property
    def agrees(self) -> bool:
        return not _disjoint(self.interval, self.measured_interval)

    def as_dict(self) -> dict[str, Any]:
        return {"outcome": self.outcome, "predicted_s": self.predicted,
                "interval_s": None if self.interval is None else list(self.interval), "measured_s": self.measured,
                "measured_interval_s": None if self.measured_interval is None else list(self.measured_interval),
                "n": self.n, "agrees": self.agrees}


@dataclass(frozen=True)
class StateLine:
    """One configuration of the chain: visits, runs that entered it, mean time in it, its successors (counts),
    and from it each outcome predicted against the rate measured over the runs that entered it."""

    configuration: str
    visits: int
    runs: int
    sojourn_s: float
    successors: dict[str, int]
    outcomes: tuple[OutcomeLine, ...]

    @property
    def agrees(self) -> bool:
        return all(o.agrees for o in self.outcomes)

    def as_dict(self) -> dict[str, Any]:
        return {"configuration": self.configuration, "visits": self.visits, "runs": self.runs,
                "mean_sojourn_s": self.sojourn_s, "successors": dict(self.successors),
                "outcomes": [o.as_dict() for o in self.outcomes], "agrees": self.agrees}


@dataclass(frozen=True)
class ConditionPrediction:
    """The prediction for one condition of the campaign (``all`` when nothing is swept)."""

    label: str
    runs: int
    outcomes: tuple[OutcomeLine, ...]
    times: tuple[TimeLine, ...]
    expected_time: tuple[float, float]  # the chain's expected run time, the measured mean sim_time_s
    states: tuple[StateLine, ...]
    unseen: tuple[float, float, float] = (0.0, 0.0, 0.0)  # P(a step no run took) from the start: mean, interval
    held_out: tuple[OutcomeLine, ...] = ()  # the chain of the even trials predicting the odd ones (>= 10 runs)

    @property
    def disagreements(self) -> list[str]:
        """Each comparison whose two intervals are disjoint, as a sentence."""
        out = [f"P({o.outcome}): predicted {_pi(o)} against measured {_mi(o)}" for o in self.outcomes
               if not o.agrees]
        out += [f"held out: P({o.outcome}) predicted from the even trials {_pi(o)} against the odd trials' "
                f"{_mi(o)}" for o in self.held_out if not o.agrees]
        out += [f"time to {t.outcome}: predicted {_ti(t.predicted, t.interval)} against measured "
                f"{_ti(t.measured, t.measured_interval)}" for t in self.times if not t.agrees]
        out += [f"from {s.configuration}: P({o.outcome}) predicted {_pi(o)}, measured {_mi(o)} over the runs "
                "that entered it" for s in self.states for o in s.outcomes if not o.agrees]
        return out

    def as_dict(self) -> dict[str, Any]:
        return {"condition": self.label, "runs": self.runs, "outcomes": [o.as_dict() for o in self.outcomes],
                "times": [t.as_dict() for t in self.times],
                "expected_time_s": {"predicted": self.expected_time[0], "measured": self.expected_time[1]},
                "unseen": {"mean": self.unseen[0], "interval": list(self.unseen[1:])},
                "held_out": [o.as_dict() for o in self.held_out],
                "configurations": [s.as_dict() for s in self.states], "disagreements": self.disagreements}


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _pi(o: OutcomeLine) -> str:
    return f"{_pct(o.predicted)} % [{_pct(o.interval[0])}, {_pct(o.interval[1])}]"


def _mi(o: OutcomeLine) -> str:
    return f"{o.k}/{o.n} = {_pct(o.k / o.n)} % [{_pct(o.measured_interval[0])}, {_pct(o.measured_interval[1])}]"


def _ti(x: float | None, iv: tuple[float, float] | None) -> str:
    if x is None:
        return "—"
    return f"{x:.2f} s" + ("" if iv is None else f" [{iv[0]:.2f}, {iv[1]:.2f}]")


@dataclass(frozen=True)
class CampaignPrediction:
    """:func:`predict`'s answer: one :class:`ConditionPrediction` per condition of the campaign."""

    mission: str
    batch_dir: str
    confidence: float
    samples: int
    conditions: tuple[ConditionPrediction, ...]

    @property
    def agrees(self) -> bool:
        return not any(c.disagreements for c in self.conditions)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = clean_floats({
            "mission": self.mission, "batch_dir": self.batch_dir, "confidence": self.confidence,
            "posterior_samples": self.samples, "agrees": self.agrees,
            "conditions": [c.as_dict() for c in self.conditions]})
        return out

    def render(self) -> str:
        """The tables a person reads: per condition the outcomes, the times, the configurations, the verdict."""
        c95 = f"{100 * self.confidence:g} %"
        out = [f"campaign {self.batch_dir} — mission {self.mission}: the chain of its records (Storm) against its "
               f"measured rates ({c95} intervals: posterior of the chain, Wilson / t of the runs)"]
        for c in self.conditions:
            out.append(f"\ncondition {c.label}: {c.runs} runs, {len(c.states)} configurations")
            out.append(f"  {'outcome':<12} {'predicted':>26}   {'measured':>30}   agrees")
            for o in c.outcomes:
                out.append(f"  {o.outcome:<12} {_pi(o):>26}   {_mi(o):>30}   {'yes' if o.agrees else 'NO'}")
            if c.held_out:
                out.append(f"  held out — the chain of the {c.runs - c.runs // 2} even trials predicting the "
                           f"{c.runs // 2} odd ones:")
                for o in c.held_out:
                    out.append(f"  {o.outcome:<12} {_pi(o):>26}   {_mi(o):>30}   {'yes' if o.agrees else 'NO'}")
            out.append(f"  expected run time: predicted {c.expected_time[0]:.2f} s, measured {c.expected_time[1]:.2f} s;"
                       f" P(a step no run took) {_pct(c.unseen[0])} % [{_pct(c.unseen[1])}, {_pct(c.unseen[2])}]")
            for t in c.times:
                out.append(f"  time to {t.outcome:<12} predicted {_ti(t.predicted, t.interval):<24} measured "
                           f"{_ti(t.measured, t.measured_interval):<24} {'' if t.agrees else 'DISAGREES'}")
            out.append(f"  {'configuration':<70} {'visits':>6} {'runs':>5} {'mean s':>7}  from it: "
                       "P(outcome) predicted / measured")
            for s in c.states:
                name = s.configuration if len(s.configuration) <= 70 else "…" + s.configuration[-69:]
                cmp = "; ".join(f"{o.outcome} {_pi(o)} / {_mi(o)}{'' if o.agrees else ' NO'}" for o in s.outcomes)
                out.append(f"  {name:<70} {s.visits:>6} {s.runs:>5} {s.sojourn_s:>7.2f}  {cmp}")
            bad = c.disagreements
            if bad:
                out.append("  DISAGREES — the mission's behaviour depends on more than its configuration (a history "
                           "the abstraction drops):")
                out += [f"    {b}" for b in bad]
            else:
                out.append("  agrees: every predicted interval meets the measured one")
        return "\n".join(out)


def _quantiles(x: NDArray[np.float64], confidence: float) -> tuple[float, float]:
    lo, hi = np.nanquantile(x, [(1 - confidence) / 2, (1 + confidence) / 2])
    return float(lo), float(hi)


def _outcome_lines(chain: Chain, post: Posterior, h: NDArray[np.float64], i: int, ends: list[str],
                   confidence: float) -> tuple[OutcomeLine, ...]:
    """From configuration ``i``: each outcome's point (``h``, Storm) and its posterior interval, beside ``ends`` (the outcomes of the runs that entered ``i``)."""
    lines = []
    for k, o in enumerate(chain.outcomes):
        lo, hi = _quantiles(post.h[:, i, k], confidence)
        got = sum(e == o for e in ends)
        lines.append(OutcomeLine(o, float(h[i, k]), (lo, min(1.0, hi)), got, len(ends),
                                 wilson_interval(got, len(ends), confidence)))
    return tuple(lines)


def predict_runs(runs: list[RunPath], label: str = "all", confidence: float = 0.95,
                 samples: int = SAMPLES) -> ConditionPrediction:
    """The prediction from the runs of one condition (all starting in one configuration)."""
    starts = {r.steps[0][0] for r in runs}
    if len(starts) != 1:
        raise _fail(f"condition {label}: the runs start in {len(starts)} configurations ({', '.join(sorted(starts))[:160]})",
                    "runs of one mission, whose machine starts in one configuration")
    chain = estimate_chain(runs)
    p, r = chain.matrices()
    h, t = storm_solve(p, r, chain.outcomes)
    post = sample_posterior(chain, samples)
    ends = [run.outcome for run in runs]
    outcomes = _outcome_lines(chain, post, h, 0, ends, confidence)
    times = []
    for k, o in enumerate(chain.outcomes):
        ts = [run.end_s for run in runs if run.outcome == o]
        mi = mean_interval(ts, confidence)
        ok = np.isfinite(post.t[:, 0, k])
        times.append(TimeLine(o, None if math.isnan(t[0, k]) else float(t[0, k]),
                              _quantiles(post.t[ok, 0, k], confidence) if ok.any() else None, mi.mean,
                              None if mi.low is None or mi.high is None else (mi.low, mi.high), len(ts)))
    expected = float(np.nansum(h[0] * t[0]))
    entered: dict[int, list[str]] = defaultdict(list)
    visits: dict[int, int] = defaultdict(int)
    index = {s: i for i, s in enumerate(chain.states)}
    for run in runs:
        seen = {index[label_] for label_, _ in run.steps}
        for label_, _ in run.steps:
            visits[index[label_]] += 1
        for i in seen:
            entered[i].append(run.outcome)
    names = chain.states + chain.outcomes
    states = tuple(StateLine(chain.states[i], visits[i], len(entered[i]), chain.sojourn(i),
                             {names[j]: c for j, c in sorted(chain.counts[i].items())},
                             _outcome_lines(chain, post, h, i, entered[i], confidence)) for i in range(chain.n))
    unseen = (float(post.unseen[:, 0].mean()), *_quantiles(post.unseen[:, 0], confidence))
    return ConditionPrediction(label, len(runs), outcomes, tuple(times),
                               (expected, float(np.mean([run.end_s for run in runs]))), states, unseen,
                               held_out(runs, confidence, samples))


HELD_OUT_MIN = 10
"""Fewest runs of a condition for the held-out prediction (half of them estimate, the other half measure)."""


def held_out(runs: list[RunPath], confidence: float = 0.95, samples: int = SAMPLES) -> tuple[OutcomeLine, ...]:
    """A prediction the measured rate did not shape: the chain estimated from the even-numbered trials, its
    P(outcome) from the start with its posterior interval, beside the odd-numbered trials' measured rate (Wilson).
    On its own runs a count-based chain reproduces the rates by construction; on runs it has not seen it
    predicts.  Empty below :data:`HELD_OUT_MIN` runs."""
    if len(runs) < HELD_OUT_MIN:
        return ()
    train, test = runs[0::2], runs[1::2]
    chain = estimate_chain(train)
    p, r = chain.matrices()
    h, _ = storm_solve(p, r, chain.outcomes)
    post = sample_posterior(chain, samples)
    ends = [run.outcome for run in test]
    lines = list(_outcome_lines(chain, post, h, 0, ends, confidence))
    for o in sorted({e for e in ends if e not in chain.outcomes}):  # an outcome the training trials never reached
        got = sum(e == o for e in ends)
        lines.append(OutcomeLine(o, 0.0, (0.0, 0.0), got, len(ends), wilson_interval(got, len(ends), confidence)))
    return tuple(lines)


def predict(mission: CompiledMission, batch_dir: Path, confidence: float = 0.95,
            samples: int = SAMPLES) -> CampaignPrediction:
    """Predict each outcome's probability and expected time from the records of the campaign in ``batch_dir``
    (``taskflow batch MISSION --keep-runs``) and set them beside its measured rates (see the module text).

    ``mission`` is the campaign's mission (its records name its states).  Every finished trial of each condition
    is read: its ``summary`` from the campaign's trial record, its ``transitions.jsonl`` from its run directory.
    A directory that is no campaign, a trial without its run directory, a record that is malformed or names a
    state the mission has not: a :class:`CampaignDataError` naming the file and line."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    try:
        camp = Campaign.open(batch_dir)
        records = camp.records()
    except CampaignError as exc:
        raise _fail(str(exc), "a directory taskflow batch --keep-runs wrote") from None
    conditions = []
    for cond in camp.spec.conditions():
        runs = _condition_runs(mission, camp, cond, records)
        if runs:
            conditions.append(predict_runs(runs, cond.label, confidence, samples))
    if not conditions:
        raise _fail(f"{batch_dir}: no finished trial", "a campaign with at least one finished trial")
    return CampaignPrediction(mission.name, str(batch_dir), confidence, samples, tuple(conditions))


def _condition_runs(mission: CompiledMission, camp: Campaign, cond: Condition,
                    records: dict[tuple[int, int], dict[str, Any]]) -> list[RunPath]:
    runs = []
    for seed in camp.spec.seeds():
        rec = records.get((cond.index, seed))
        if rec is None:
            continue
        summary = rec["summary"]
        where = camp.root / "trials" / f"c{cond.index:03d}-s{seed:05d}.json"
        if summary.get("mission") not in (None, mission.name):
            raise _fail(f"{where}: a trial of mission {str(summary.get('mission'))[:80]!r}, not {mission.name!r}",
                        "give the mission file the campaign ran")
        run_dir = camp.run_dir(cond.index, seed)
        if not run_dir.is_dir():
            raise _fail(f"{run_dir}: no run directory for trial seed {seed}",
                        "a campaign whose run directories were kept: taskflow batch MISSION --keep-runs")
        runs.append(read_run(mission, run_dir, seed, summary))
    return runs
