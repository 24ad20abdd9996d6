"""A campaign directory: what was asked, one record per finished trial, and the sweep's conditions.

``DIR/``
  ``campaign.json``          the campaign as asked (:class:`CampaignSpec`): mission file and the
                             sha256 of its bytes, overrides, sweep, trials per condition, first seed,
                             max time; written before any trial starts, read back by
                             ``taskflow batch --resume DIR``, which runs the mission only while the file
                             is still the one the campaign started with (:meth:`Campaign.check_mission`)
  ``trials/cCCC-sSSSSS.json`` one record per finished trial (condition ``CCC``, seed ``SSSSS``): its
                             ``summary`` (as ``summary.json`` of a run) and its wall-clock ``timing``;
                             written atomically the moment the trial's result reaches the parent, so an
                             interrupted campaign keeps every trial that finished
  ``batch.json``             the campaign's result, rebuilt from the records (:mod:`taskflow.campaigns.batch`);
                             it depends on the mission and the seeds alone
  ``timing.json``            wall-clock figures only
  ``trial-SSSSS/``           with ``--keep-runs``, each trial's run directory (``cCCC/trial-SSSSS/``
                             when sweeping)

A sweep is the grid of every combination of its keys' values (:func:`parse_sweep`,
:func:`grid`); every condition runs the same seeds, so two conditions differ only by the swept values
(common random numbers: the comparison is paired by seed).
"""

from __future__ import annotations

import hashlib
import itertools
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from taskflow.execution.record_io import NotJSONError, RunDirError, check_summary, read_json
from taskflow.execution.records import write_json
from taskflow.mission.data import clean_floats
from taskflow.mission.yamlsrc import MissionLoader


def read_value(text: str) -> Any:
    """A swept value read as ``--set`` reads it (the mission's safe YAML 1.2 reader: ``on`` stays text)."""
    return yaml.load(text, Loader=MissionLoader)

SPEC_FILE, TRIALS_DIR = "campaign.json", "trials"


class CampaignError(Exception):
    """A campaign directory or a sweep that cannot be used; the message says what would be valid."""


@dataclass(frozen=True)
class Condition:
    """One point of a sweep's grid: ``values`` maps each swept key to its value as written on the command
    line; ``overrides`` are the matching ``KEY=VALUE`` strings applied after the campaign's own."""

    index: int
    values: dict[str, str]

    @property
    def overrides(self) -> list[str]:
        return [f"{k}={v}" for k, v in self.values.items()]

    @property
    def label(self) -> str:
        """``key=value, key=value`` ("all" when nothing is swept)."""
        return ", ".join(self.overrides) or "all"

    def parsed_values(self) -> dict[str, Any]:
        """The values read as YAML, as the mission reads them (``0.5`` a number, ``[1, 2]`` a list)."""
        return {k: read_value(v) for k, v in self.values.items()}


def _split_values(text: str) -> list[str]:
    """Split at the commas that are not inside brackets, braces or quotes: ``1,[2, 3],'a,b'`` has three."""
    out: list[str] = []
    cur: list[str] = []
    depth, quote = 0, ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur).strip())
    if depth != 0 or quote:
        raise CampaignError(f"--sweep value list {text!r}: unbalanced brackets or quotes")
    return out


