"""A run record is untrusted input: every reader on every hostile record of the corpus (tests/hostile_records.py).

Each reader — ``taskflow plot``, ``taskflow export``, the end-of-run report (``load_run`` +
``format_report``), ``taskflow view`` (refused at open) and the replay page's endpoints (a record that
turns hostile after the page opened, ``/view/frame`` included), ``taskflow compare``, ``taskflow plot`` of
a batch directory and ``taskflow batch --resume`` — must answer with exit 1 (or HTTP 4xx) and one line naming the damaged file, no traceback,
and never read or show what lies outside the folder (``SECRET``).
"""

from __future__ import annotations

import json
import shutil
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from hostile_records import BATCH_CASES, RUN_CASES, SECRET, base_batch, base_run, make_case

from taskflow.cli import main
from taskflow.operate.replay import serve_replay
from taskflow.operate.view import ViewError, open_run
from taskflow.readers.recorded import RunDirError, load_run
from taskflow.readers.report import format_report

ROUTES = ["/state", "/view/machine", "/view/trace?since=0", "/view/transitions?since=0", "/view/summary",
          "/view/frames?since=0", "/view/frame?sensor=image", "/view/frame?sensor=image&t=0"]
SERVED_FILES = ("trace.csv", "transitions.jsonl", "summary.json", "frames.jsonl", "000020.png")


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return base_run(tmp_path_factory.mktemp("base") / "run")


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return base_batch(tmp_path_factory.mktemp("batch") / "b")


def _no_secret_inside(d: Path) -> None:
    """No regular file of the record (links are the damage, not the readers' output) holds SECRET."""
    for f in d.rglob("*"):
        if f.is_file() and not f.is_symlink() and not any(p.is_symlink() for p in f.relative_to(d).parents if p != Path(".")):
            assert SECRET.encode() not in f.read_bytes(), f


def _one_line(text: str, names: str) -> None:
    assert text.strip() and "\n" not in text.strip(), text
    assert "Traceback" not in text and SECRET not in text and names in text, text


