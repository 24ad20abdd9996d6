"""Monte Carlo campaigns: N independent seeded runs per condition, on a local pool or a Ray cluster.

Trial ``i`` runs with seed ``seed + i``: its world parameters are drawn from the distributions the
mission declares and its sensors' noise from the same seed, each with its own PyBullet DIRECT client in
whichever process or node runs it (:mod:`taskflow.campaigns.backends`).  With a sweep (``--sweep KEY=V1,V2``,
repeatable) every condition of the grid runs the same seeds (:mod:`taskflow.campaigns.campaign`).

The batch directory is a campaign directory: one record per trial is written the moment the trial
finishes, and ``batch.json`` is rebuilt from the records; it holds every trial's summary and the
aggregates, over all trials and per condition, with their 95 % intervals (:mod:`taskflow.campaigns.stats`):
mission success (Wilson interval), item success for missions that loop over items (screws,
waypoints), each declared property's violation rate (Wilson interval; over the trials that decided it), and
mean/std/min/max with the t interval of the mean of every numeric final metric.
``batch.json`` depends on the mission and the seeds alone; wall-clock figures go to ``timing.json``.

Ctrl-C or SIGTERM stops a batch at once: unfinished trials are cancelled, running workers are
terminated, and ``batch.json`` is written with the trials that finished (``interrupted: true``); so
does a worker that dies (:class:`~taskflow.campaigns.backends.WorkerLost`, raised once ``batch.json`` is written);
:func:`resume_batch` then runs only the missing trials and writes the ``batch.json`` an uninterrupted
run would have written.  :class:`BatchStopped` says which signal stopped it (``taskflow batch``
exits 130 after Ctrl-C, 143 after SIGTERM, as ``taskflow run`` does).

While it runs, :class:`BatchProgress` reports each finished trial on stderr (the command line passes
one): on a terminal one line rewritten in place — trials done / total, successes so far, the estimated
time left — otherwise one line per finished trial.  It writes nothing into the campaign's files.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from taskflow.campaigns.backends import BackendError, TrialInterrupted, TrialJob, WorkerLost, make_backend
from taskflow.campaigns.campaign import Campaign, CampaignSpec, file_sha256, parse_sweep, read_value
from taskflow.campaigns.stats import mean_interval, wilson_interval
from taskflow.execution.records import write_json
from taskflow.mission.data import clean_floats


class BatchInterrupted(Exception):
    """Raised inside the parent on SIGTERM so the batch ends like on Ctrl-C."""

    signum = signal.SIGTERM


class BatchStopped(KeyboardInterrupt):
    """A batch stopped by a signal once its partial ``batch.json`` is written: ``str()`` is that file's
    path, :attr:`signum` the signal (``SIGINT`` for Ctrl-C, ``SIGTERM``)."""

    def __init__(self, batch_file: str, signum: int) -> None:
        super().__init__(batch_file)
        self.signum = signum


class BatchProgress:
    """Reports a batch's finished trials on ``stream`` (stderr by default).  ``tty`` (default: whether
    the stream is a terminal) rewrites one line in place: ``batch NAME: 3/10 trials, 3 succeeded, ETA
    12 s``; otherwise one line per trial, with its condition, seed and outcome.  The time left is the
    wall-clock time per trial so far times the trials left — a display only, never recorded."""

    def __init__(self, stream: TextIO | None = None, tty: bool | None = None) -> None:
        self.stream: TextIO = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.name, self.total, self.done, self.ok, self.new = "", 0, 0, 0, 0
        self.t0 = 0.0
        self._open_line = False

    def start(self, name: str, total: int, done: int, succeeded: int) -> None:
        """A campaign of ``total`` trials of which ``done`` (``succeeded`` of them) are already recorded."""
        self.name, self.total, self.done, self.ok, self.new = name, total, done, succeeded, 0
        self.t0 = time.perf_counter()
        if self.tty:
            self._write(f"\r{self._fit(f'batch {name}: {done}/{total} trials, {succeeded} succeeded, running …')}\x1b[K")
            self._open_line = True

    def trial(self, condition: int, seed: int, outcome: str) -> None:
        """One more finished trial."""
        self.done, self.new = self.done + 1, self.new + 1
        self.ok += outcome == "succeeded"
        left = self.total - self.done
        eta = (time.perf_counter() - self.t0) / self.new * left
        status = (f"{self.done}/{self.total} trials, {self.ok} succeeded"
                  + (f", ETA {_duration(eta)}" if left else ""))
        if self.tty:
            self._write(f"\r{self._fit(f'batch {self.name}: {status}')}\x1b[K")
            self._open_line = True
        else:
            self._write(f"batch {self.name}: {status} (condition {condition} seed {seed}: {outcome})\n")

    def finish(self) -> None:
        """End the terminal's progress line (before the table, or an interruption's message)."""
        if self._open_line:
            self._write("\n")
            self._open_line = False

    def _fit(self, line: str) -> str:
        """``line`` cut to the terminal's width, so that ``\\r`` rewrites it instead of leaving a wrapped
        remainder behind."""
        try:
            width = os.get_terminal_size(self.stream.fileno()).columns
        except (OSError, ValueError, AttributeError):
            return line
        return line if width <= 1 or len(line) < width else line[:width - 2] + "…"

    def _write(self, text: str) -> None:
        self.stream.write(text)
        self.stream.flush()


def _duration(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s} s" if s < 60 else f"{s // 60} min {s % 60:02d} s" if s < 3600 else f"{s // 3600} h {s % 3600 // 60:02d} min"


def _metric_stats(vals: np.ndarray) -> dict[str, Any]:
    ci = mean_interval(vals)
    return {"mean": ci.mean, "std": float(vals.std()), "min": float(vals.min()), "max": float(vals.max()),
            "n": int(vals.size), "ci95": None if ci.low is None else [ci.low, ci.high]}


def _wilson(k: int, n: int) -> list[float] | None:
    return list(wilson_interval(k, n)) if n else None


def aggregate(summaries: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate with its Wilson 95 % interval (``success_ci95``), outcome counts, item success per foreach loop
    (Wilson interval over the items, each an independent trial counted on its last attempt; with ``retry``, also
    ``attempts``, ``retried``, ``recovered``), and mean (with the t 95 % interval of the mean, ``ci95``), std
    (population, ddof 0), min, max of every numeric final metric and of ``sim_time_s``."""
    n = len(summaries)
    outcomes: dict[str, int] = {}
    for s in summaries:
        outcomes[s["outcome"]] = outcomes.get(s["outcome"], 0) + 1
    stats: dict[str, dict[str, Any]] = {}
    keys = sorted({k for s in summaries for k, v in s.get("metrics", {}).items()
                   if isinstance(v, (int, float)) and not isinstance(v, bool)})
    for k in keys:
        vals = np.array([s["metrics"][k] for s in summaries
                         if isinstance(s.get("metrics", {}).get(k), (int, float)) and s["metrics"][k] is not None
                         and math.isfinite(s["metrics"][k])], dtype=float)
        if vals.size:
            stats[k] = _metric_stats(vals)
    vals = np.array([s["sim_time_s"] for s in summaries], dtype=float)
    if vals.size:
        stats["sim_time_s"] = _metric_stats(vals)
    items: dict[str, dict[str, Any]] = {}
    for s in summaries:
        for loop, c in s.get("items", {}).items():
            agg = items.setdefault(loop, {"attempted": 0, "succeeded": 0, "rule": c.get("rule")})
            for key in {"attempted", "succeeded", "attempts", "retried", "recovered"} & set(c):  # the last 3: `retry`
                agg[key] = agg.get(key, 0) + c[key]
    for agg in items.values():
        agg["failed"] = agg["attempted"] - agg["succeeded"]
        agg["success_rate"] = agg["succeeded"] / agg["attempted"] if agg["attempted"] else None
        agg["success_ci95"] = _wilson(agg["succeeded"], agg["attempted"])
    ok = outcomes.get("succeeded", 0)
    out = {"trials": n, "success_rate": ok / n if n else 0.0, "success_ci95": _wilson(ok, n),
           "outcomes": outcomes, "items": items, "metrics": stats}
    properties = property_rates(summaries)
    if properties:
        out["properties"] = properties
    return out


