"""Code actions through a real LSP client over stdio: each quick fix applied to the text, and the fixed text
then loads without the problem it fixed."""

from __future__ import annotations

import pytest
from lsp_session import BROKEN, MISSIONS, change_doc, open_doc
from lsprotocol import types
from test_navigation import apply, doc

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]


async def actions_for(client, path, diag: types.Diagnostic) -> list[types.CodeAction]:
    got = await client.text_document_code_action_async(types.CodeActionParams(
        text_document=doc(path), range=diag.range, context=types.CodeActionContext(diagnostics=[diag])))
    return [a for a in got or [] if isinstance(a, types.CodeAction)]


async def fix_and_reload(client, path, needle: str) -> tuple[str, str, list[types.Diagnostic]]:
    """Open ``path``, apply the one quick fix of its diagnostic whose message holds ``needle``; the action's
    title, the fixed text and the diagnostics of the fixed text."""
    text = path.read_text()
    diags = await open_doc(client, path)
    [diag] = [d for d in diags if needle in d.message]
    [action] = await actions_for(client, path, diag)
    fixed = apply(text, action.edit.changes[path.resolve().as_uri()])
    return action.title, fixed, await change_doc(client, path, fixed, 2)


@pytest.mark.parametrize("name, wrong, right", [
    ("guard_unknown_metric", "position_error", "pos_error"),
    ("initial_not_substate", "aproach", "approach"),
])
async def test_did_you_mean_is_applied(toy_client, name, wrong, right):
    path = BROKEN / f"{name}.yaml"
    title, fixed, diags = await fix_and_reload(toy_client, path, "did you mean")
    assert right in title and wrong not in fixed.split("\n", 2)[2]  # the header comment names the typo
    assert diags == []


async def test_did_you_mean_on_a_shipped_mission(client):
    path = MISSIONS / "viki_hyco.yaml"
    text = path.read_text()
    await open_doc(client, path)
    bad = text.replace("task: {name: viki_rotate", "task: {name: viki_rotat", 1)
    [diag] = await change_doc(client, path, bad, 2)
    [action] = await actions_for(client, path, diag)
    assert apply(bad, action.edit.changes[path.resolve().as_uri()]) == text


@pytest.mark.parametrize("name, target", [
    ("no_way_out", "error"),  # a flow-style state: the transition goes in its braces
    ("gap_stuck_behind_done", "arrived"),  # no failed final near: the nearest final state
])
async def test_a_timeout_is_added_to_a_state_with_no_way_out(toy_client, name, target):
    path = BROKEN / f"{name}.yaml"
    title, fixed, diags = await fix_and_reload(toy_client, path, "has no way out")
    assert f"'{target}'" in title
    assert f"transitions: [{{to: {target}, after: 10 s}}]" in fixed
    assert diags == []


async def test_a_timeout_is_added_to_a_block_state_correctly_indented(toy_client):
    path = BROKEN / "no_way_out.yaml"
    block = path.read_text().replace("    idle: {description: waits forever}   # <-- here",
                                     "    idle:\n      description: waits forever  # a comment\n")
    await open_doc(toy_client, path)
    diags = await change_doc(toy_client, path, block, 2)
    [diag] = [d for d in diags if "has no way out" in d.message]
    [action] = await actions_for(toy_client, path, diag)
    fixed = apply(block, action.edit.changes[path.resolve().as_uri()])
    assert ("    idle:\n      description: waits forever  # a comment\n"
            "      transitions:\n        - {to: error, after: 10 s}\n") in fixed
    assert await change_doc(toy_client, path, fixed, 3) == []


async def test_a_bare_guard_number_gets_the_metric_unit(toy_client):
    path = BROKEN / "guard_number_without_unit.yaml"
    title, fixed, diags = await fix_and_reload(toy_client, path, "needs a unit")
    assert 'when: "pos_error < 3 m"' in fixed and "3 m" in title
    assert diags == []


async def test_no_action_where_nothing_is_wrong(client):
    path = MISSIONS / "screw_fastening.yaml"
    assert await open_doc(client, path) == []
    got = await client.text_document_code_action_async(types.CodeActionParams(
        text_document=doc(path), range=types.Range(start=types.Position(line=0, character=0),
                                                   end=types.Position(line=200, character=0)),
        context=types.CodeActionContext(diagnostics=[])))
    assert not got
