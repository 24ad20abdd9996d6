"""What ``taskflow run`` and ``taskflow batch`` import (issue 24): only what the command uses.  Each command runs in
a fresh interpreter, the console script's body, and reports ``sys.modules`` at the points that matter; the speed
itself is measured by ``benchmarks/startup.py``, not here."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.mission  # both run the default mission on PyBullet (briefly)

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT / "missions" / "car_waypoints.yaml"
HEAVY = ("scipy", "matplotlib", "cv2", "pinocchio", "ray", "stormpy", "pygls")

_PROBE = r'''
import json, sys
import taskflow.execution.executor as executor
import taskflow.campaigns.backends as backends
seen = {}
def loaded():
    return sorted({m.split(".")[0] for m in sys.modules.copy()} & set(json.loads(sys.argv[1])))  # copy: a thread may import
tick, trial = executor.Executor.tick, backends.run_trial
def first_tick(self, *a, **k):
    seen.setdefault("first_tick", loaded())
    return tick(self, *a, **k)
def first_trial(*a, **k):
    seen.setdefault("first_trial", loaded())
    return trial(*a, **k)
executor.Executor.tick, backends.run_trial = first_tick, first_trial
from taskflow.cli import main
code = main(sys.argv[2:])
seen["end"] = loaded()
seen["scipy.stats"] = "scipy.stats" in sys.modules
print(json.dumps(seen))
'''


def _probe(tmp_path: Path, *args: str) -> dict[str, object]:
    res = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(HEAVY), *args], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def test_run_of_the_default_mission_imports_none_of_the_heavy_libraries(tmp_path: Path) -> None:
    # the default mission has no camera, no arm, no campaign: no OpenCV, Pinocchio, scipy, plots, Ray, Storm or LSP;
    # the operator endpoint is on (the default), so its server's imports are counted too
    seen = _probe(tmp_path, "run", "--max-time", "0.5", "--out", str(tmp_path / "run"))
    assert seen["first_tick"] == [] and seen["end"] == []
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["ticks"] == 10


def test_batch_starts_its_first_trial_without_scipy_and_never_imports_scipy_stats(tmp_path: Path) -> None:
    # the intervals of batch.json need two special functions (scipy.special) once the trials are done; the
    # distributions of scipy.stats (seconds of imports) serve only `taskflow compare`
    seen = _probe(tmp_path, "batch", str(DEFAULT), "--trials", "2", "--workers", "1", "--max-time", "0.5",
                  "--out", str(tmp_path / "batch"))
    assert seen["first_trial"] == [] and seen["first_tick"] == []
    assert seen["end"] == ["scipy"] and seen["scipy.stats"] is False
    batch = json.loads((tmp_path / "batch" / "batch.json").read_text())
    assert len(batch["trials"]) == 2 and batch["aggregate"]["metrics"]["sim_time_s"]["ci95"] is not None
