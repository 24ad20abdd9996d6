"""Figures of a campaign (a batch directory's ``batch.json``), as PNG (matplotlib, no display needed).

* ``success_vs_KEY.png`` — for each swept key: the success rate against the key's values with the
  Wilson 95 % interval as error bars; one line per combination of the other swept keys' values;
* with :func:`plot_success_comparison` (``taskflow compare A B --plot FILE``): several campaigns that
  swept the same key on one success figure;
* ``distribution_METRIC.png`` — for each error metric (the numeric final metrics whose name holds
  ``err``, or the ones asked for): the value of every trial per condition (points) over a box plot.

Each figure's title gives the trial count per condition and the mission, so a figure is never read
without knowing how many trials stand behind it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .campaign import CampaignError
from .compare import load_batch

MAX_DEFAULT_METRICS = 6


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _error_metrics(batch: dict[str, Any]) -> list[str]:
    names = sorted({k for t in batch["trials"] for k, v in t.get("metrics", {}).items() if _is_number(v)})
    return [n for n in names if "err" in n][:MAX_DEFAULT_METRICS]


def _success_lines(ax: Any, batch: dict[str, Any], key: str, prefix: str) -> None:
    """Success rate against swept ``key`` with Wilson error bars, a line per combination of the other
    swept keys; labels start with ``prefix``."""
    sweep: dict[str, list[Any]] = batch["sweep"]
    values = sweep[key]
    others = [k for k in sweep if k != key]
    numeric = all(_is_number(v) for v in values)
    xs = {repr(v): (float(v) if numeric else float(i)) for i, v in enumerate(values)}
    lines: dict[str, list[tuple[float, dict[str, Any]]]] = {}
    for c in batch["conditions"]:
        rest = ", ".join(f"{k}={c['values'][k]}" for k in others)
        lines.setdefault(rest, []).append((xs[repr(c["values"][key])], c["aggregate"]))
    for rest, pts in lines.items():
        pts.sort(key=lambda p: p[0])
        y = [100 * a["success_rate"] for _, a in pts]
        lo = [100 * (a["success_rate"] - a["success_ci95"][0]) if a.get("success_ci95") else 0 for _, a in pts]
        hi = [100 * (a["success_ci95"][1] - a["success_rate"]) if a.get("success_ci95") else 0 for _, a in pts]
        label = ", ".join(x for x in (prefix, rest) if x) or None
        ax.errorbar([p[0] for p in pts], y, yerr=[lo, hi], marker="o", capsize=4, label=label)
    if not numeric:
        ax.set_xticks(list(xs.values()), [str(v) for v in values])
    ax.set_xlabel(key)
    ax.set_ylabel("mission success [%] (95 % Wilson interval)")
    ax.set_ylim(-5, 105)
    ax.grid(alpha=0.3)
    if any(lines) or prefix:
        ax.legend(fontsize=8)


def plot_success_comparison(batches: list[tuple[str, dict[str, Any]]], path: str | Path) -> Path:
    """One figure of the success rate of several campaigns (name, batch.json) against the key they all
    swept (the first, when they swept several), with Wilson intervals; written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [list(b.get("sweep") or {}) for _, b in batches]
    if not keys[0] or any(k != keys[0] for k in keys):
        raise CampaignError("a success plot of several campaigns needs campaigns that swept the same keys")
    key = keys[0][0]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, b in batches:
        _success_lines(ax, b, key, f"{name} ({b.get('trials_requested', '?')} trials per point)")
    ax.set_title(f"success vs {key.rsplit('.', 1)[-1]}", fontsize=10)
    return _save(fig, Path(path))


def _save(fig: Any, path: Path) -> Path:
    """Lay ``fig`` out, write it to ``path`` and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_campaign(batch_dir: str | Path, metrics: list[str] | None = None) -> list[Path]:
    """Write the campaign's figures into ``batch_dir`` and return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    root = Path(batch_dir)
    batch = load_batch(root)
    conditions = batch["conditions"]
    n_per = batch.get("trials_requested", "?")
    out: list[Path] = []
    sweep: dict[str, list[Any]] = batch.get("sweep") or {}
    for key in sweep:
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        _success_lines(ax, batch, key, "")
        ax.set_title(f"{batch['mission']}: success vs {key.rsplit('.', 1)[-1]} ({n_per} trials per point)", fontsize=10)
        out.append(_save(fig, root / f"success_vs_{key.replace('.', '_')}.png"))
    for metric in metrics or _error_metrics(batch):
        groups = []
        for c in conditions:
            vals = [t["metrics"].get(metric) for t in batch["trials"] if t.get("condition", 0) == c["index"]]
            groups.append([float(v) for v in vals if _is_number(v) and math.isfinite(v)])
        if not any(groups):
            continue
        fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(groups) + 2), 4.2))
        pos = list(range(1, len(groups) + 1))
        ax.boxplot([g or [math.nan] for g in groups], positions=pos, widths=0.5, showfliers=False)
        for p, g in zip(pos, groups):
            jitter = [p + 0.15 * ((i * 0.618) % 1.0 - 0.5) for i in range(len(g))]  # deterministic spread
            ax.plot(jitter, g, "o", ms=3, alpha=0.6)
        short = ["\n".join(f"{k.rsplit('.', 1)[-1]}={v}" for k, v in c.get("values", {}).items()) or c["label"]
                 for c in conditions]  # the last part of each key: the full keys are in the x label
        ax.set_xticks(pos, short, fontsize=7)
        if sweep:
            ax.set_xlabel(", ".join(sweep), fontsize=8)
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3, axis="y")
        ax.set_title(f"{batch['mission']}: {metric} per condition ({n_per} trials each)", fontsize=10)
        out.append(_save(fig, root / f"distribution_{metric}.png"))
    return out