def property_rates(summaries: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Each declared property's verdicts over the trials (``summary.json``'s ``properties``): ``held``,
    ``violated``, ``not_decided`` counts, ``violation_rate`` = violated / (held + violated) with its Wilson 95 %
    interval ``violation_ci95`` (a trial cut short before deciding it does not count), and the earliest
    violation time ``first_violation_t``.  Empty when no trial's mission declares properties."""
    out: dict[str, dict[str, Any]] = {}
    for s in summaries:
        verdicts = s.get("properties")
        if not isinstance(verdicts, dict):
            continue
        for name, v in verdicts.items():
            if not isinstance(v, dict):
                continue
            agg = out.setdefault(name, {"pattern": v.get("pattern", ""), "held": 0, "violated": 0, "not_decided": 0})
            verdict = v.get("verdict")
            if verdict in ("held", "violated", "not_decided"):
                agg[verdict] += 1
            t = v.get("t")
            if verdict == "violated" and isinstance(t, (int, float)):
                agg["first_violation_t"] = min(agg.get("first_violation_t", t), t)
    for agg in out.values():
        decided = agg["held"] + agg["violated"]
        agg["violation_rate"] = agg["violated"] / decided if decided else None
        agg["violation_ci95"] = _wilson(agg["violated"], decided)
    return out


