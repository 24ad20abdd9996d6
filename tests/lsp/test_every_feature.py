"""Every feature on every shipped mission of the issue (``viki_hyco.yaml``, ``screw_fastening.yaml`` with its
sub-mission, ``visual_path_oval.yaml``) and on each of them half-typed: one state that a transition enters,
found in the file, is completed as a target, hovered, gone to, found everywhere it is named, renamed (the
renamed text compiles) and misspelt (the quick fix restores the text).

Half-typed: the line after the state's key cut mid-word (the buffer does not parse; line numbers stay), so the
answers come from the last analysis that compiled, at the same positions of the current text."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from lsp_session import MISSIONS, change_doc, open_doc, pos
from lsprotocol import types
from test_actions import actions_for
from test_navigation import apply, doc, text_at

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

SCREW = MISSIONS / "screw_fastening.yaml"
SUB = MISSIONS / "lib" / "screw_operation.yaml"
CASES = {"viki_hyco": MISSIONS / "viki_hyco.yaml", "screw_fastening": SCREW, "screw_operation (sub-mission)": SUB,
         "visual_path_oval": MISSIONS / "visual_path_oval.yaml"}
_TARGET = re.compile(r"\bto: ([A-Za-z_][A-Za-z0-9_-]*)(?=[,}\s])")


def _state(text: str) -> tuple[str, int, str]:
    """A state of the file that a transition enters by its plain name and that runs a task or uses a
    sub-mission: its name, the line of its key and what its hover must show (the first such state in
    document order)."""
    for m in re.finditer(r"^( +)([A-Za-z_][A-Za-z0-9_-]*):\s*$", text, re.M):
        name = m.group(2)
        body = text[m.end():].split("\n")[1:8]
        indent = len(m.group(1))
        block = []
        for ln in body:
            if ln.strip() and len(ln) - len(ln.lstrip()) <= indent:
                break
            block.append(ln)
        if name in _TARGET.findall(text) and any("task:" in ln or "use:" in ln for ln in block):
            return name, text.count("\n", 0, m.start()), "task" if any("task:" in ln for ln in block) else "children"
    raise AssertionError("no state entered by a transition in this file")


def _half_typed(text: str, line: int) -> str:
    """``text`` with the line after ``line`` cut mid-word (it no longer parses; the line count is the same)."""
    lines = text.split("\n")
    cut = lines[line + 1]
    word = re.search(r"[A-Za-z_]{4,}", cut)
    assert word, cut
    lines[line + 1] = cut[: word.start() + 2] + " {["
    return "\n".join(lines)


async def _open(client, path: Path, text: str, half: bool) -> None:
    if path == SUB:
        await open_doc(client, SCREW)  # the sub-mission is read through the mission that uses it
    await open_doc(client, path)
    if half:
        diags = await change_doc(client, path, text, 2)
        assert diags, "the half-typed text should not load"


@pytest.mark.parametrize("half", [False, True], ids=["as shipped", "half-typed"])
@pytest.mark.parametrize("case", list(CASES))
async def test_one_state_through_every_feature(client, case, half):
    path = CASES[case]
    shipped = path.read_text()
    name, key_line, shows = _state(shipped)
    text = _half_typed(shipped, key_line) if half else shipped
    uri = path.resolve().as_uri()
    await _open(client, path, text, half)
    target_lines = [text.count("\n", 0, m.start()) for m in _TARGET.finditer(text) if m.group(1) == name]
    first = next(m for m in _TARGET.finditer(text) if m.group(1) == name)
    at_target = pos(text, first.group(0), offset=-1, nth=text[: first.start()].count(first.group(0)))

    # completion: the state is a target the transition may name
    got = await client.text_document_completion_async(types.CompletionParams(text_document=doc(path),
                                                                             position=at_target))
    assert got is not None and name in [i.label for i in got.items], case

    # hover on the state's key: the state, with its effective task (or its children, a sub-mission's states)
    key_at = types.Position(line=key_line, character=shipped.split("\n")[key_line].index(name) + 1)
    hov = await client.text_document_hover_async(types.HoverParams(text_document=doc(path), position=key_at))
    assert hov is not None and name in hov.contents.value and shows in hov.contents.value

    # definition from the target: the state's key
    [loc] = await client.text_document_definition_async(types.DefinitionParams(text_document=doc(path),
                                                                                position=at_target))
    assert loc.uri == uri and loc.range.start.line == key_line and text_at(path, loc.range) == name

    # references: every transition that names it, in this file
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc(path), position=key_at, context=types.ReferenceContext(include_declaration=True)))
    here = sorted({r.range.start.line for r in refs if r.uri == uri})
    assert set(target_lines) | {key_line} <= set(here), (here, target_lines)

    # rename: the key and every target; the renamed text compiles (the shipped text: positions are the same)
    edit = await client.text_document_rename_async(types.RenameParams(text_document=doc(path), position=key_at,
                                                                      new_name="renamed_state"))
    assert edit is not None and uri in edit.changes
    renamed = apply(shipped, edit.changes[uri])
    assert not [m for m in _TARGET.finditer(renamed) if m.group(1) == name]
    assert sum(1 for m in _TARGET.finditer(renamed) if m.group(1) == "renamed_state") == len(target_lines)
    assert await change_doc(client, path, renamed, 3) == []
    if path == SUB:
        assert await change_doc(client, SCREW, SCREW.read_text(), 2) == []  # the mission using it compiles

    # code action: a misspelt target gets "did you mean" and the fix restores the text
    typo = shipped[: first.end() - 1] + shipped[first.end():]  # the name's last letter dropped
    diags = await change_doc(client, path, typo, 4)
    [diag] = [d for d in diags if "did you mean" in d.message and d.range.start.line == target_lines[0]]
    actions = await actions_for(client, path, diag)
    assert any(apply(typo, a.edit.changes[uri]) == shipped for a in actions), [a.title for a in actions]
