"""``taskflow compare A B``: do two campaigns differ?

For each pair of conditions (the one condition of each campaign; or conditions of equal label when both
swept the same grid; or the single condition of one campaign against each of the other's):

* mission success: both rates with their Wilson 95 % intervals, Fisher's exact test (two-sided p) and
  the pooled two-proportion z test;
* item success per foreach loop both campaigns have (screws, waypoints): the same, over items (each item
  counted on its last attempt), and for a loop that retries in either campaign its attempts and the items
  retried (``foreach: {retry: …}``);
* each numeric aggregate both have (or the ones asked for): every numeric final metric of the trials and
  the run's own numbers :mod:`taskflow.campaigns.batch` aggregates beside them (``sim_time_s``, from each trial's
  summary): means with their t 95 % intervals and the two-sided Mann–Whitney U test, which assumes
  nothing about the errors' distribution.

``p < alpha`` (0.05) is reported as a difference.  With many metrics some will pass that by chance;
the table says how many were tested.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError

from taskflow.campaigns.campaign import CampaignError
from taskflow.campaigns.stats import fisher_exact, mann_whitney, mean_interval, two_proportion_z, wilson_interval
from taskflow.execution.record_io import RunDirError, SummaryFields, problem, read_json

ALPHA = 0.05


class _Items(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    attempted: int
    succeeded: int


class _Stats(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    mean: float | None = None
    n: int = 0
    ci95: list[float] | None = None


class _Property(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    pattern: str = ""
    held: int = 0
    violated: int = 0
    not_decided: int = 0
    violation_rate: float | None = None
    violation_ci95: list[float] | None = None
    first_violation_t: float | None = None


class _Aggregate(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    trials: int = 0
    success_rate: float | None = None
    success_ci95: list[float] | None = None
    outcomes: dict[str, int] = {}
    items: dict[str, _Items] = {}
    metrics: dict[str, _Stats] = {}
    properties: dict[str, _Property] = {}


class _Condition(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    index: int
    label: str
    values: dict[str, Any] = {}
    aggregate: _Aggregate


class _Verdict(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True)
    pattern: str = ""
    verdict: str
    t: float | None = None


class _Trial(SummaryFields):
    outcome: str
    condition: int = 0
    properties: dict[str, _Verdict] = {}


class BatchFields(BaseModel):
    """The fields of ``batch.json`` the readers (:func:`compare`, :mod:`taskflow.campaigns.campaign_plots`, the
    campaign page :mod:`taskflow.operate.campaign_view`) use, with their types: the trials (each a run summary,
    :class:`~taskflow.execution.record_io.SummaryFields`, with its ``condition`` and its properties' verdicts),
    the aggregate (with each property's rates) and the conditions with theirs."""

    model_config = ConfigDict(extra="allow", strict=True)
    mission: str = ""
    sweep: dict[str, list[Any]] | None = None
    trials: list[_Trial]
    aggregate: _Aggregate
    conditions: list[_Condition] | None = None


def load_batch(path: str | Path) -> dict[str, Any]:
    """``batch.json`` of a batch directory (or the file itself), read as untrusted input
    (:mod:`taskflow.execution.record_io`: inside its folder, bounded, its fields' types checked); a
    :class:`CampaignError` of one line naming the file and what is wrong otherwise."""
    p = Path(path)
    root, name = (p, "batch.json") if p.is_dir() else (p.parent, p.name)
    if not (root / name).is_file():
        raise CampaignError(f"{path}: {'no such file or directory' if not p.exists() else 'has no batch.json'}")
    try:
        data = read_json(root, name)
        if not isinstance(data, dict):
            raise RunDirError(f"{root / name}: a JSON object was expected, got {type(data).__name__}")
        try:
            fields = BatchFields.model_validate(data)
        except ValidationError as exc:
            raise RunDirError(f"{root / name}: {problem(exc)} — not a batch.json written by taskflow batch") from None
        for c in fields.conditions or []:
            if set(c.values) != set(fields.sweep or {}):
                raise RunDirError(f"{root / name}: condition {c.index} sets {', '.join(sorted(c.values)) or 'nothing'}"
                                  f" — the keys its sweep names: {', '.join(sorted(fields.sweep or {})) or 'none'}")
    except RunDirError as exc:
        raise CampaignError(str(exc)) from None
    if data.get("conditions") is None:  # written before sweeps: one condition
        data["conditions"] = [{"index": 0, "label": "all", "aggregate": data["aggregate"]}]
    return dict(data)


def _pairs(a: dict[str, Any], b: dict[str, Any]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    ca, cb = a["conditions"], b["conditions"]
    if len(ca) == 1 or len(cb) == 1:
        return [(x, y) for x in ca for y in cb]
    by_label = {c["label"]: c for c in cb}
    if {c["label"] for c in ca} == set(by_label):
        return [(c, by_label[c["label"]]) for c in ca]
    raise CampaignError("the two campaigns swept different grids: compare campaigns with the same sweep, "
                        "or one of them without a sweep")


def _trials(batch: dict[str, Any], condition: dict[str, Any]) -> list[dict[str, Any]]:
    return [t for t in batch["trials"] if t.get("condition", 0) == condition["index"]]


RUN_NUMBERS = ("sim_time_s",)
"""The numbers of a trial's summary itself (not of its ``metrics``) that :func:`taskflow.campaigns.batch.aggregate`
aggregates, and so that a comparison compares."""


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _value(trial: dict[str, Any], metric: str) -> Any:
    """A trial's value of ``metric``: its final metric of that name, else its summary's own number."""
    metrics = trial.get("metrics", {})
    if metric in metrics:
        return metrics[metric]
    return trial.get(metric) if metric in RUN_NUMBERS else None


def _values(trials: list[dict[str, Any]], metric: str) -> np.ndarray:
    vals = [_value(t, metric) for t in trials]
    return np.array([v for v in vals if _number(v)], dtype=float)


def _proportions(k1: int, n1: int, k2: int, n2: int) -> dict[str, Any]:
    z, pz = two_proportion_z(k1, n1, k2, n2)
    p = fisher_exact(k1, n1, k2, n2)
    return {"a": [k1, n1], "b": [k2, n2], "rate_a": k1 / n1, "rate_b": k2 / n2,
            "ci95_a": list(wilson_interval(k1, n1)), "ci95_b": list(wilson_interval(k2, n2)),
            "fisher_p": p, "z": z, "z_p": pz, "differs": p < ALPHA}


def _metric_names(trials: list[dict[str, Any]]) -> set[str]:
    """Every numeric final metric of the trials and every :data:`RUN_NUMBERS` entry a trial has."""
    return {k for t in trials for k, v in [*t.get("metrics", {}).items(), *((n, t.get(n)) for n in RUN_NUMBERS)]
            if _number(v)}


def compare(a: dict[str, Any], b: dict[str, Any], metrics: list[str] | None = None) -> list[dict[str, Any]]:
    """One comparison per pair of conditions (see the module docstring)."""
    out = []
    for ca, cb in _pairs(a, b):
        ta, tb = _trials(a, ca), _trials(b, cb)
        if not ta or not tb:
            raise CampaignError(f"condition {ca['label'] if not ta else cb['label']} has no finished trial")
        common = sorted(_metric_names(ta) & _metric_names(tb))
        if metrics:
            unknown = [m for m in metrics if m not in common]
            if unknown:
                raise CampaignError(f"--metric {unknown[0]}: not a numeric metric of both campaigns; they have "
                                    + (", ".join(common) or "none"))
            common = list(metrics)
        k = [sum(t["outcome"] == "succeeded" for t in ts) for ts in (ta, tb)]
        entry: dict[str, Any] = {"a": ca["label"], "b": cb["label"],
                                 "success": _proportions(k[0], len(ta), k[1], len(tb)), "items": {}, "metrics": {}}
        items_a, items_b = ca["aggregate"].get("items", {}), cb["aggregate"].get("items", {})
        for loop in sorted(set(items_a) & set(items_b)):
            ia, ib = items_a[loop], items_b[loop]
            if ia["attempted"] and ib["attempted"]:
                entry["items"][loop] = _proportions(ia["succeeded"], ia["attempted"], ib["succeeded"], ib["attempted"])
                if "attempts" in ia or "attempts" in ib:  # a loop that retries (in one campaign or both)
                    entry.setdefault("attempts", {})[loop] = {
                        side: [c.get("attempts", c["attempted"]), c["attempted"], c.get("retried", 0)]
                        for side, c in (("a", ia), ("b", ib))}
        for m in common:
            va, vb = _values(ta, m), _values(tb, m)
            if va.size == 0 or vb.size == 0:
                continue
            u, p = mann_whitney(va, vb)
            ma, mb = mean_interval(va), mean_interval(vb)
            entry["metrics"][m] = {"n_a": int(va.size), "n_b": int(vb.size), "mean_a": ma.mean, "mean_b": mb.mean,
                                   "ci95_a": None if ma.low is None else [ma.low, ma.high],
                                   "ci95_b": None if mb.low is None else [mb.low, mb.high],
                                   "U": u, "p": p, "differs": p < ALPHA}
        out.append(entry)
    return out


def _ci(ci: list[float] | None, scale: float = 1.0) -> str:
    return "" if not ci else f" [{ci[0] * scale:.4g}, {ci[1] * scale:.4g}]"


def format_comparison(names: tuple[str, str], results: list[dict[str, Any]]) -> str:
    """The comparison as text, one block per pair of conditions."""
    lines = []
    for r in results:
        if len(results) > 1 or r["a"] != "all" or r["b"] != "all":
            lines.append(f"A: {r['a']}   B: {r['b']}")
        rows = [("mission success", r["success"])] + [(f"items of {k}", v) for k, v in r["items"].items()]
        for what, s in rows:
            lines.append(f"{what}: A {s['a'][0]}/{s['a'][1]} = {100 * s['rate_a']:.1f} %{_ci(s['ci95_a'], 100)}   "
                         f"B {s['b'][0]}/{s['b'][1]} = {100 * s['rate_b']:.1f} %{_ci(s['ci95_b'], 100)}   "
                         f"Fisher p = {s['fisher_p']:.3g}, z = {s['z']:.2f} (p = {s['z_p']:.3g})"
                         f"  -> {'DIFFERENT' if s['differs'] else 'no significant difference'}")
        for loop, s in r.get("attempts", {}).items():
            lines.append(f"attempts of {loop}: A {s['a'][0]} over {s['a'][1]} items ({s['a'][2]} retried)   "
                         f"B {s['b'][0]} over {s['b'][1]} items ({s['b'][2]} retried)")
        if r["metrics"]:
            lines.append(f"{'metric':32s} {'mean A [95 %]':>30s} {'mean B [95 %]':>30s} {'Mann-Whitney p':>15s}")
            for m, s in r["metrics"].items():
                mean_a = f"{s['mean_a']:.4g}{_ci(s['ci95_a'])}"
                mean_b = f"{s['mean_b']:.4g}{_ci(s['ci95_b'])}"
                lines.append(f"{m:32s} {mean_a:>30s} {mean_b:>30s} {s['p']:15.3g}"
                             + ("  DIFFERENT" if s["differs"] else ""))
            n_diff = sum(s["differs"] for s in r["metrics"].values())
            lines.append(f"{n_diff} of {len(r['metrics'])} metrics differ at p < {ALPHA} (expect about "
                         f"{ALPHA * len(r['metrics']):.1f} by chance alone when they do not)")
        lines.append("")
    lines.append(f"A = {names[0]}, B = {names[1]}")
    return "\n".join(lines)