def run_batch(path: str, *, trials: int, workers: int | None = None, seed: int = 0,
              overrides: list[str] | None = None, out: str | Path | None = None,
              max_time: float | None = None, keep_runs: bool = False, sweep: list[str] | None = None,
              backend: str = "pool", address: str | None = None,
              progress: BatchProgress | None = None) -> dict[str, Any]:
    """Start a campaign in ``out`` (a new directory, or one without a campaign), run it, write
    ``batch.json`` and return its content with the wall-clock ``timing`` and ``batch_file``.

    ``sweep`` holds ``KEY=V1,V2,...`` items (:func:`taskflow.campaigns.campaign.parse_sweep`); ``backend`` is
    ``pool`` (``workers`` local processes) or ``ray`` (the cluster at ``address``, or a local one of
    ``workers`` CPUs).  ``progress`` reports each finished trial.  On Ctrl-C / SIGTERM the partial
    ``batch.json`` is written and :class:`BatchStopped` (a :class:`KeyboardInterrupt`) is raised, its
    message the ``batch.json`` path."""
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    spec = CampaignSpec(mission=str(Path(path).resolve()), trials=trials, first_seed=seed,
                        overrides=list(overrides or []), sweep=parse_sweep(sweep or [], overrides),
                        max_time=max_time, keep_runs=keep_runs)
    name = check_conditions(spec)  # the mission loads: it is a readable file
    spec.mission_sha256 = file_sha256(spec.mission)
    out_dir = Path(out) if out is not None else Path("runs") / f"batch-{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    return _run(Campaign.create(out_dir, spec), name, workers, backend, address, progress)


def resume_batch(directory: str | Path, *, workers: int | None = None, backend: str = "pool",
                 address: str | None = None, progress: BatchProgress | None = None) -> dict[str, Any]:
    """Run the trials of the campaign in ``directory`` that have no record yet and rewrite its
    ``batch.json``: the same file an uninterrupted run writes."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    campaign = Campaign.open(directory)
    campaign.check_mission()  # before the mission file is parsed
    return _run(campaign, check_conditions(campaign.spec), workers, backend, address, progress)


def check_conditions(spec: CampaignSpec) -> str:
    """Load the mission under every condition of the sweep (a bad key or value fails here, with its
    ``--set``/``--sweep`` named, before any trial starts) and return the mission's name."""
    from dataclasses import replace

    from taskflow.errors import MissionError
    from taskflow.mission.loader import load_mission

    name = ""
    for c in spec.conditions():
        try:
            name = load_mission(spec.mission, spec.overrides + c.overrides).name
        except MissionError as exc:  # the loader names every override --set: say which came from --sweep
            swept = [f"--set {o}" for o in c.overrides]
            raise MissionError([replace(p, message=_as_sweep(p.message, swept)) for p in exc.problems]) from None
    return name


def _as_sweep(message: str, swept: list[str]) -> str:
    for s in swept:
        if s in message:
            return message.replace(s, "--sweep " + s[len("--set "):])
    return message