def parse_sweep(items: list[str], overrides: list[str] | None = None) -> list[tuple[str, list[str]]]:
    """``["world.params.dropout=0,0.25,0.5", ...]`` → ``[("world.params.dropout", ["0", "0.25", "0.5"]), ...]``.

    Each item is ``KEY=V1,V2,...`` (commas inside ``[...]``, ``{...}`` or quotes belong to one value);
    a key may be swept once and not also be set with ``--set``; values are not empty and not repeated."""
    sweep: list[tuple[str, list[str]]] = []
    set_keys = {o.partition("=")[0].strip() for o in overrides or []}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key or not text.strip():
            raise CampaignError(f"--sweep {item!r} is not KEY=V1,V2,...: write e.g. "
                                "--sweep world.params.dropout=0,0.25,0.5")
        values = _split_values(text)
        if any(not v for v in values):
            raise CampaignError(f"--sweep {item!r}: an empty value (two commas in a row or a trailing comma)")
        for v in values:
            try:
                read_value(v)
            except yaml.YAMLError:
                raise CampaignError(f"--sweep {key}: value {v!r} is not valid YAML") from None
        dup = sorted({v for v in values if values.count(v) > 1})
        if dup:
            raise CampaignError(f"--sweep {key}: value {dup[0]!r} is given twice")
        if any(key == k for k, _ in sweep):
            raise CampaignError(f"--sweep {key} is given twice: list all its values in one --sweep")
        if key in set_keys:
            raise CampaignError(f"--sweep {key} is also set with --set: drop one of them")
        sweep.append((key, values))
    return sweep


def grid(sweep: list[tuple[str, list[str]]]) -> list[Condition]:
    """Every combination of the swept values, the last key varying fastest; one empty condition when
    nothing is swept."""
    keys = [k for k, _ in sweep]
    return [Condition(i, dict(zip(keys, combo)))
            for i, combo in enumerate(itertools.product(*(vals for _, vals in sweep)))]


@dataclass
class CampaignSpec:
    """What a campaign runs: ``trials`` seeds (``first_seed`` …) of ``mission`` under each condition of
    ``sweep``.  ``mission`` is an absolute path: a trial loads it wherever it runs."""

    mission: str
    trials: int
    first_seed: int = 0
    overrides: list[str] = field(default_factory=list)
    sweep: list[tuple[str, list[str]]] = field(default_factory=list)
    max_time: float | None = None
    keep_runs: bool = False
    mission_sha256: str = ""  # of the mission file's bytes when the campaign started ("" : not recorded)

    def conditions(self) -> list[Condition]:
        return grid(self.sweep)

    def seeds(self) -> range:
        return range(self.first_seed, self.first_seed + self.trials)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["sweep"] = [[k, list(v)] for k, v in self.sweep]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CampaignSpec:
        return cls(mission=str(d["mission"]), trials=int(d["trials"]), first_seed=int(d["first_seed"]),
                   overrides=[str(o) for o in d["overrides"]],
                   sweep=[(str(k), [str(v) for v in vals]) for k, vals in d["sweep"]],
                   max_time=None if d.get("max_time") is None else float(d["max_time"]),
                   keep_runs=bool(d.get("keep_runs", False)), mission_sha256=str(d.get("mission_sha256", "")))


