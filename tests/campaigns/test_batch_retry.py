"""``taskflow batch`` and ``taskflow compare`` on a loop that retries (``foreach: {retry: …}``, issue 25): items
counted on their last attempt, and the attempts, the items retried and those then saved beside them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from taskflow.campaigns.batch import format_table, run_batch
from taskflow.cli import main

pytestmark = pytest.mark.machine

RETRY = Path(__file__).resolve().parents[1] / "machine" / "missions" / "toy_retry.yaml"
DECLARED = ", retry: {times: 3, on: [late]}"


def test_batch_counts_items_on_their_last_attempt_and_compare_sets_the_attempts_side_by_side(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plain, retried = tmp_path / "plain.yaml", tmp_path / "retried.yaml"
    text = RETRY.read_text()
    assert DECLARED in text
    plain.write_text(text.replace(DECLARED, ""))
    retried.write_text(text.replace(DECLARED, ", retry: 1"))  # the 3 m spot needs three attempts of 2 s: one is too few
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