def _run(campaign: Campaign, name: str, workers: int | None, backend: str, address: str | None,
         progress: BatchProgress | None = None) -> dict[str, Any]:
    spec = campaign.spec
    todo = campaign.missing()
    n_workers = max(1, min(workers or os.cpu_count() or 1, max(1, len(todo))))
    jobs = [TrialJob(spec.mission, tuple(spec.overrides + c.overrides), s, spec.max_time,
                     str(campaign.run_dir(c.index, s)) if spec.keep_runs else None) for c, s in todo]

    def on_result(i: int, result: tuple[dict[str, Any], dict[str, Any]]) -> None:
        campaign.record(todo[i][0].index, todo[i][1], *result)
        if progress is not None:
            progress.trial(todo[i][0].index, todo[i][1], str(result[0].get("outcome")))

    t0, started = time.perf_counter(), time.time()
    interrupted: BaseException | None = None
    lost: WorkerLost | None = None
    runner = None
    old_term = None
    try:
        if jobs:
            try:
                runner = make_backend(backend, n_workers, address)
            except BackendError as exc:
                raise BackendError(f"{exc} (the campaign waits in {campaign.root}: taskflow batch --resume "
                                   f"{campaign.root} runs it)") from None
            old_term = _on_sigterm()  # after the backend starts: Ray's own handler must not win
            if progress is not None:  # once the backend is up: a backend that cannot start is one line
                recorded = campaign.records()
                progress.start(name, spec.trials * len(spec.conditions()), len(recorded),
                               sum(r["summary"].get("outcome") == "succeeded" for r in recorded.values()))
            runner.run(jobs, on_result)
    except (KeyboardInterrupt, BatchInterrupted, TrialInterrupted) as exc:
        interrupted = exc
    except WorkerLost as exc:
        lost = exc
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
        if runner is not None:
            runner.close()
        if progress is not None:
            progress.finish()
    wall = time.perf_counter() - t0
    result, timing_trials = campaign_result(campaign, name)
    batch_file = campaign.root / "batch.json"
    write_json(batch_file, result)
    timing = clean_floats({"backend": backend, "address": address,
                           "workers": runner.workers if runner is not None else n_workers,
                           "trials_run": len(jobs) - len(campaign.missing()) if jobs else 0,
                           "started": started, "total_wall_s": wall, "trials": timing_trials})
    timing["per_trial_wall_s"] = wall / max(1, timing["trials_run"])
    timing.update(cpu_figures(timing_trials))
    write_json(campaign.root / "timing.json", timing)
    if interrupted is not None:
        signum = getattr(interrupted, "signum", signal.SIGINT)  # BatchInterrupted: SIGTERM; a trial's: its own
        raise BatchStopped(str(batch_file), signum) from None
    if lost is not None:
        raise WorkerLost(f"{lost}: the trials that finished are recorded in {batch_file}; run the rest with "
                         f"taskflow batch --resume {campaign.root}")
    return dict(result, timing=timing, batch_file=str(batch_file))


def cpu_figures(trials: list[dict[str, Any]]) -> dict[str, Any]:
    """What the campaign's trials cost in CPU: ``trial_cpu_s`` (their sum: loading, world, control loop, records;
    the batch's own start-up and aggregation not included), ``per_trial_cpu_s`` and ``trials_per_cpu_hour`` — a
    figure that does not depend on how many cores ran them or what else the machine did.  Over the trials that
    recorded their CPU time (a campaign resumed from records of an older version may hold some that did not)."""
    cpu = [float(t["cpu_s"]) for t in trials if isinstance(t.get("cpu_s"), (int, float))]
    total = sum(cpu)
    if not cpu or total <= 0.0:
        return {}
    return {"trials_with_cpu": len(cpu), "trial_cpu_s": total, "per_trial_cpu_s": total / len(cpu),
            "trials_per_cpu_hour": 3600.0 * len(cpu) / total}


