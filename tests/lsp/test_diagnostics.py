"""Diagnostics as you type: the real load path on the unsaved text, through a real LSP client over stdio.

The broken-mission corpus (tests/broken/) is opened in the server and each file's diagnostics are compared with
what ``taskflow validate``'s load path reports for it in this process: the same problems, at the same line and
column, with the same text.  Sub-missions: a problem inside a used file shows in that file and at the ``use:``
line, the used file's unsaved buffer is what the mission sees.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from lsp_session import BROKEN, MISSIONS, change_doc, open_doc
from lsprotocol import types

from taskflow.errors import MissionError, Problem
from taskflow.mission.loader import load_mission

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

CORPUS = sorted(BROKEN.glob("*.yaml"))


def _validate(path: Path) -> list[Problem]:
    """What `taskflow validate` finds in ``path`` (the same load path, in this process)."""
    try:
        load_mission(str(path))
    except MissionError as exc:
        return exc.problems
    return []


def _text(p: Problem) -> str:
    return f"{p.message} — {p.hint}" if p.hint else p.message


def _start(d: types.Diagnostic) -> tuple[int, int]:
    return d.range.start.line + 1, d.range.start.character + 1


async def test_a_shipped_mission_has_no_diagnostics_and_a_typo_gets_one_at_its_word(client):
    path = MISSIONS / "viki_hyco.yaml"
    text = path.read_text()
    assert await open_doc(client, path) == []
    bad = text.replace("task: {name: viki_hyco", "task: {name: viki_hyko", 1)
    diags = await change_doc(client, path, bad, 2)
    assert len(diags) == 1, diags
    d = diags[0]
    at = bad.index("name: viki_hyko")  # where validate points: the key, whose value is on its line
    line, col = bad.count("\n", 0, at), at - (bad.rfind("\n", 0, at) + 1)
    assert (d.range.start.line, d.range.start.character) == (line, col)
    assert (d.range.end.line, d.range.end.character) == (line, col + len("name: viki_hyko"))  # key and value
    assert "unknown task 'viki_hyko'" in d.message and "did you mean 'viki_hyco'" in d.message
    assert d.severity == types.DiagnosticSeverity.Error and d.source == "taskflow"
    assert await change_doc(client, path, text, 3) == []  # fixed: cleared


async def test_the_broken_corpus_gets_validate_s_problems_at_validate_s_lines_and_columns(toy_client):
    assert len(CORPUS) >= 20
    compared = 0
    for path in CORPUS:
        expected = [p for p in _validate(path) if Path(p.file).resolve() == path.resolve()]
        diags = await open_doc(toy_client, path)
        got = sorted((_start(d), d.message) for d in diags)
        want = sorted(((p.line, p.col) if p.line else (1, 1), _text(p)) for p in expected)
        assert got == want, path.name
        compared += bool(want)
    assert compared >= 90  # nearly every file has a problem in itself (the rest are in the file it uses)


async def test_a_file_that_does_not_parse_gets_the_yaml_error_at_its_position(toy_client):
    for name in ("yaml_unclosed_bracket.yaml", "yaml_tab_indentation.yaml", "gap_duplicate_key_line.yaml"):
        path = BROKEN / name
        (want,) = _validate(path)
        (d,) = await open_doc(toy_client, path)
        assert _start(d) == (want.line, want.col) and ("YAML error" in d.message or "duplicate key" in d.message), name


@pytest.fixture
def missions(tmp_path: Path) -> Path:
    """A copy of the shipped missions to edit on disk."""
    shutil.copytree(MISSIONS, tmp_path / "missions")
    return tmp_path / "missions"


async def test_a_problem_in_a_used_sub_mission_shows_in_that_file_and_at_the_use_line(client, missions):
    lib = missions / "lib" / "screw_operation.yaml"
    lib.write_text(lib.read_text().replace("name: pbvs_arm,", "name: pbvs_armm,", 1))
    mission = missions / "screw_fastening.yaml"
    text = mission.read_text()
    problems = _validate(mission)
    assert problems and all(Path(p.file).resolve() == lib.resolve() for p in problems)
    diags = await open_doc(client, mission)
    use_line = next(i for i, line in enumerate(text.splitlines()) if "use: lib/screw_operation.yaml" in line)
    at_use = [d for d in diags if d.range.start.line == use_line]
    assert len(at_use) == len(diags) == len(problems)
    assert all("screw_operation.yaml:" in d.message and "unknown task 'pbvs_armm'" in d.message for d in at_use)
    inner = client.diagnostics.get(lib.resolve().as_uri())
    assert inner is not None and len(inner) == len(problems)
    assert sorted(_start(d) for d in inner) == sorted((p.line, p.col) for p in problems)
    assert "did you mean 'pbvs_arm'" in inner[0].message


async def test_the_mission_reads_the_used_file_s_unsaved_buffer(client, missions):
    lib = missions / "lib" / "screw_operation.yaml"
    mission = missions / "screw_fastening.yaml"
    assert await open_doc(client, mission) == []
    good = lib.read_text()
    assert await open_doc(client, lib) == []
    bad = good.replace("name: pbvs_arm,", "name: pbvs_armm,", 1)
    await change_doc(client, lib, bad, 2)  # unsaved: the file on disk is still good
    assert lib.read_text() == good
    mission_uri = mission.resolve().as_uri()
    await _until(lambda: any("pbvs_armm" in d.message for d in client.diagnostics.get(mission_uri, [])))
    inner = client.diagnostics[lib.resolve().as_uri()]
    assert len(inner) == 1 and "unknown task 'pbvs_armm'" in inner[0].message
    client.diagnostics.pop(mission_uri)
    await change_doc(client, lib, good, 3)
    await _until(lambda: mission_uri in client.diagnostics and not client.diagnostics[mission_uri])
    assert not client.diagnostics[lib.resolve().as_uri()]


async def test_a_burst_of_changes_ends_with_the_diagnostics_of_the_last_text(client):
    path = MISSIONS / "visual_path_oval.yaml"
    text = path.read_text()
    await open_doc(client, path)
    uri = path.resolve().as_uri()
    typed = "rate_hz: 3"
    at = text.index("rate_hz:")
    end = text.index("\n", at)
    for k in range(1, 12):  # keystrokes replacing the rate line, faster than the debounce
        partial = text[:at] + ("rate_hz: -"[:k] if k < 10 else typed) + text[end:]
        client.text_document_did_change(types.DidChangeTextDocumentParams(
            text_document=types.VersionedTextDocumentIdentifier(uri=uri, version=k + 1),
            content_changes=[types.TextDocumentContentChangeWholeDocument(text=partial)]))
    final = text[:at] + typed + text[end:]
    want = _validate_text(path, final)
    await _settled(client, uri)  # the last publish (an earlier text may have been analysed on the way)
    got = sorted((_start(d), d.message) for d in client.diagnostics[uri])
    assert got == sorted(((p.line, p.col), _text(p)) for p in want)


def _validate_text(path: Path, text: str) -> list[Problem]:
    from taskflow.mission.loader import load_mission_text

    try:
        load_mission_text(text, str(path.resolve()))
    except MissionError as exc:
        return exc.problems
    return []


async def _until(cond, timeout: float = 20.0) -> None:
    import asyncio

    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not cond():
        assert loop.time() < deadline, "timed out"
        await asyncio.sleep(0.01)


async def _settled(client, uri: str, quiet: float = 0.5) -> None:
    """Wait until ``uri``'s diagnostics have not been published again for ``quiet`` seconds."""
    import asyncio

    last = object()
    while True:
        await asyncio.sleep(quiet)
        now = client.diagnostics.get(uri)
        if now is last:
            return
        last = now
