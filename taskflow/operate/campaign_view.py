"""The campaign page (``taskflow view BATCH_DIR``): what the page (``taskflow/operate/web/campaign.html``)
asks for, as JSON.  :mod:`taskflow.operate.campaign_http` serves it.

``GET /campaign``   :meth:`CampaignView.page`: the campaign as ``batch.json`` tells it — mission, trials asked
                    and recorded, ``interrupted``, the sweep; ``aggregate`` and each condition's ``aggregate``
                    exactly as ``batch.json`` holds them (mission success with its Wilson 95 % interval,
                    outcome counts, item success per loop, each declared property's held / violated / not
                    decided counts, violation rate with its interval and earliest violation, every metric's
                    mean with its t interval: :func:`taskflow.campaigns.batch.aggregate` computed them once,
                    the page recomputes nothing); and the trials: seed, condition, outcome, sim time, each
                    property's verdict, and ``replay`` — the address of the kept run's page (``--keep-runs``),
                    relative to the campaign page, or null

A kept trial's run folder is served under ``/run/<folder>/`` (``run/trial-00003/``, ``run/c001/trial-00003/``
when sweeping: :func:`taskflow.campaigns.campaign.trial_dir`) by the same server, with the run view's routes
(:mod:`taskflow.operate.view_http`).

``batch.json`` is untrusted input (a CI artifact, a campaign from a cluster): it is read by the batch readers'
one reader (:func:`taskflow.campaigns.compare.load_batch`: inside its folder, bounded, its fields' types
checked), and each kept trial's ``summary.json`` by the run readers' (:mod:`taskflow.execution.record_io`):
a trial folder that is a link out of the campaign's, a summary that is malformed or that tells another
seed or outcome than ``batch.json`` gets no replay link and its reason (``run_error``) on the page instead.
A malformed ``batch.json`` is a :class:`~taskflow.operate.view.ViewError` of one line naming the file (and its
line, when it is not JSON).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from taskflow.campaigns.campaign import CampaignError, trial_dir
from taskflow.campaigns.compare import load_batch
from taskflow.execution.record_io import RunDirError, check_summary, inside, read_json
from taskflow.operate.view import ViewError

RUN_PREFIX = "run"
"""The path under which the campaign's server serves its kept trials' pages (``/run/trial-00003/``)."""


def _kept_run(root: Path, rel: str, trial: dict[str, Any]) -> tuple[str | None, str | None]:
    """``(rel, None)`` when ``root / rel`` is a kept run of ``trial`` (its summary readable and telling the same
    seed and outcome as ``batch.json``); ``(None, why not)`` when it is there but not that; ``(None, None)``
    when there is no such folder (a campaign run without ``--keep-runs``)."""
    path = root / rel
    if not (path.exists() or path.is_symlink()):
        return None, None
    try:
        real = inside(root, rel)
        if not real.is_dir():
            raise RunDirError(f"{path}: not a folder — a kept trial is a run folder")
        summary = check_summary(read_json(root, f"{rel}/summary.json"), path / "summary.json")
        for key in ("seed", "outcome"):
            if summary.get(key) != trial.get(key):
                raise RunDirError(f"{path / 'summary.json'}: {key} {summary.get(key)!r}, but batch.json's trial says "
                                  f"{trial.get(key)!r} — not this trial's run")
    except RunDirError as exc:
        return None, str(exc)
    return rel, None


def _verdicts(trial: dict[str, Any]) -> dict[str, Any]:
    return {name: {"verdict": v["verdict"], "t": v.get("t")} for name, v in trial.get("properties", {}).items()}


class CampaignView:
    """A batch folder's page: its ``batch.json`` (checked) and which trials' run folders were kept."""

    def __init__(self, root: Path, batch: dict[str, Any]) -> None:
        self.root = root
        self.batch = batch
        swept = bool(batch.get("sweep"))
        self.trials: list[dict[str, Any]] = []
        self.runs: dict[str, Path] = {}  # folder (relative) → its path, for each kept trial with a replay
        for t in batch["trials"]:
            seed, condition = t.get("seed"), t.get("condition", 0)
            rel, error = _kept_run(root, trial_dir(swept, condition, seed), t) if isinstance(seed, int) else (None, None)
            if rel is not None:
                self.runs[rel] = root / rel
            self.trials.append({"seed": seed, "condition": condition, "outcome": t["outcome"],
                                "reason": t.get("reason", ""), "sim_time_s": t.get("sim_time_s"),
                                "properties": _verdicts(t),
                                "replay": None if rel is None else f"{RUN_PREFIX}/{rel}/", "run_error": error})

    def page(self) -> dict[str, Any]:
        """``GET /campaign`` (module docstring)."""
        b = self.batch
        return {"mission": b.get("mission", ""), "file": b.get("file", ""), "folder": str(self.root),
                "trials_requested": b.get("trials_requested"), "first_seed": b.get("first_seed"),
                "interrupted": bool(b.get("interrupted", False)), "sweep": b.get("sweep") or {},
                "overrides": b.get("overrides", []), "aggregate": b["aggregate"], "conditions": b["conditions"],
                "trials": self.trials, "kept": len(self.runs)}


def is_campaign(folder: str | Path) -> bool:
    """``folder`` holds a campaign's ``batch.json`` and is no run folder (``trace.csv``)."""
    d = Path(folder)
    return (d / "batch.json").is_file() and not (d / "trace.csv").exists()


def open_campaign(folder: str | Path) -> CampaignView:
    """The page of the batch folder ``folder``; :class:`ViewError` (one line, naming the file) when its
    ``batch.json`` is malformed or hostile."""
    root = Path(folder)
    if not root.is_dir():
        raise ViewError(f"{root}: no such folder")
    try:
        return CampaignView(root, load_batch(root))
    except CampaignError as exc:
        raise ViewError(str(exc)) from None