def campaign_result(campaign: Campaign, name: str) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """``batch.json`` of the campaign as its records stand (trials in condition, then seed order), and
    the records' wall-clock figures in the same order."""
    spec = campaign.spec
    records = campaign.records()
    conditions, trials, timing = [], [], []
    for c in spec.conditions():
        done = [records[(c.index, s)] for s in spec.seeds() if (c.index, s) in records]
        summaries = [r["summary"] for r in done]
        conditions.append({"index": c.index, "label": c.label, "values": c.parsed_values(),
                           "overrides": c.overrides, "aggregate": aggregate(summaries)})
        trials += [dict(s, condition=c.index) for s in summaries]
        timing += [dict(r["timing"], condition=c.index) for r in done]
    expected = spec.trials * len(conditions)
    result = {
        "mission": name, "file": spec.mission, "overrides": spec.overrides, "first_seed": spec.first_seed,
        "trials_requested": spec.trials, "sweep": {k: [read_value(v) for v in vals] for k, vals in spec.sweep},
        "interrupted": len(trials) < expected, "aggregate": aggregate(trials),
        "conditions": conditions, "trials": trials,
    }
    return clean_floats(result), timing


def _on_sigterm() -> Any:
    def handler(signum: int, frame: Any) -> None:
        raise BatchInterrupted()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        return None


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}"


def _rate(k: int, n: int, rate: float | None, ci: list[float] | None) -> str:
    return (f"{k}/{n}" + (f" = {_pct(rate)} %" if rate is not None else "")
            + (f" [{_pct(ci[0])}, {_pct(ci[1])}]" if ci else ""))


def _aggregate_lines(agg: dict[str, Any]) -> list[str]:
    lines = [f"success {_rate(agg['outcomes'].get('succeeded', 0), agg['trials'], agg['success_rate'], agg.get('success_ci95'))}"
             f" (95 % Wilson)  outcomes {json.dumps(agg['outcomes'])}"]
    for loop, c in agg.get("items", {}).items():
        lines.append(f"items of {loop}: {_rate(c['succeeded'], c['attempted'], c['success_rate'], c.get('success_ci95'))}"
                     f" succeeded, rule per run: {c['rule']}")
        if "attempts" in c:  # a loop that retries
            lines.append(f"  attempts of {loop}: {c['attempts']} over {c['attempted']} items; {c['retried']} retried, "
                         f"{c['recovered']} of them then succeeded")
    for name, c in agg.get("properties", {}).items():
        undecided = f", {c['not_decided']} not decided" if c["not_decided"] else ""
        lines.append(f"property {name} ({c['pattern']}): violated in "
                     f"{_rate(c['violated'], c['held'] + c['violated'], c['violation_rate'], c.get('violation_ci95'))}"
                     f" (95 % Wilson){undecided}")
    lines.append(f"{'metric':34s} {'mean':>11s} {'95 % interval of the mean':>25s} {'std':>11s} {'min':>11s} {'max':>11s}")
    for k, m in agg["metrics"].items():
        ci = m.get("ci95")
        ci_text = "-" if not ci else f"[{ci[0]:.5g}, {ci[1]:.5g}]"
        lines.append(f"{k:34s} {m['mean']:11.5g} {ci_text:>25s} {m['std']:11.5g} {m['min']:11.5g} {m['max']:11.5g}")
    return lines


def format_table(result: dict[str, Any]) -> str:
    """The batch as text: the whole campaign, then, when sweeping, each condition."""
    agg, timing = result["aggregate"], result.get("timing", {})
    head = (f"{result['mission']}: {agg['trials']} trials  wall {timing.get('total_wall_s', 0):.1f} s "
            f"({timing.get('workers', '?')} workers, {timing.get('backend', 'pool')})")
    if timing.get("trials_per_cpu_hour"):
        head += f"  {timing['per_trial_cpu_s']:.2f} CPU s a trial: {timing['trials_per_cpu_hour']:.0f} trials per CPU-hour"
    conditions = result.get("conditions", [])
    if result.get("interrupted"):
        head += f"  INTERRUPTED after {agg['trials']} of {result.get('trials_requested', 0) * max(1, len(conditions))}"
    lines = [head, *_aggregate_lines(agg)]
    if len(conditions) > 1:
        for c in conditions:
            lines += ["", f"condition {c['index']}: {c['label']}  ({c['aggregate']['trials']} trials)",
                      *_aggregate_lines(c["aggregate"])]
    return "\n".join(lines)
