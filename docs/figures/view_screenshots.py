"""Regenerate the web view's screenshots in docs/figures/ (view_*.png): the three papers' missions.

ViKi-HyCo is shown live (``taskflow run --view``, paused by an operator script during the backward
positioning, so the operator buttons show); screw fastening and the visual-path oval are replays
(``taskflow view RUN_DIR``) with the timeline set to a chosen sim time.  The visual path runs in its fast
``geometric`` perception mode.  Needs the distribution's chromium and chromedriver (as the browser test).

Usage: ``python docs/figures/view_screenshots.py`` from the repository root (about a minute).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "figures"
# (file, mission, --set overrides, sim time to show, live?)
SHOTS = [
    ("view_viki_hyco.png", "missions/viki_hyco.yaml", [], 18.3, True),
    ("view_screw_fastening.png", "missions/screw_fastening.yaml", [], 16.6, False),
    ("view_visual_path_oval.png", "missions/visual_path_oval.yaml", ["world.params.perception=geometric"], 48.0, False),
]


def browser() -> Any:
    from taskflow.testing import headless_chromium

    return headless_chromium()


def until(pred: Any, timeout: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout
    while not (value := pred()):
        if time.monotonic() > deadline:
            raise TimeoutError("the page did not get there")
        time.sleep(0.1)
    return value


def run_cmd(mission: str, sets: list[str], out: Path, extra: list[str]) -> list[str]:
    cmd = [sys.executable, "-m", "taskflow.cli", "run", mission, "--seed", "0", "--out", str(out), "--quiet", *extra]
    for s in sets:
        cmd += ["--set", s]
    return cmd


def live_shot(driver: Any, mission: str, sets: list[str], t: float, png: Path, tmp: Path) -> None:
    ops = tmp / "ops.yaml"
    ops.write_text(f"- {{t: {t}, action: pause, who: screenshot}}\n")
    proc = subprocess.Popen(run_cmd(mission, sets, tmp / "live", ["--view", "--operator-script", str(ops)]),
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    url = next(line.split()[1] for line in proc.stderr if line.startswith("view: "))
    driver.get(url)
    until(lambda: driver.execute_script("return document.getElementById('live-state').dataset.mode") == "paused")
    time.sleep(1.0)  # one more poll: the rows flushed at the pause
    driver.save_screenshot(str(png))
    driver.find_element("id", "op-resume").click()
    proc.wait(120)


def replay_shot(driver: Any, mission: str, sets: list[str], t: float, png: Path, tmp: Path) -> None:
    out = tmp / Path(mission).stem
    subprocess.run(run_cmd(mission, sets, out, ["--no-control"]), cwd=ROOT, check=False, stdout=subprocess.DEVNULL)
    from taskflow.operate.view_http import serve_replay

    server = serve_replay(out, "127.0.0.1:0")
    try:
        driver.get(server.url + "/")
        until(lambda: driver.execute_script("return document.body.dataset.ready"))
        driver.execute_script("const S = taskflowView.S; taskflowView.seek(S.rows.findIndex(r => r[0] >= arguments[0]))", t)
        driver.save_screenshot(str(png))
    finally:
        server.stop()


def main() -> None:
    driver = browser()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name, mission, sets, t, live in SHOTS:
                (live_shot if live else replay_shot)(driver, mission, sets, t, OUT / name, Path(tmp))
                print(OUT / name)
    finally:
        driver.quit()


if __name__ == "__main__":
    main()
