"""The run recorder writes each tick's values as they were at that tick, even when a task or world hands
back the same dict or array every tick and changes it in place (rows are buffered before they are written)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taskflow.execution.records import RunRecorder, read_trace


def test_values_reused_and_changed_in_place_are_recorded_per_tick(tmp_path: Path) -> None:
    rec = RunRecorder(tmp_path, ["err"], {"v": 2}, ["x"], flush_every=50)
    metrics, command, gt = {"err": 0.0}, {"v": np.zeros(2)}, {"x": 0.0}
    for k in range(3):  # one dict and one array, changed in place every tick
        metrics["err"] = float(k)
        command["v"][:] = (k, -k)
        gt["x"] = 10.0 * k
        rec.tick(0.1 * k, "s", (), metrics, command, gt)
    rec.close()
    trace = read_trace(tmp_path)
    assert trace["m.err"].tolist() == [0.0, 1.0, 2.0]
    assert trace["cmd.v.0"].tolist() == [0.0, 1.0, 2.0] and trace["cmd.v.1"].tolist() == [0.0, -1.0, -2.0]
    assert trace["gt.x"].tolist() == [0.0, 10.0, 20.0]
