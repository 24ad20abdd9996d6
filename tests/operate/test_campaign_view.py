"""The campaign page's server side without a browser (taskflow.operate.campaign_view, campaign_http): what
``taskflow view BATCH_DIR`` feeds the page, for real toy campaigns with properties — kept runs or not, a
sweep or not — and for hostile or malformed batch folders.

The page itself is driven in a real browser by tests/operate/test_view_browser.py.
"""

from __future__ import annotations

import json
import os
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest
from toy_campaigns import SWEEP, toy_with_properties

from taskflow.campaigns.batch import run_batch
from taskflow.cli import main
from taskflow.operate.campaign_view import open_campaign
from taskflow.operate.replay import serve_replay
from taskflow.operate.view import ViewError

pytestmark = pytest.mark.machine


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("campaigns")
    mission = str(toy_with_properties(root))
    out = {"swept_kept": root / "swept_kept", "plain": root / "plain"}
    run_batch(mission, trials=2, workers=1, out=out["swept_kept"], keep_runs=True, sweep=SWEEP)
    run_batch(mission, trials=3, workers=1, seed=5, out=out["plain"])
    return out


def _get(url: str) -> tuple[int, Any]:
    try:
        with urllib.request.urlopen(url, timeout=20) as r:
            body = r.read()
            return r.status, json.loads(body) if r.headers.get("content-type", "").startswith("application/json") else body
    except urllib.error.HTTPError as exc:
        body = exc.read()
        return exc.code, json.loads(body) if exc.headers.get("content-type", "").startswith("application/json") else body


def test_the_page_of_a_swept_campaign_with_kept_runs_is_batch_json_and_links_each_replay(campaigns):
    batch = json.loads((campaigns["swept_kept"] / "batch.json").read_text())
    server = serve_replay(campaigns["swept_kept"], "127.0.0.1:0")
    try:
        status, page = _get(server.url + "/campaign")
        assert status == 200
        # the figures are batch.json's own, not recomputed: aggregate and conditions are passed through
        assert page["aggregate"] == batch["aggregate"] and page["conditions"] == batch["conditions"]
        assert page["mission"] == "toy_full" and page["interrupted"] is False and page["kept"] == 4
        props = page["aggregate"]["properties"]
        assert list(props) == ["never_broken", "always_near", "tool_after_approach"]  # declared order
        assert (props["never_broken"]["violated"], props["never_broken"]["held"]) == (2, 2)
        assert props["never_broken"]["violation_rate"] == 0.5 and page["aggregate"]["success_rate"] == 0.5
        by_condition = {c["index"]: c["aggregate"] for c in page["conditions"]}
        assert by_condition[0]["properties"]["never_broken"]["violation_rate"] == 0.0
        assert by_condition[1]["properties"]["never_broken"]["violation_rate"] == 1.0
        assert [(t["condition"], t["seed"]) for t in page["trials"]] == [(0, 0), (0, 1), (1, 0), (1, 1)]
        for shown, recorded in zip(page["trials"], batch["trials"]):
            assert shown["outcome"] == recorded["outcome"] and shown["sim_time_s"] == recorded["sim_time_s"]
            assert shown["properties"] == {n: {"verdict": v["verdict"], "t": v["t"]}
                                           for n, v in recorded["properties"].items()}
            assert shown["replay"] == f"run/c{shown['condition']:03d}/trial-{shown['seed']:05d}/"
            # the link opens that trial's replay, served by the same server
            status, summary = _get(f"{server.url}/{shown['replay']}view/summary")
            assert status == 200 and (summary["seed"], summary["outcome"]) == (shown["seed"], shown["outcome"])
            status, state = _get(f"{server.url}/{shown['replay']}state")
            assert state["replay"] and state["t"] == shown["sim_time_s"]
        status, html = _get(server.url + "/run/c001/trial-00001/")
        assert status == 200 and b"/web/view.js" in html
        status, html = _get(server.url + "/")
        assert status == 200 and b"/web/campaign.js" in html
    finally:
        server.stop()


def test_a_campaign_without_kept_runs_has_no_replay_links(campaigns):
    batch = json.loads((campaigns["plain"] / "batch.json").read_text())
    server = serve_replay(campaigns["plain"], "127.0.0.1:0")
    try:
        status, page = _get(server.url + "/campaign")
        assert page["aggregate"] == batch["aggregate"] and page["kept"] == 0
        assert [t["seed"] for t in page["trials"]] == [5, 6, 7]
        assert all(t["replay"] is None and t["run_error"] is None for t in page["trials"])
        assert len(page["conditions"]) == 1 and page["aggregate"]["properties"]["always_near"]["violation_rate"] == 1.0
        assert _get(server.url + "/run/trial-00005/")[0] == 404
    finally:
        server.stop()


def _copy_campaign(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst, symlinks=True)
    return dst


