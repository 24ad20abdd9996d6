"""Figures of a campaign (a batch directory's ``batch.json``), as PNG (matplotlib, no display needed).

* ``success_vs_KEY.png`` — for each swept key: the success rate against the key's values with the
  Wilson 95 % interval as error bars; one line per combination of the other swept keys' values;
* with :func:`plot_success_comparison` (``taskflow compare A B --plot FILE``): several campaigns that
  swept the same key on one success figure;
* ``distribution_METRIC.png`` — for each error metric (the numeric final metrics whose name holds
  ``err``, or the ones asked for): the value of every trial per condition (points) over a box plot.

Each figure's title gives the trial count per condition and the mission, so a figure is never read
without knowing how many trials stand behind it.  Every axis is labelled ``name [unit]`` as the run
figures are (:func:`taskflow.readers.plots.axis_label`; ``[-]`` dimensionless, ``[?]`` not known): a metric's unit
is the one its task or world declares in the campaign's mission (loaded again from ``batch.json``'s
``file`` and ``overrides``), else its name's suffix (``sim_time_s``, ``final_error_m``), else none (a
count or a ratio); a swept key's is the one its parameter declares (``world.params.*``,
``robot.params.*``), or the unit its values are written in (``--sweep parameters.tol="1 cm,2 cm"`` is drawn
against 0.01 and 0.02 m).
"""

from __future__ import annotations

import math
import typing
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel

from taskflow.campaigns.campaign import CampaignError
from taskflow.campaigns.compare import load_batch
from taskflow.units import BASE_UNIT_OF, UnitError, parse_quantity, suffix_unit

if TYPE_CHECKING:
    from taskflow.mission.model import CompiledMission

UNKNOWN_UNIT = "?"
"""Axis unit shown when neither the mission nor the name says what the unit is."""

MAX_DEFAULT_METRICS = 6


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def campaign_mission(batch: dict[str, Any]) -> CompiledMission | None:
    """The campaign's mission as its trials ran (``batch.json``'s ``file`` with its ``overrides``); None
    when it cannot be loaded here (moved, edited since): the units then come from the names alone."""
    from taskflow.errors import MissionError
    from taskflow.mission.loader import load_mission

    try:
        return load_mission(str(batch["file"]), [str(o) for o in batch.get("overrides") or []])
    except (MissionError, OSError, KeyError, TypeError, ValueError):
        return None


def metric_unit(name: str, mission: CompiledMission | None) -> str:
    """The unit of the final metric (or aggregate) ``name``: the one the mission's tasks or world declare,
    else its name's suffix, else '' (dimensionless) — or :data:`UNKNOWN_UNIT` when the mission could not
    be loaded to say."""
    if mission is not None and name in mission.metric_units:
        return mission.metric_units[name]
    by_suffix = suffix_unit(name)
    if by_suffix is not None:
        return by_suffix
    return "" if mission is not None else UNKNOWN_UNIT


def _quantities(values: list[Any]) -> tuple[list[float], str] | None:
    """Swept values written as quantities of one dimension (``"1 cm"``, ``"2 cm"``): their values in the
    base unit and that unit; None when they are not all such."""
    if not values or not all(isinstance(v, str) for v in values):
        return None
    try:
        parsed = [parse_quantity(v) for v in values]
    except UnitError:
        return None
    dims = {d for _, d in parsed}
    if len(dims) != 1 or dims == {"ratio"}:
        return None
    return [v for v, _ in parsed], BASE_UNIT_OF[dims.pop()]