def test_the_base_record_is_readable_by_every_reader(base: Path, batch: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The corpus is made from records every reader accepts: each case fails by its damage alone."""
    d = make_case(base, tmp_path, "intact", lambda d: None)
    assert main(["plot", str(d)]) == 0 and main(["export", str(d)]) == 0
    assert "operator actions (3)" in format_report(load_run(d))
    view = open_run(d)
    assert len(view.reader.frames) == 2 and view.reader.frame("image", 1.0) is not None
    b = make_case(batch, tmp_path, "intact-batch", lambda d: None)
    assert main(["compare", str(b), str(batch)]) == 0
    assert main(["batch", "--resume", str(b), "--workers", "1"]) == 0
    capsys.readouterr()


PROPERTY_LINE = ('{"t": 0.5, "cause": "property", "property": "far", "pattern": "absence", "verdict": "violated", '
                 '"state": "operate.home", "atoms": {"state(operate.home)": true, "pos_error": 0.25, "data.n": null}}')


def test_a_property_record_is_read_by_every_reader(base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A ``cause: property`` line (a declared property's first violation) in the middle of the record: every reader
    takes it, and the "how it got there" chain and the page's transitions stay those of the state changes."""
    def add(d: Path) -> None:
        lines = (d / "transitions.jsonl").read_text().splitlines()
        (d / "transitions.jsonl").write_text("\n".join([lines[0], PROPERTY_LINE, *lines[1:]]) + "\n")
        summary = json.loads((d / "summary.json").read_text())
        summary["properties"] = {"far": {"pattern": "absence", "verdict": "violated", "t": 0.5}}
        (d / "summary.json").write_text(json.dumps(summary))

    d = make_case(base, tmp_path, "with-property", add)
    assert main(["plot", str(d)]) == 0 and main(["export", str(d)]) == 0
    run = load_run(d)
    assert [r.property for r in run.properties] == ["far"] and all(r.cause != "property" for r in run.transitions)
    assert "far (absence): violated at t = 0.50 s in operate.home: state(operate.home) = true, pos_error = 0.25, " \
           "data.n = none" in format_report(run)
    view = open_run(d)
    recs = view.reader.transitions(0)["records"]
    assert sum(r["cause"] == "property" for r in recs) == 1
    capsys.readouterr()


@pytest.mark.parametrize("reader", ["plot", "export", "report", "view"])
@pytest.mark.parametrize("case", sorted(RUN_CASES))
def test_every_reader_refuses_a_hostile_run_record(case: str, reader: str, base: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    damage, names = RUN_CASES[case]
    d = make_case(base, tmp_path, case, damage)
    capsys.readouterr()
    if reader == "report":
        with pytest.raises(RunDirError) as err:
            format_report(load_run(d))
        _one_line(str(err.value), names)
    else:
        if reader == "view":  # refused at open, so `taskflow view` exits instead of serving forever
            with pytest.raises(ViewError):
                open_run(d)
        assert main([reader, str(d)]) == 1
        out, err_text = capsys.readouterr()
        _one_line(err_text, names)
        assert SECRET not in out
    assert not (d / "telemetry.mcap").exists() and not list(d.glob("*.png"))
    _no_secret_inside(d)


@pytest.mark.parametrize("case", sorted(RUN_CASES))
def test_the_page_of_a_record_turned_hostile_answers_4xx_and_serves_nothing_outside(
        case: str, base: Path, tmp_path: Path) -> None:
    damage, names = RUN_CASES[case]
    d = make_case(base, tmp_path, case, lambda d: None)
    server = serve_replay(d, "127.0.0.1:0")  # opened intact, as a live run's page is; then the record turns
    try:
        damage(d)
        answers = {}
        for route in ROUTES:
            try:
                with urllib.request.urlopen(server.url + route, timeout=10) as r:
                    answers[route] = (r.status, r.read())
            except urllib.error.HTTPError as exc:
                answers[route] = (exc.code, exc.read())
    finally:
        server.stop()
    for route, (status, body) in answers.items():
        assert status < 500 and SECRET.encode() not in body, (route, status, body[:200])
        if status >= 400:
            error = json.loads(body)["error"]
            assert "\n" not in error and "Traceback" not in error, error
    refused = [json.loads(body)["error"] for status, body in answers.values() if status == 422]
    if any(f in names for f in SERVED_FILES) and "missing" not in case:
        assert refused and all(names.split(":")[0] in e for e in refused), answers  # the line: as read since
    _no_secret_inside(d)


@pytest.mark.parametrize("case", sorted(BATCH_CASES))
def test_compare_and_resume_refuse_a_hostile_batch(case: str, batch: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str],
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    import taskflow

    if hasattr(taskflow, "record_io") or Path(taskflow.__file__).with_name("record_io.py").is_file():
        from taskflow.readers import record_io

        monkeypatch.setattr(record_io, "MAX_JSON_BYTES", 1 << 20)  # "huge" without writing 256 MiB
    damage, names, readers = BATCH_CASES[case]
    d = make_case(batch, tmp_path, case, damage)
    capsys.readouterr()
    for reader in readers:
        args = {"compare": ["compare", str(d), str(batch)], "plot": ["plot", str(d)],
                "resume": ["batch", "--resume", str(d), "--workers", "1"]}[reader]
        assert main(args) == 1, reader
        out, err = capsys.readouterr()
        _one_line(err, names)
        assert SECRET not in out
    _no_secret_inside(d)
    if (d / "trials").is_dir() and not (d / "trials").is_symlink():
        assert sorted(p.name for p in (d / "trials").iterdir()) == sorted(p.name for p in (batch / "trials").iterdir())


def test_a_batch_whose_trials_are_hostile_is_refused_by_compare_when_rebuilt(batch: Path, tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """compare reads batch.json only: a hostile trial record reaches it only through a resume, which refuses it."""
    damage, names, _ = BATCH_CASES["trial-string-for-number"]
    d = make_case(batch, tmp_path, "rebuilt", damage)
    before = (d / "batch.json").read_bytes()
    assert main(["batch", "--resume", str(d), "--workers", "1"]) == 1
    _one_line(capsys.readouterr().err, names)
    assert (d / "batch.json").read_bytes() == before  # nothing rewritten from the hostile record
    shutil.rmtree(d.parent)


@pytest.mark.parametrize("name", ["../outside.txt", "ABS", "trial/../../outside.txt"])
def test_a_remote_trial_cannot_write_outside_its_run_directory(name: str, tmp_path: Path) -> None:
    from taskflow.campaigns.backends import BackendError, _write_files

    root = tmp_path / "campaign" / "trial-00000"
    name = str(tmp_path / "campaign" / "outside.txt") if name == "ABS" else name
    with pytest.raises(BackendError, match="outside its run directory"):
        _write_files(root, {"trace.csv": b"t,state,events\n", name: SECRET.encode()})
    assert not (tmp_path / "campaign" / "outside.txt").exists()
    _write_files(root, {"frames/image/000000.png": b"png"})  # inside: written
    assert (root / "frames/image/000000.png").read_bytes() == b"png"


def test_a_record_whose_mission_names_a_folder_outside_is_read_without_opening_it(base: Path, tmp_path: Path,
                                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """``quad_room``'s ``keyframe_dir`` names a folder the world reads when it runs; a reader of the record
    never opens it (the outside ``keyframes.json`` is not JSON: opening it would fail the load)."""
    import yaml

    from taskflow.mission.loader import load_mission

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "keyframes.json").write_text(SECRET + " {")
    raw = load_mission(Path(__file__).resolve().parents[2] / "missions" / "visual_path_pose_regulation.yaml").raw
    raw["world"]["params"] = {**raw["world"].get("params", {}), "keyframe_dir": str(outside)}
    def damage(d: Path) -> None:
        (d / "mission.yaml").write_text(yaml.safe_dump(raw))
        lines = (d / "transitions.jsonl").read_text().splitlines()  # this case is about the mission alone
        (d / "transitions.jsonl").write_text("".join(f"{x}\n" for x in lines if '"action"' not in x))

    d = make_case(base, tmp_path, "keyframes", damage)
    run = load_run(d)
    assert run.mission.name == raw["mission"] and run.world_params.keyframe_dir is None  # type: ignore[attr-defined]
    report = format_report(run)
    assert SECRET not in report and "keyframes.json" not in report
