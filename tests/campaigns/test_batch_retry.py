"""``taskflow batch`` and ``taskflow compare`` on a loop that retries (``foreach: {retry: …}``, issue 25): items
counted on their last attempt, and the attempts, the items retried and those then saved beside them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskflow.campaigns.batch import format_table, run_batch
from taskflow.cli import main

pytestmark = pytest.mark.machine

MISSION = """\
mission: r
robot: toy_point
world: {name: toy_line, params: {start: 0.0}}
rate_hz: 20
max_time: 30 s
parameters: {spots: [1.0, 3.0], tol: 2 cm}
profiles:
  gains: {soft: {kp: 1.0}}
machine:
  initial: visit
  states:
    visit:
      foreach: {in: spots, as: spot, on_failure: continue, require: all%s}
      bind: {gains: soft}
      initial: go
      transitions:
        - {to: fin, done: succeeded}
        - {to: missed, done: failed}
      states:
        go:
          task: {name: toy_goto, params: {target: $spot}}
          transitions:
            - {to: ok, when: "pos_error < $tol"}
            - {to: late, after: 2 s}
        ok: {final: succeeded}
        late: {final: failed}
    fin: {final: succeeded}
    missed: {final: failed}
"""


def test_batch_counts_items_on_their_last_attempt_and_compare_sets_the_attempts_side_by_side(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plain, retried = tmp_path / "plain.yaml", tmp_path / "retried.yaml"
    plain.write_text(MISSION % "")
    retried.write_text(MISSION % ", retry: 1")  # the 3 m spot needs three attempts of 2 s: one retry is too few
    run_batch(str(plain), trials=2, workers=1, out=tmp_path / "a")
    result = run_batch(str(retried), trials=2, workers=1, out=tmp_path / "b")
    a = json.loads((tmp_path / "a" / "batch.json").read_text())["aggregate"]["items"]["visit"]
    b = json.loads((tmp_path / "b" / "batch.json").read_text())["aggregate"]["items"]["visit"]
    assert (a["attempted"], a["succeeded"]) == (4, 0) and "attempts" not in a  # 1 m takes > 2 s from the start
    assert (b["attempted"], b["succeeded"], b["attempts"], b["retried"], b["recovered"]) == (4, 2, 8, 4, 2)
    assert "attempts of visit: 8 over 4 items; 4 retried, 2 of them then succeeded" in format_table(result)
    capsys.readouterr()
    main(["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    out = capsys.readouterr().out
    assert "items of visit: A 0/4 = 0.0 %" in out and "B 2/4 = 50.0 %" in out
    assert "attempts of visit: A 4 over 4 items (0 retried)   B 8 over 4 items (4 retried)" in out