def key_unit(key: str, values: list[Any], mission: CompiledMission | None) -> str:
    """The unit of swept ``key``: its values' when written as quantities, else the base unit of the mission
    parameter ``parameters.NAME``'s declared quantity, else the one the world's or the robot's parameter
    model declares for ``world.params.A.B`` / ``robot.params.A.B`` ('' when it declares none), else
    :data:`UNKNOWN_UNIT`."""
    from taskflow.catalogue.catalogue import params_of

    q = _quantities(values)
    if q is not None:
        return q[1]
    parts = key.split(".")
    if mission is not None and len(parts) == 2 and parts[0] == "parameters" and parts[1] in mission.spec.parameters:
        declared = _quantities([mission.spec.parameters[parts[1]]])  # the mission writes it "5 cm": metres
        return declared[1] if declared is not None else UNKNOWN_UNIT
    if mission is None or len(parts) < 3 or parts[1] != "params" or parts[0] not in ("world", "robot"):
        return UNKNOWN_UNIT
    model: type[BaseModel] | None = mission.world_cls.Params if parts[0] == "world" else type(mission.robot_params)
    for i, part in enumerate(parts[2:], 2):
        if model is None:
            return UNKNOWN_UNIT
        if i == len(parts) - 1:
            return next((p.unit for p in params_of(model) if p.name == part), UNKNOWN_UNIT)
        info = next((f for n, f in model.model_fields.items() if (f.alias or n) == part), None)
        if info is None:
            return UNKNOWN_UNIT
        nested = [t for t in (info.annotation, *typing.get_args(info.annotation))
                  if isinstance(t, type) and issubclass(t, BaseModel)]
        model = nested[0] if nested else None
    return UNKNOWN_UNIT


def _error_metrics(batch: dict[str, Any]) -> list[str]:
    names = sorted({k for t in batch["trials"] for k, v in t.get("metrics", {}).items() if _is_number(v)})
    return [n for n in names if "err" in n][:MAX_DEFAULT_METRICS]


def _success_lines(ax: Any, batch: dict[str, Any], key: str, prefix: str, mission: CompiledMission | None) -> None:
    """Success rate against swept ``key`` with Wilson error bars, a line per combination of the other
    swept keys; labels start with ``prefix``.  Values written as quantities are drawn in their base unit."""
    from taskflow.readers.plots import axis_label

    sweep: dict[str, list[Any]] = batch["sweep"]
    values = sweep[key]
    others = [k for k in sweep if k != key]
    quantities = _quantities(values)
    numeric = quantities is not None or all(_is_number(v) for v in values)
    at = quantities[0] if quantities is not None else [float(v) if numeric else float(i) for i, v in enumerate(values)]
    xs = {repr(v): x for v, x in zip(values, at)}
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
    ax.set_xlabel(axis_label(key, key_unit(key, values, mission)))
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
    mission = campaign_mission(batches[0][1])
    for name, b in batches:
        _success_lines(ax, b, key, f"{name} ({b.get('trials_requested', '?')} trials per point)", mission)
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
    root = Path(batch_dir)
    return [_save(fig, root / name) for name, fig in campaign_figures(load_batch(root), metrics)]


def campaign_figures(batch: dict[str, Any], metrics: list[str] | None = None) -> list[tuple[str, Any]]:
    """The campaign's figures (file name, matplotlib figure), not yet written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from taskflow.readers.plots import axis_label

    conditions = batch["conditions"]
    n_per = batch.get("trials_requested", "?")
    mission = campaign_mission(batch)
    out: list[tuple[str, Any]] = []
    sweep: dict[str, list[Any]] = batch.get("sweep") or {}
    for key in sweep:
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        _success_lines(ax, batch, key, "", mission)
        ax.set_title(f"{batch['mission']}: success vs {key.rsplit('.', 1)[-1]} ({n_per} trials per point)", fontsize=10)
        out.append((f"success_vs_{key.replace('.', '_')}.png", fig))
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
            ax.set_xlabel(", ".join(axis_label(k, key_unit(k, v, mission)) for k, v in sweep.items()), fontsize=8)
        ax.set_ylabel(axis_label(metric, metric_unit(metric, mission)))
        ax.grid(alpha=0.3, axis="y")
        ax.set_title(f"{batch['mission']}: {metric} per condition ({n_per} trials each)", fontsize=10)
        out.append((f"distribution_{metric}.png", fig))
    return out
