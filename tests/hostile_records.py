"""A corpus of hostile run and batch directories, each made from a real small record.

:func:`base_run` runs the toy mission (tests/toys.py) with an operator script, so its record holds state
changes and operator actions, and adds camera frames written by the real :class:`taskflow.execution.frames.
FrameRecorder`; :func:`base_batch` runs a two-trial campaign.  Each case of :data:`RUN_CASES` /
:data:`BATCH_CASES` copies one and damages it in one way: traversal and links out of the folder, huge
lines and files, malformed JSON, wrong types, a missing file.  Next to every copy lies ``secret.txt``
(and valid-looking records holding :data:`SECRET`), what a hostile record would make a reader serve or
read; a reader that stays inside the folder never shows :data:`SECRET`.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from taskflow.execution.frames import FrameRecorder
from taskflow.messages import Image

SECRET = "S3CRET-of-the-machine-7f1c"
MISSIONS = Path(__file__).resolve().parent / "machine" / "missions"
TOY = MISSIONS / "toy_full.yaml"
SCRIPT = [{"t": 1.0, "action": "pause", "who": "script"}, {"t": 1.0, "action": "resume", "who": "ann"},
          {"t": 2.0, "action": "preempt", "who": "bob", "args": {"to": "operate.home"}}]
HUGE = 2 << 20  # bytes: past record_io.MAX_LINE_BYTES


def base_run(out: Path) -> Path:
    """A real toy run with operator actions, plus two camera frames of sensor ``image``."""
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    run_mission(load_mission(TOY), out_dir=out, max_time=60, operator=SCRIPT)
    frames = FrameRecorder(out, hz=1.0)
    rng = np.random.default_rng(0)
    for tick, t in ((0, 0.0), (20, 1.0)):
        frames.offer(t, tick, {"image": Image(stamp=t, frame="camera", pixels=rng.integers(0, 255, (8, 12, 3),
                                                                                             dtype=np.uint8))})
    frames.close()
    return out


def base_batch(out: Path) -> Path:
    """A real two-trial campaign of the toy mission (``campaign.json``, ``trials/``, ``batch.json``)."""
    from taskflow.campaigns.batch import run_batch

    run_batch(str(TOY), trials=2, workers=1, out=out)
    return out


def _secret_copy(src: Path, dst: Path, replace: tuple[str, str]) -> Path:
    """``src`` copied to ``dst`` (outside the record) with ``SECRET`` written into it."""
    dst.write_text(src.read_text().replace(*replace))
    return dst


def _link_out(name: str, replace: tuple[str, str]) -> Callable[[Path], None]:
    """``name`` replaced by a link to a valid-looking copy of it outside the folder that holds SECRET."""
    def damage(d: Path) -> None:
        target = _secret_copy(d / name, d.parent / f"outside-{Path(name).name}", replace)
        (d / name).unlink()
        (d / name).symlink_to(target)
    return damage


def _append(name: str, line: str) -> Callable[[Path], None]:
    def damage(d: Path) -> None:
        with open(d / name, "a") as f:
            f.write(line + "\n")
    return damage


def _edit_json(name: str, edit: Callable[[dict], object]) -> Callable[[Path], None]:
    def damage(d: Path) -> None:
        data = json.loads((d / name).read_text())
        new = edit(data)
        (d / name).write_text(json.dumps(data if new is None else new))
    return damage


def _frame_line(file: str, **fields: object) -> str:
    rec = {"t": 1.5, "tick": 30, "sensor": "image", "stamp": 1.5, "frame": "camera", "width": 12, "height": 8,
           "file": file}
    rec.update(fields)
    return json.dumps(rec)


def _frame_link(d: Path) -> None:
    target = d.parent / "outside.png"
    target.write_bytes((d / "frames/image/000020.png").read_bytes() + SECRET.encode())
    (d / "frames/image/000020.png").unlink()
    (d / "frames/image/000020.png").symlink_to(target)


def _use_outside(d: Path) -> None:
    (d.parent / "outside-sub.yaml").write_text(f"submission: s\ndescription: {SECRET}\nmachine: {{}}\n")
    text = (d / "mission.yaml").read_text()
    (d / "mission.yaml").write_text(text.replace("    search:\n", "    search:\n      use: ../outside-sub.yaml\n", 1))


def _set(key: str, value: object) -> Callable[[dict], None]:
    def edit(data: dict) -> None:
        data[key] = value
    return edit


def _set_first_trial(key: str, value: object) -> Callable[[dict], None]:
    def edit(data: dict) -> None:
        data["trials"][0][key] = value
    return edit


RUN_CASES: dict[str, tuple[Callable[[Path], None], str]] = {
    # name: (damage, the file the error must name)
    "frames-traversal": (_append("frames.jsonl", _frame_line("../../../../../../../../etc/passwd")), "frames.jsonl:3"),
    "frames-next-door": (_append("frames.jsonl", _frame_line("../secret.txt")), "frames.jsonl:3"),
    "frames-absolute": (lambda d: _append("frames.jsonl", _frame_line(str(d.parent / "secret.txt")))(d), "frames.jsonl:3"),
    "frame-file-links-out": (_frame_link, "000020.png"),
    "trace-links-out": (_link_out("trace.csv", ("operate.home", SECRET)), "trace.csv"),
    "summary-links-out": (_link_out("summary.json", ("reached final state", SECRET)), "summary.json"),
    "transitions-link-out": (_link_out("transitions.jsonl", ("operate.home", SECRET)), "transitions.jsonl"),
    "frames-index-links-out": (_link_out("frames.jsonl", ("camera", SECRET)), "frames.jsonl"),
    "mission-links-out": (_link_out("mission.yaml", ("toy_full", "toy_full  # " + SECRET)), "mission.yaml"),
    "mission-uses-a-file-outside": (_use_outside, "mission.yaml"),
    "transitions-huge-line": (_append("transitions.jsonl", '{"t": 1, "label": "' + "x" * HUGE + '"}'),
                              "transitions.jsonl:"),
    "trace-huge-line": (_append("trace.csv", "9.0,s,," + "1" * HUGE), "trace.csv:"),
    "frames-huge-line": (_append("frames.jsonl", "[" + " " * HUGE + "]"), "frames.jsonl:3"),
    "transitions-malformed-json": (_append("transitions.jsonl", '{"t": 1.0, "from": '), "transitions.jsonl:"),
    "summary-malformed-json": (lambda d: (d / "summary.json").write_text('{"outcome": "succeeded",'), "summary.json"),
    "frames-malformed-json": (_append("frames.jsonl", "{nope"), "frames.jsonl:3"),
    "transitions-string-for-number": (_append("transitions.jsonl", '{"t": "soon", "from": "a", "to": "b", "cause": "guard"}'),
                                      "transitions.jsonl:"),
    "transitions-list-for-dict": (_append("transitions.jsonl", '{"t": 9.0, "from": "a", "to": "b", "cause": "guard", '
                                                              '"metrics": [1, 2]}'), "transitions.jsonl:"),
    "transitions-list-for-record": (_append("transitions.jsonl", "[1, 2, 3]"), "transitions.jsonl:"),
    "transitions-unknown-cause": (_append("transitions.jsonl", '{"t": 9.0, "from": "a", "to": "b", "cause": "magic"}'),
                                  "transitions.jsonl:"),
    "operator-args-not-strings": (_append("transitions.jsonl", '{"t": 9.0, "tick": 1, "cause": "operator", "action": '
                                                              '"preempt", "who": "x", "state": "s", "args": {"to": [1]}}'),
                                  "transitions.jsonl:"),
    "property-atoms-a-list": (_append("transitions.jsonl", '{"t": 9.0, "cause": "property", "property": "p", '
                                                          '"atoms": [1, 2]}'), "transitions.jsonl:"),
    "property-atom-an-object": (_append("transitions.jsonl", '{"t": 9.0, "cause": "property", "property": "p", '
                                                            '"atoms": {"x": {"y": 1}}}'), "transitions.jsonl:"),
    "property-without-name": (_append("transitions.jsonl", '{"t": 9.0, "cause": "property", "atoms": {}}'),
                              "transitions.jsonl:"),
    "summary-string-for-number": (_edit_json("summary.json", _set("sim_time_s", "long")), "summary.json"),
    "summary-list-for-dict": (_edit_json("summary.json", _set("metrics", [1, 2])), "summary.json"),
    "summary-a-list": (_edit_json("summary.json", lambda data: [data]), "summary.json"),
    "summary-seed-text": (_edit_json("summary.json", _set("seed", "zero")), "summary.json"),
    "frames-string-for-number": (_append("frames.jsonl", _frame_line("frames/image/000020.png", width="12")),
                                 "frames.jsonl:3"),
    "frames-not-a-png": (_append("frames.jsonl", _frame_line("summary.json")), "frames.jsonl:3"),
    "trace-text-for-number": (_append("trace.csv", "9.0,s,,lots"), "trace.csv:"),
    "trace-too-many-cells": (_append("trace.csv", "9.0,s,," + ",1" * 400), "trace.csv:"),
    "trace-bad-header": (lambda d: (d / "trace.csv").write_text("a,b\n1,2\n"), "trace.csv:1"),
    "summary-missing": (lambda d: (d / "summary.json").unlink(), "summary.json"),
    "transitions-missing": (lambda d: (d / "transitions.jsonl").unlink(), "transitions.jsonl"),
    "mission-missing": (lambda d: (d / "mission.yaml").unlink(), "mission.yaml"),
}

BATCH_CASES: dict[str, tuple[Callable[[Path], None], str, tuple[str, ...]]] = {
    # name: (damage, the file the error must name, the readers it is for: compare, resume, plot (a batch
    # directory's figures); a link out is not a batch directory to plot: its batch.json is not a file there)
    "batch-links-out": (_link_out("batch.json", ('"mission"', f'"note": "{SECRET}", "mission"')), "batch.json",
                        ("compare",)),
    "batch-malformed-json": (lambda d: (d / "batch.json").write_text('{"trials": ['), "batch.json", ("compare", "plot")),
    "batch-trials-a-dict": (_edit_json("batch.json", _set("trials", {"a": 1})), "batch.json", ("compare", "plot")),
    "batch-string-for-number": (_edit_json("batch.json", _set_first_trial("sim_time_s", "long")), "batch.json",
                                ("compare", "plot")),
    "batch-list-for-dict": (_edit_json("batch.json", _set_first_trial("metrics", [1, 2])), "batch.json", ("compare", "plot")),
    "batch-huge": (lambda d: (d / "batch.json").write_text('{"trials": [], "pad": "' + "x" * HUGE + '"}'),
                   "batch.json", ("compare", "plot")),
    "trial-links-out": (_link_out("trials/c000-s00000.json", ('"outcome"', f'"note": "{SECRET}", "outcome"')),
                        "c000-s00000.json", ("resume",)),
    "trials-folder-links-out": (lambda d: _move_trials_out(d), "c000-s00000.json", ("resume",)),
    "trial-string-for-number": (_edit_json("trials/c000-s00001.json",
                                           lambda r: r["summary"].__setitem__("sim_time_s", "long")),
                                "c000-s00001.json", ("resume",)),
    "trial-summary-a-list": (_edit_json("trials/c000-s00001.json", _set("summary", [1, 2])), "c000-s00001.json",
                             ("resume",)),
    "trial-huge": (lambda d: (d / "trials/c000-s00001.json").write_text('{"pad": "' + "x" * HUGE + '"}'),
                   "c000-s00001.json", ("resume",)),
    "campaign-links-out": (_link_out("campaign.json", ('"mission"', f'"note": "{SECRET}", "mission"')),
                           "campaign.json", ("resume",)),
    "campaign-string-for-number": (_edit_json("campaign.json", _set("trials", "two")), "campaign.json", ("resume",)),
}


def _move_trials_out(d: Path) -> None:
    outside = d.parent / "outside-trials"
    shutil.move(str(d / "trials"), outside)
    (d / "trials").symlink_to(outside)


def make_case(base: Path, root: Path, name: str, damage: Callable[[Path], None]) -> Path:
    """``base`` copied to ``root/NAME/run`` (``secret.txt`` beside it), then damaged; returns the copy."""
    case = root / name
    case.mkdir(parents=True)
    (case / "secret.txt").write_text(SECRET + "\n")
    d = case / "run"
    shutil.copytree(base, d, symlinks=True)
    damage(d)
    return d