def test_a_kept_folder_that_is_not_the_trials_run_gets_no_link_and_says_why(campaigns, tmp_path):
    d = _copy_campaign(campaigns["swept_kept"], tmp_path / "c")
    outside = tmp_path / "elsewhere"
    (d / "c000" / "trial-00000").rename(outside)
    os.symlink(outside, d / "c000" / "trial-00000")  # a link out of the batch folder
    summary = d / "c001" / "trial-00001" / "summary.json"
    summary.write_text(json.dumps(dict(json.loads(summary.read_text()), seed=9)))  # another trial's record
    trials = {(t["condition"], t["seed"]): t for t in open_campaign(d).page()["trials"]}
    assert trials[(0, 0)]["replay"] is None and "outside the record's folder" in trials[(0, 0)]["run_error"]
    assert trials[(1, 1)]["replay"] is None
    assert "seed 9, but batch.json's trial says 1" in trials[(1, 1)]["run_error"]
    assert trials[(0, 1)]["replay"] == "run/c000/trial-00001/"
    server = serve_replay(d, "127.0.0.1:0")
    try:
        assert _get(server.url + "/run/c000/trial-00000/view/summary")[0] == 404  # not served at all
    finally:
        server.stop()


def _hostile(d: Path, text: str | None = None, data: Any = None) -> Path:
    d.mkdir()
    (d / "batch.json").write_text(text if text is not None else json.dumps(data))
    return d


@pytest.mark.parametrize("name, text, expect", [
    ("not_json", '{\n  "trials": [\n  oops\n]}', "batch.json:3:3: not JSON"),
    ("list", "[1, 2]", "batch.json: a JSON object was expected, got list"),
    ("no_trials", '{"aggregate": {}}', "batch.json: trials: field required"),
    ("bad_rate", None, "aggregate.properties.p.violation_rate: input should be a valid number"),
    ("bad_verdict", None, "trials.0.properties.p.verdict: field required"),
])
def test_a_malformed_batch_json_is_one_line_naming_the_file(campaigns, tmp_path, capsys, name, text, expect):
    good = json.loads((campaigns["plain"] / "batch.json").read_text())
    if name == "bad_rate":
        good["aggregate"]["properties"]["p"] = {"pattern": "absence", "violation_rate": "50 %"}
    if name == "bad_verdict":
        good["trials"][0]["properties"]["p"] = {"pattern": "absence", "t": 1.0}
    d = _hostile(tmp_path / name, text, good)
    with pytest.raises(ViewError) as err:
        open_campaign(d)
    assert str(err.value).startswith(str(d / "batch.json")) and expect.lower() in str(err.value).lower()
    assert main(["view", str(d), "--port", "0"]) == 1
    out = capsys.readouterr().err
    assert expect.lower() in out.lower() and "Traceback" not in out and len(out.strip().splitlines()) == 1


def test_a_batch_json_that_links_out_of_its_folder_is_refused(campaigns, tmp_path, capsys):
    d = tmp_path / "linked"
    d.mkdir()
    os.symlink(campaigns["plain"] / "batch.json", d / "batch.json")  # a real batch.json, elsewhere
    assert main(["view", str(d), "--port", "0"]) == 1
    err = capsys.readouterr().err
    assert "a link to a file outside the record's folder" in err and len(err.strip().splitlines()) == 1


def test_a_folder_that_is_neither_a_run_nor_a_campaign_is_one_line(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("nothing to see")
    assert main(["view", str(tmp_path), "--port", "0"]) == 1
    err = capsys.readouterr().err
    assert "neither a run folder (it has no trace.csv) nor a batch folder (no batch.json)" in err
    assert len(err.strip().splitlines()) == 1


def test_off_loopback_the_campaign_and_its_replays_need_the_token(campaigns):
    """``--host`` another address than loopback: the campaign page draws a token, as a replay does, and every
    request for its data — the campaign's and each kept trial's — must carry it; the package's files need none."""
    server = serve_replay(campaigns["swept_kept"], "0.0.0.0:0")
    url, token = server.url.replace("0.0.0.0", "127.0.0.1"), server.token
    assert token is not None
    try:
        for path in ("/", "/campaign", "/run/c000/trial-00000/", "/run/c000/trial-00000/view/summary"):
            assert _get(url + path)[0] == 401, path
            assert _get(f"{url}{path}?token=x{token[1:]}")[0] == 403, path
        status, page = _get(f"{url}/campaign?token={token}")
        assert status == 200 and page["kept"] == 4
        status, summary = _get(f"{url}/{page['trials'][0]['replay']}view/summary?token={token}")
        assert status == 200 and summary["seed"] == 0
        assert _get(url + "/web/campaign.js")[0] == 200 and _get(url + "/web/common.js")[0] == 200
    finally:
        server.stop()
