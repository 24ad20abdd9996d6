"""The web view (taskflow/operate/web/, served by taskflow.operate.view_http) in a real headless browser.

Chromium and chromedriver come from the distribution's packages (Debian: ``chromium``,
``chromium-driver``; ``.ci/run`` installs them when missing); selenium drives them.  Without them the
tests skip, saying so.  The mission is the toy machine (tests/machine/missions/toy_full.yaml) on the
scripted backend, whose metric function sleeps 10 ms a tick so that a live run lasts a few seconds of
wall time: long enough to click on a page that follows it.

Live: an operator script pauses the run at three sim times; at each, the page (following the run) must
show the state and the guard's metric value of the last trace row written, and its resume button must
resume the run; then the page's pause button must stop the simulation clock.  Afterwards the shown values
are checked against ``trace.csv``.  Replay: stepping transition by transition and scrubbing the timeline
show the states and values of the record.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from taskflow.execution.summary import RunResult
from taskflow.mission.loader import load_mission
from taskflow.operate.control_http import ControlClient, ControlServer
from taskflow.operate.replay import serve_replay
from taskflow.readers.run_files import read_trace
from taskflow.testing import Script, browser_paths, drive, headless_chromium

HERE = Path(__file__).resolve().parents[1]
TOY = HERE / "machine" / "missions" / "toy_full.yaml"
DT = 1.0 / 20  # the toy mission's rate


CHROMIUM, DRIVER = browser_paths()
_MISSING = [name for name, path in (("chromium", CHROMIUM), ("chromedriver", DRIVER)) if path is None]
pytestmark = pytest.mark.skipif(bool(_MISSING), reason=(
    f"no {' and no '.join(_MISSING)} on this machine: the browser test needs the distribution's chromium and "
    "chromium-driver (apt-get install chromium chromium-driver); .ci/run installs them"))


def _metrics(slow: bool) -> Callable[[Any], dict[str, float]]:
    def metrics(s: Any) -> dict[str, float]:
        if slow:
            time.sleep(0.01)
        return {"pos_error": max(0.0, 0.3 - 0.1 * s.time_in_state), "visible": 1.0}
    return metrics


def _script(slow: bool) -> Script:
    return Script(metrics=_metrics(slow), actions={"tool": (1.0, "tool_done")})


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    driver = headless_chromium()
    yield driver
    driver.quit()


def _until(pred: Callable[[], Any], what: str, timeout: float = 15.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = pred()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


def _open(browser: Any, url: str, token: str | None = None) -> None:
    browser.get(url + "/" + (f"?token={token}" if token else ""))  # as the run prints it
    _until(lambda: browser.execute_script("return document.body.dataset.ready || document.body.dataset.error"),
           "the page to load")
    assert browser.execute_script("return document.body.dataset.error || ''") == ""


def _shown(browser: Any) -> dict[str, Any]:
    """What the page shows now: the time and state of its cursor row, and every guard value displayed."""
    return browser.execute_script("""
        const vals = {};
        document.querySelectorAll('#guards .val').forEach(v => { vals[v.dataset.metric] = v.dataset.value; });
        return {t: document.getElementById('cur-t').dataset.t, state: document.getElementById('cur-state').textContent,
                mode: document.getElementById('live-state').dataset.mode || '', values: vals};""")


def _row(trace: dict[str, Any], t: float) -> int:
    k = int(abs(trace["t"] - t).argmin())
    assert abs(trace["t"][k] - t) < 1e-9, f"no trace row at t={t}"
    return k


def _check_against_trace(trace: dict[str, Any], seen: dict[str, Any]) -> None:
    k = _row(trace, float(seen["t"]))
    assert seen["state"] == trace["state"][k]
    for metric, text in seen["values"].items():
        assert text != "" and float(text) == trace[f"m.{metric}"][k], (metric, text, trace[f"m.{metric}"][k])


def test_live_view_follows_the_record_and_its_buttons_resume_and_pause_the_run(browser, tmp_path):
    mission = load_mission(TOY)
    out = tmp_path / "live"
    pauses = [1.5, 4.5, 8.0]
    server = ControlServer("127.0.0.1:0", view=True)
    box: dict[str, RunResult | BaseException] = {}

    def run() -> None:
        try:
            box["result"] = drive(mission, _script(slow=True), max_time=120, out_dir=out, control=server,
                                  operator=[{"t": t, "action": "pause", "who": "script"} for t in pauses])
        except BaseException as exc:
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        _until(lambda: (out / "control.json").is_file(), "the control endpoint")
        client = ControlClient.for_run(out)
        _open(browser, client.url, client.token)
        seen: list[dict[str, Any]] = []
        for t_pause in pauses:
            _until(lambda t_pause=t_pause: client.state()["paused"] and client.state()["t"] == t_pause, f"the pause at {t_pause}")
            # the page follows the record: its last row is the tick before the pause
            shown = _until(lambda t_pause=t_pause: (s := _shown(browser)) and s["mode"] == "paused"
                           and abs(float(s["t"] or -1) - (t_pause - DT)) < 1e-9 and s, f"the page at {t_pause}")
            seen.append(shown)
            browser.find_element("id", "op-resume").click()
            _until(lambda: not client.state()["paused"], "the page's resume")
        # the clock runs …
        t1 = _until(lambda: (s := client.state())["t"] > pauses[-1] + 0.5 and s["t"], "the run to go on")
        _until(lambda: client.state()["t"] > t1, "the clock to advance")
        assert client.state()["running"], "the run ended before the pause button could be tried"
        # … and the page's pause button stops it
        browser.find_element("id", "op-pause").click()
        paused = _until(lambda: (s := client.state())["paused"] and s, "the page's pause")
        time.sleep(0.5)
        again = client.state()
        assert again["paused"] and again["t"] == paused["t"] and again["tick"] == paused["tick"]
        browser.find_element("id", "op-resume").click()
        thread.join(60)
        assert not thread.is_alive(), "the run did not end"
    finally:
        if thread.is_alive():
            try:
                ControlClient.for_run(out).send("preempt", who="teardown")
            except Exception:
                pass
            thread.join(10)
    assert "error" not in box, box.get("error")
    assert box["result"].outcome == "succeeded"  # type: ignore[union-attr]
    trace = read_trace(out)
    states = {s["state"] for s in seen}
    assert "operate.visit.approach" in states, seen  # a state with a guard on pos_error was among them
    assert any("pos_error" in s["values"] for s in seen)
    for s in seen:
        _check_against_trace(trace, s)
    ops = [json.loads(line) for line in (out / "transitions.jsonl").read_text().splitlines()]
    by_view = [(r["action"], r["t"]) for r in ops if r.get("cause") == "operator" and r["who"] == "view"]
    assert [a for a, _ in by_view] == ["resume", "resume", "resume", "pause", "resume"]
    assert by_view[3][1] == paused["t"]


def test_replay_steps_transition_by_transition_and_scrubs_to_the_record(browser, tmp_path):
    out = tmp_path / "replay"
    result = drive(load_mission(TOY), _script(slow=False), max_time=120, out_dir=out)
    assert result.outcome == "succeeded"
    trace = read_trace(out)
    records = [json.loads(line) for line in (out / "transitions.jsonl").read_text().splitlines()]
    last_at: dict[float, dict[str, Any]] = {}  # a final state left in the same tick (next → approach) is never shown
    for r in records:
        if r["cause"] != "start":
            last_at[r["t"]] = r
    moves = list(last_at.values())
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        first = _shown(browser)
        assert float(first["t"]) == 0.0 and first["state"] == "search"
        for rec in moves[:3]:  # three chosen times: just after each of the first three transitions
            browser.find_element("id", "next-tr").click()
            shown = _until(lambda rec=rec: (s := _shown(browser)) and float(s["t"]) > rec["t"] and s, "the step")
            assert shown["state"] == rec["to"]
            assert abs(float(shown["t"]) - (rec["t"] + DT)) < 1e-9  # the first row in the new state
            _check_against_trace(trace, shown)
        assert "pos_error" in _shown(browser)["values"] or "pos_error" in shown["values"]
        # scrub: the timeline slider to a row in the middle of an approach
        k = next(i for i, s in enumerate(trace["state"]) if s == "operate.visit.approach" and trace["t"][i] > 3.0)
        browser.execute_script("const s = document.getElementById('timeline'); s.value = arguments[0];"
                               "s.dispatchEvent(new Event('input'));", k)
        shown = _shown(browser)
        assert float(shown["t"]) == trace["t"][k] and shown["state"] == "operate.visit.approach"
        assert shown["values"]["pos_error"] != ""
        _check_against_trace(trace, shown)
        # a replay has no run to operate
        status = browser.execute_script("""
            const r = await fetch('/pause', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: '{}'});
            return r.status;""")
        assert status == 409
        assert not browser.find_element("id", "operator").is_displayed()
    finally:
        server.stop()


REGIONS = HERE / "machine" / "missions" / "toy_regions.yaml"  # two regions: drive (owns v) and watch


def test_parallel_regions_are_drawn_side_by_side_with_a_lit_leaf_each(browser, tmp_path):
    from taskflow.execution.runtime import run_mission

    out = tmp_path / "par"
    run_mission(load_mission(REGIONS), out_dir=out, max_time=3.0)
    trace = read_trace(out)
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        for k in (0, len(trace["t"]) // 2, len(trace["t"]) - 1):
            browser.execute_script("taskflowView.seek(arguments[0])", k)
            lit = browser.execute_script(
                "return [...document.querySelectorAll('#chart .st.active')].map(e => e.dataset.path).sort()")
            assert lit == sorted(trace["state"][k].split("|")) and len(lit) == 2
        boxes = browser.execute_script("""return ['work.drive', 'work.watch'].map(p => {
            const r = document.querySelector(`#chart [data-path="${p}"]`).getBoundingClientRect();
            return [r.left, r.top, r.right]; });""")
        (l1, t1, r1), (l2, t2, _) = boxes
        assert t1 == t2 and l2 >= r1  # the regions side by side, inside the parallel state's box
        assert browser.execute_script(
            "return document.querySelector('#chart [data-path=\"work\"]').classList.contains('parallel')")
    finally:
        server.stop()


def test_the_car_top_view_draws_the_control_point_where_the_figure_does(browser, tmp_path):
    """The page's top view of car_waypoints: the point drawn at every row is the figure's
    (:meth:`taskflow.readers.recorded.RecordedRun.control_track`: d = 0.325 m ahead of the rear axle while a
    ``car_goto`` state runs), and the page says which point it draws."""
    import numpy as np

    from taskflow.execution.runtime import run_mission
    from taskflow.readers.recorded import load_run

    out = tmp_path / "car"
    assert run_mission(load_mission(HERE.parent / "missions" / "car_waypoints.yaml"), out_dir=out).succeeded
    run = load_run(out)
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        drawn = np.array(browser.execute_script(
            "const v = taskflowView; return v.S.rows.map(r => v.controlAt(r));"), dtype=float)
        cx, cy = run.control_track()
        np.testing.assert_allclose(drawn[:, 0], cx)
        np.testing.assert_allclose(drawn[:, 1], cy)
        k = int(np.flatnonzero(run.trace["state"] == "drive.settle")[0])
        browser.execute_script("taskflowView.seek(arguments[0])", k)
        note = browser.find_element("id", "path-note").text
        assert "drawn now: control point d = 0.325 m ahead of the rear axle" in note and "waypoint" in note
    finally:
        server.stop()


def test_a_rendered_run_shows_the_camera_frame_nearest_the_cursor(browser, rendered_run_dir):
    """The page of a rendered run (quad_room, perception rendered): its frame element holds a decoded image,
    the one of ``frames.jsonl`` captured nearest the cursor's time, with that capture time as its caption;
    scrubbing to another time shows the frame recorded nearest it."""
    from taskflow.execution.frames import nearest, read_frames

    frames = read_frames(rendered_run_dir)
    server = serve_replay(rendered_run_dir, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        for k in (0, 40, 62):  # ticks at t = 0, 1.6 and 2.48 s (25 Hz)
            browser.execute_script("taskflowView.seek(arguments[0])", k)
            t = float(browser.find_element("id", "cur-t").get_attribute("data-t"))
            want = nearest(frames, "image", t)
            assert want is not None
            shown = _until(lambda: browser.execute_script("""
                const img = document.querySelector('img.frame[data-sensor="image"]');
                return img && img.complete && img.naturalWidth > 0 && img.src.endsWith('t=' + img.dataset.stamp)
                  ? [img.naturalWidth, img.naturalHeight, +img.dataset.stamp, img.nextSibling.textContent] : null;"""),
                f"the camera frame at t = {t}")
            assert shown[:3] == [64, 48, want.stamp]
            assert f"captured at t = {want.stamp:.3f} s" in shown[3]
    finally:
        server.stop()


def test_an_after_countdown_does_not_count_the_time_held(browser, tmp_path):
    """Held ticks do not count toward ``after`` (the engine's operating clock): held 0.9 s in ``search``
    (``after: 0.5 s``), the page shows at t = 1.2 s the 0.2 s the engine still waits, and the engine leaves
    ``search`` 0.5 s of operating time after entering it."""
    out = tmp_path / "held"
    ops = [{"t": 0.1, "action": "hold", "who": "t"}, {"t": 1.0, "action": "resume", "who": "t"}]
    result = drive(load_mission(TOY), _script(slow=False), max_time=120, out_dir=out, operator=ops)
    assert result.outcome == "succeeded"
    trace = read_trace(out)
    held = [t for t, e in zip(trace["t"], trace["events"]) if "hold" in str(e).split("|")]
    assert len(held) == 18  # ticks 0.10 .. 0.95
    left_search = next(r for r in result.executor.transitions_fired if r.source == "search")
    assert abs(left_search.t - (0.5 + len(held) * DT)) < 1e-9
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        k = _row(trace, 1.2)
        browser.execute_script("taskflowView.seek(arguments[0])", k)
        text = browser.execute_script("""return [...document.querySelectorAll('#guards tbody tr')]
            .map(r => r.textContent).find(x => x.includes('s left of')) || ''""")
        assert "0.20 s left of 0.5 s" in text and "0.90 s held" in text, text
    finally:
        server.stop()


def test_the_page_lists_each_property_with_its_verdict_at_the_cursor(browser, tmp_path):
    from taskflow.mission.loader import load_mission_text

    props = ('properties:\n  no_settle: {never: "state(operate.visit.settle)"}\n'
             '  near: {always: "pos_error < 0.5 m"}\nmachine:\n')
    mission = load_mission_text(TOY.read_text().replace("machine:\n", props, 1), str(TOY))
    out = tmp_path / "props"
    result = drive(mission, _script(slow=False), max_time=120, out_dir=out)
    assert result.summary["properties"]["no_settle"]["verdict"] == "violated"
    trace = read_trace(out)
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)

        def verdicts() -> dict[str, str]:
            return browser.execute_script("const o = {}; document.querySelectorAll('#properties li')"
                                          ".forEach(li => { o[li.dataset.property] = li.dataset.verdict; }); return o;")

        browser.execute_script("taskflowView.seek(0)")
        assert verdicts() == {"no_settle": "open", "near": "open"}
        browser.execute_script("taskflowView.seek(arguments[0])", len(trace["t"]) - 1)
        assert verdicts() == {"no_settle": "violated", "near": "held"}
    finally:
        server.stop()


def _rate_text(k: int, n: int, rate: float, ci: list[float]) -> str:
    """A rate as ``taskflow batch`` prints it (:func:`taskflow.campaigns.batch._rate`)."""
    return f"{k}/{n} = {100 * rate:.1f} % [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"


def test_the_campaign_page_shows_batch_json_rates_and_a_trial_link_opens_its_replay(browser, tmp_path):
    """``taskflow view BATCH_DIR`` of a swept toy campaign with properties and kept runs: the page shows
    the mission success rate and each property's violation rate with their Wilson intervals as batch.json
    holds them, per condition too; a trial's replay link opens the replay of that trial's run folder, which
    leads back to the campaign."""
    from toy_campaigns import SWEEP, toy_with_properties

    from taskflow.campaigns.batch import run_batch

    out = tmp_path / "campaign"
    run_batch(str(toy_with_properties(tmp_path)), trials=2, workers=1, out=out, keep_runs=True, sweep=SWEEP)
    batch = json.loads((out / "batch.json").read_text())
    agg = batch["aggregate"]
    server = serve_replay(out, "127.0.0.1:0")
    try:
        _open(browser, server.url)
        assert browser.find_element("id", "mission").text == "toy_full"
        success = browser.find_element("id", "success-rate").text
        assert success == _rate_text(agg["outcomes"]["succeeded"], agg["trials"], agg["success_rate"], agg["success_ci95"])
        assert success == "2/4 = 50.0 % [15.0, 85.0]"
        shown = browser.execute_script("""const o = {};
            document.querySelectorAll('#properties tbody tr').forEach(tr => {
              o[tr.dataset.property] = tr.querySelector('td.violation').textContent; }); return o;""")
        for name, p in agg["properties"].items():
            assert shown[name] == _rate_text(p["violated"], p["held"] + p["violated"], p["violation_rate"],
                                             p["violation_ci95"]), name
        assert shown["never_broken"] == "2/4 = 50.0 % [15.0, 85.0]"
        per_condition = browser.execute_script("""return [...document.querySelectorAll('#conditions tbody tr')].map(tr =>
            tr.querySelector('td[data-property="never_broken"]').textContent);""")
        assert per_condition == [_rate_text(c["aggregate"]["properties"]["never_broken"]["violated"], 2,
                                            c["aggregate"]["properties"]["never_broken"]["violation_rate"],
                                            c["aggregate"]["properties"]["never_broken"]["violation_ci95"])
                                 for c in batch["conditions"]]
        # the trial of condition 1, seed 0: its verdict, then its replay
        row = browser.find_element("css selector", '#trials tr[data-condition="1"][data-seed="0"]')
        assert row.find_element("css selector", 'td[data-property="never_broken"]').get_attribute("data-verdict") == "violated"
        row.find_element("css selector", "a.replay").click()
        _until(lambda: browser.execute_script("return location.pathname") == "/run/c001/trial-00000/", "the replay page")
        _until(lambda: browser.execute_script("return document.body.dataset.ready || document.body.dataset.error"),
               "the replay to load")
        assert browser.execute_script("return document.body.dataset.error || ''") == ""
        summary = json.loads((out / "c001" / "trial-00000" / "summary.json").read_text())
        assert summary["outcome"] == "failed"
        assert browser.find_element("id", "live-state").text.startswith(f"outcome: failed ({summary['reason']})")
        verdicts = browser.execute_script("taskflowView.seek(taskflowView.S.rows.length - 1); const o = {};"
                                          "document.querySelectorAll('#properties li').forEach(li => {"
                                          " o[li.dataset.property] = li.dataset.verdict; }); return o;")
        assert verdicts["never_broken"] == "violated"
        back = browser.find_element("id", "campaign-link")
        assert back.is_displayed()
        back.click()
        _until(lambda: browser.execute_script("return location.pathname === '/' && document.body.dataset.ready"),
               "the campaign page again")
    finally:
        server.stop()