def file_sha256(path: str | Path) -> str:
    """The sha256 of a file's bytes (read in blocks), as a campaign records its mission file."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def trial_dir(swept: bool, condition: int, seed: int) -> str:
    """A kept trial's run directory inside its campaign's (``--keep-runs``): ``trial-SSSSS``, or
    ``cCCC/trial-SSSSS`` when the campaign sweeps."""
    return f"c{condition:03d}/trial-{seed:05d}" if swept else f"trial-{seed:05d}"


def record_name(condition: int, seed: int) -> str:
    return f"c{condition:03d}-s{seed:05d}.json"


class Campaign:
    """A campaign directory on disk (see the module docstring)."""

    def __init__(self, root: Path, spec: CampaignSpec) -> None:
        self.root = root
        self.spec = spec

    @classmethod
    def create(cls, root: str | Path, spec: CampaignSpec) -> Campaign:
        """Start a campaign in ``root`` (created if missing); refuses a directory that holds one already."""
        root = Path(root)
        if (root / SPEC_FILE).exists():
            raise CampaignError(f"{root} already holds a campaign: finish it with taskflow batch --resume {root}, "
                                "or choose another --out")
        (root / TRIALS_DIR).mkdir(parents=True, exist_ok=True)
        write_json(root / SPEC_FILE, spec.as_dict())
        return cls(root, spec)

    @classmethod
    def open(cls, root: str | Path) -> Campaign:
        """The campaign in ``root``, as ``taskflow batch`` left it."""
        root = Path(root)
        spec_file = root / SPEC_FILE
        if not spec_file.is_file():
            what = "no such directory" if not root.is_dir() else f"not a campaign directory (it has no {SPEC_FILE})"
            raise CampaignError(f"{root}: {what}")
        try:
            spec = CampaignSpec.from_dict(read_json(root, SPEC_FILE))
        except RunDirError as exc:
            raise CampaignError(str(exc)) from None
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise CampaignError(f"{spec_file}: not a campaign description ({type(exc).__name__}: "
                                f"{str(exc)[:80]})") from None
        (root / TRIALS_DIR).mkdir(exist_ok=True)
        return cls(root, spec)

    def check_mission(self) -> None:
        """Refuse to resume unless ``campaign.json``'s mission file is still the file this campaign started
        with (the sha256 of its bytes): a resume must not mix two missions in one ``batch.json``, and a
        campaign directory is a record that may come from elsewhere, so the file it names is never parsed
        (nor any of its text shown) before its fingerprint matches."""
        spec, where = self.spec, self.root / SPEC_FILE
        if not spec.mission_sha256:
            raise CampaignError(f"{where}: no mission_sha256 (the campaign's fingerprint of its mission file) — "
                                f"a resume runs only the mission a campaign started with: start it again with "
                                f"taskflow batch MISSION")
        path = Path(spec.mission)
        if not path.is_absolute() or not path.is_file():
            raise CampaignError(f"{where}: its mission {str(path)[:200]!r} is not an existing file (an absolute "
                                "path) — a resume runs the mission file the campaign started with")
        if file_sha256(path) != spec.mission_sha256:
            raise CampaignError(f"{where}: {str(path)[:200]} is not the mission file this campaign started with "
                                "(its sha256 differs) — a resume would mix two missions: start a new campaign")

    def run_dir(self, condition: int, seed: int) -> Path:
        """Where a trial's run directory goes with ``keep_runs``."""
        return self.root / trial_dir(bool(self.spec.sweep), condition, seed)

    def record(self, condition: int, seed: int, summary: dict[str, Any], timing: dict[str, Any]) -> None:
        """Store one finished trial (atomically: a record on disk is always whole)."""
        write_json(self.root / TRIALS_DIR / record_name(condition, seed),
                   clean_floats({"condition": condition, "seed": seed, "summary": summary, "timing": timing}))

    def records(self) -> dict[tuple[int, int], dict[str, Any]]:
        """The finished trials of this campaign, keyed by (condition, seed); files of other names, of
        conditions or seeds outside the spec, or cut short (not whole JSON: a record being written when
        the machine died) are ignored — such a trial runs again.  A record that is hostile or was not
        written by taskflow — a link out of the folder, too large, whole JSON with a field of the wrong
        type — is a :class:`CampaignError` naming it (:mod:`taskflow.execution.record_io`)."""
        wanted = {record_name(c.index, s): (c.index, s) for c in self.spec.conditions() for s in self.spec.seeds()}
        out = {}
        for f in sorted((self.root / TRIALS_DIR).glob("c*-s*.json")):
            key = wanted.get(f.name)
            if key is None:
                continue
            try:
                try:
                    rec = read_json(self.root, f"{TRIALS_DIR}/{f.name}")
                except NotJSONError:
                    continue  # cut short: the trial runs again
                if not isinstance(rec, dict) or not isinstance(rec.get("timing"), dict):
                    raise RunDirError(f"{f}: a trial record is an object with summary and timing objects")
                out[key] = {"summary": check_summary(rec.get("summary"), f"{f}: summary", require=("outcome", "sim_time_s")), "timing": rec["timing"]}
            except RunDirError as exc:
                raise CampaignError(f"{exc} (move it away to run that trial again)") from None
        return out

    def missing(self) -> list[tuple[Condition, int]]:
        """The (condition, seed) pairs with no record yet, in grid order."""
        done = self.records()
        return [(c, s) for c in self.spec.conditions() for s in self.spec.seeds() if (c.index, s) not in done]
