"""Diagnostics as you type: the real load path on the unsaved text, through a real LSP client over stdio."""

from __future__ import annotations

import pytest
from conftest import MISSIONS, change_doc, open_doc

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]


async def test_a_shipped_mission_has_no_diagnostics_and_a_typo_gets_one_at_its_key(client):
    path = MISSIONS / "viki_hyco.yaml"
    text = path.read_text()
    assert await open_doc(client, path) == []
    bad = text.replace("task: {name: viki_hyco", "task: {name: viki_hyko", 1)
    diags = await change_doc(client, path, bad, 2)
    assert len(diags) == 1, diags
    d = diags[0]
    line = bad[:bad.index("viki_hyko")].count("\n")
    assert d.range.start.line == line
    assert "unknown task 'viki_hyko'" in d.message and "did you mean 'viki_hyco'" in d.message
