"""Navigation through a real LSP client over stdio: go to definition, references, the outline and renaming a
state, on the shipped missions (screw_fastening with its sub-mission) and on half-typed text."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from lsp_session import BROKEN, MISSIONS, change_doc, open_doc, pos
from lsprotocol import types

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

SCREW = MISSIONS / "screw_fastening.yaml"
LIB = MISSIONS / "lib" / "screw_operation.yaml"


def doc(path: Path) -> types.TextDocumentIdentifier:
    return types.TextDocumentIdentifier(uri=path.resolve().as_uri())


def line_of(text: str, needle: str, nth: int = 0) -> int:
    return pos(text, needle, nth=nth).line


def state_key(text: str, name: str, indent: int = 4) -> types.Position:
    """A position inside the key of state ``name`` (at ``indent``) under ``machine:``."""
    at = text.index(f"\n{' ' * indent}{name}:", text.index("\nmachine:")) + indent + 2
    line = text.count("\n", 0, at)
    return types.Position(line=line, character=at - (text.rfind("\n", 0, at) + 1))


def text_at(path: Path, rng: types.Range) -> str:
    lines = path.read_text().split("\n")
    assert rng.start.line == rng.end.line
    return lines[rng.start.line][rng.start.character:rng.end.character]


async def definition(client, path: Path, at: types.Position) -> list[types.Location]:
    got = await client.text_document_definition_async(types.DefinitionParams(text_document=doc(path), position=at))
    return list(got or [])


def apply(text: str, edits: list[types.TextEdit]) -> str:
    """``text`` with ``edits`` applied (ASCII text: code points are UTF-16 units)."""
    lines = text.split("\n")
    offsets = [0]
    for ln in lines:
        offsets.append(offsets[-1] + len(ln) + 1)
    out = text
    for e in sorted(edits, key=lambda e: (e.range.start.line, e.range.start.character), reverse=True):
        a = offsets[e.range.start.line] + e.range.start.character
        b = offsets[e.range.end.line] + e.range.end.character
        out = out[:a] + e.new_text + out[b:]
    return out


async def test_a_transition_target_goes_to_the_state_it_enters(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    # `searching` → `error_stop` is an ancestor's sibling, not a sibling
    at = pos(text, "- {to: error_stop, after: 3 s}", offset=-18)
    [loc] = await definition(client, SCREW, at)
    assert loc.uri == SCREW.resolve().as_uri()
    assert loc.range.start.line == line_of(text, "\n    error_stop:")
    assert text_at(SCREW, loc.range) == "error_stop"
    [loc] = await definition(client, SCREW, pos(text, "initial: initial_search", offset=-3))
    assert loc.range.start.line == line_of(text, "            initial_search:")


async def test_a_dotted_path_in_a_property_state_and_initial_of_the_root(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    [loc] = await definition(client, SCREW, pos(text, "  initial: cell", offset=-1))
    assert loc.range.start.line == line_of(text, "\n    cell:")
    # a property's state(NAME) of a state spliced from the sub-mission: its key there
    [loc] = await definition(client, SCREW, pos(text, 'only_after: "state(s1_pl'))
    lib = LIB.read_text()
    assert loc.uri == LIB.resolve().as_uri() and loc.range.start.line == line_of(lib, "    s1_platform_approach:")


async def test_a_bound_profile_defined_in_the_sub_mission(client):
    text, lib = SCREW.read_text(), LIB.read_text()
    await open_doc(client, SCREW)
    await open_doc(client, LIB)
    # in the sub-mission, through the open mission that uses it
    [loc] = await definition(client, LIB, pos(lib, "bind: {platform: platform_boost", offset=-3))
    assert loc.uri == LIB.resolve().as_uri()
    assert loc.range.start.line == line_of(lib, "    platform_boost:")
    # in the mission: `prediction: feedforward` is the mission's own profile
    [loc] = await definition(client, SCREW, pos(text, "bind: {prediction: feedforward", offset=-2))
    assert loc.range.start.line == line_of(text, "    feedforward:")


async def test_use_goes_to_the_file_and_its_states_are_reached_from_the_mission(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    [loc] = await definition(client, SCREW, pos(text, "use: lib/screw_", offset=-2))
    assert loc.uri == LIB.resolve().as_uri()
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc(SCREW), position=pos(text, "    error_stop:", offset=-3),
        context=types.ReferenceContext(include_declaration=False)))
    where = {(r.uri, r.range.start.line) for r in refs}
    lib = LIB.read_text()
    # the sub-mission's `screws` state names the mission's error_stop (one of its exits)
    assert (LIB.resolve().as_uri(), line_of(lib, "- {to: error_stop, done: failed}")) in where
    assert (SCREW.resolve().as_uri(), line_of(text, "- {to: error_stop, after: 10 s}")) in where
    assert len(refs) == text.count("to: error_stop") + lib.count("to: error_stop")
    assert all(text_at(Path(r.uri[len("file://"):]), r.range) == "error_stop" for r in refs)


async def test_parameters_go_to_their_declaration_and_the_with_that_binds_them(client):
    text, lib = SCREW.read_text(), LIB.read_text()
    await open_doc(client, SCREW)
    await open_doc(client, LIB)
    [loc] = await definition(client, SCREW, pos(text, '"tool_force > $max_tool', offset=-2))
    assert loc.range.start.line == line_of(text, "  max_tool_force: 40 N")
    locs = await definition(client, LIB, pos(lib, "< $eps_t_pl"))
    lines = {(loc.uri, loc.range.start.line) for loc in locs}
    assert (LIB.resolve().as_uri(), line_of(lib, "  eps_t_platform: ~")) in lines
    assert (SCREW.resolve().as_uri(), line_of(text, "eps_t_platform: $eps_t_platform")) in lines
    # a foreach item: the `as:` that names it
    [loc] = await definition(client, LIB, pos(lib, "target: $screw,", offset=-3))
    assert loc.range.start.line == line_of(lib, "foreach: {in: screws, as: screw")


async def test_a_task_goes_to_its_python_class(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    [loc] = await definition(client, SCREW, pos(text, "task: contact_monitor", offset=-3))
    source = Path(loc.uri[len("file://"):]).read_text().split("\n")
    assert source[loc.range.start.line].startswith("class ")
    assert 'register_task("contact_monitor")' in source[loc.range.start.line - 1]


async def test_profile_references_are_every_bind_using_it(client):
    lib = LIB.read_text()
    await open_doc(client, SCREW)
    await open_doc(client, LIB)
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc(LIB), position=pos(lib, "arm: arm_zero", offset=-2),
        context=types.ReferenceContext(include_declaration=True)))
    lines = sorted(r.range.start.line for r in refs)
    assert lines == sorted([line_of(lib, "    arm_zero:")] + [i for i, ln in enumerate(lib.split("\n"))
                                                                 if "arm: arm_zero" in ln])


async def test_the_outline_is_the_state_tree_with_the_sub_mission_under_the_using_state(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(text_document=doc(SCREW)))
    assert [s.name for s in syms] == ["cell", "error_stop", "error", "success"]
    cell = syms[0]
    assert cell.kind == types.SymbolKind.Struct and [r.name for r in cell.children] == ["operation", "safety"]
    assert all(r.kind == types.SymbolKind.Namespace for r in cell.children)
    operate = next(s for s in cell.children[0].children if s.name == "operate")
    names = [s.name for s in operate.children]
    assert names[:2] == ["s1_platform_approach", "screws"] and "s8_final_platform_retract" in names
    screws = operate.children[1]
    assert "screw_failed" in [s.name for s in screws.children]
    assert screws.range == operate.range  # ranges in this file: the using state's
    assert syms[2].kind == types.SymbolKind.Event and syms[1].kind == types.SymbolKind.Function
    assert syms[1].selection_range.start.line == line_of(text, "\n    error_stop:")


async def test_rename_a_state_updates_targets_initial_and_dotted_paths(client):
    path = MISSIONS / "viki_hyco.yaml"
    text = path.read_text()
    await open_doc(client, path)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(text_document=doc(path)))
    # a state with a sibling named by a transition: rename it and check the renamed mission still compiles
    name = next(s.name for s in syms if re.search(rf"to: {s.name}\b", text) and s.kind != types.SymbolKind.Event)
    at = state_key(text, name)
    rng = await client.text_document_prepare_rename_async(types.PrepareRenameParams(text_document=doc(path),
                                                                                      position=at))
    assert rng is not None and text_at(path, rng) == name
    edit = await client.text_document_rename_async(types.RenameParams(text_document=doc(path), position=at,
                                                                      new_name="renamed_state"))
    new = apply(text, edit.changes[path.resolve().as_uri()])
    assert name not in [ln.strip().rstrip(":") for ln in new.split("\n")]
    assert not re.search(rf"to: {name}\b", new) and "to: renamed_state" in new
    assert await change_doc(client, path, new, 2) == []
    # a clash with a sibling and an invalid name are refused
    other = next(s.name for s in syms if s.name != name)
    at = state_key(new, "renamed_state")
    for bad in (other, "a.b", "with space"):
        assert await client.text_document_rename_async(types.RenameParams(text_document=doc(path), position=at,
                                                                          new_name=bad)) is None


async def test_rename_a_sub_mission_state_and_a_property_state_path(client):
    text, lib = SCREW.read_text(), LIB.read_text()
    await open_doc(client, SCREW)
    await open_doc(client, LIB)
    at = pos(text, "then: \"not state(cell.operation.op")  # a property's state(PATH) names states too
    rng = await client.text_document_prepare_rename_async(types.PrepareRenameParams(
        text_document=doc(SCREW), position=at))
    assert rng is not None and text_at(SCREW, rng) == "operate"
    [loc] = await definition(client, SCREW, at)
    assert loc.range.start.line == line_of(text, "            operate:")
    at = pos(lib, "to: s7_final_arm_retract", offset=-3)
    edit = await client.text_document_rename_async(types.RenameParams(text_document=doc(LIB), position=at,
                                                                      new_name="s7_retract"))
    assert list(edit.changes) == [LIB.resolve().as_uri()]  # defined in the sub-mission: edits there only
    new = apply(lib, edit.changes[LIB.resolve().as_uri()])
    assert "s7_final_arm_retract" not in new and new.count("s7_retract") == lib.count("s7_final_arm_retract")
    await change_doc(client, LIB, new, 2)
    assert await change_doc(client, SCREW, text, 2) == []  # the mission using it still compiles


async def test_a_dotted_target_names_each_of_its_states(client):
    path = MISSIONS / "visual_path_oval.yaml"
    text = path.read_text()
    await open_doc(client, path)
    new = text.replace("- {to: lost, on: features_lost}", "- {to: follow.lost, on: features_lost}", 1)
    assert new != text and await change_doc(client, path, new, 2) == []
    line = line_of(new, "to: follow.lost")
    [a] = await definition(client, path, pos(new, "to: fol"))
    [b] = await definition(client, path, pos(new, "to: follow.lo"))
    assert a.range.start.line == line_of(new, "\n    follow:") and text_at(path, a.range) == "follow"
    assert b.range.start.line == line_of(new, "\n        lost:") and text_at(path, b.range) == "lost"
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc(path), position=pos(new, "\n    follow:", offset=-2),
        context=types.ReferenceContext(include_declaration=False)))
    assert [(r.range.start.line, r.range.start.character) for r in refs] == \
        [(line, new.split("\n")[line].index("follow.lost")), (line_of(new, "initial: follow"), 11)]


async def test_navigation_on_half_typed_text(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    cut = text.index("task: {name: arm_home") + len("task: {name: arm_h")
    half = text[:cut] + "\n" + text[cut:].split("\n", 1)[1]  # a line cut mid-word: does not parse
    assert await change_doc(client, SCREW, half, 2)
    [loc] = await definition(client, SCREW, pos(half, "- {to: error_stop, after: 3 s}", offset=-18))
    assert loc.range.start.line == line_of(half, "\n    error_stop:")
    [loc] = await definition(client, SCREW, pos(half, '"tool_force > $max_tool', offset=-2))
    assert loc.range.start.line == line_of(half, "  max_tool_force: 40 N")
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(text_document=doc(SCREW)))
    assert [s.name for s in syms] == ["cell", "error_stop", "error", "success"]
    # nonsense answers nothing, never an error
    await change_doc(client, SCREW, "machine: [: {", 3)
    assert await definition(client, SCREW, types.Position(line=0, character=3)) == []
    assert await client.text_document_rename_async(types.RenameParams(
        text_document=doc(SCREW), position=types.Position(line=0, character=3), new_name="x")) is None


async def test_a_data_key_goes_to_the_task_class_that_declares_it(toy_client):
    path = BROKEN / "guard_number_without_unit.yaml"
    head = path.read_text().split("machine:")[0]
    text = head + """machine:
  initial: mark
  states:
    mark:
      task: toy_mark
      transitions: [{to: away, when: "data.toy.mark > 20 cm"}]
    away:
      task: {name: toy_goto, params: {target: $data.toy.mark}}
      bind: {gains: slow}
      transitions: [{to: done, when: "pos_error < 1 cm"}]
    done: {final: succeeded}
"""
    assert await open_doc(toy_client, path, text) == []
    for at in (pos(text, '"data.toy.ma'), pos(text, "$data.to")):
        [loc] = await definition(toy_client, path, at)
        source = Path(loc.uri[len("file://"):])
        assert source.name == "toys.py"
        line = source.read_text().split("\n")[loc.range.start.line]
        assert line.startswith("class ToyMark")


async def test_use_of_a_shipped_name_goes_to_the_shipped_file(client, tmp_path):
    """A copy of a shipped mission outside the package names its sub-mission ``taskflow:lib/…``: no diagnostic,
    and go to definition opens the shipped file."""
    text = SCREW.read_text().replace("use: lib/screw_operation.yaml", "use: taskflow:lib/screw_operation.yaml")
    copy = tmp_path / "screw_fastening.yaml"
    copy.write_text(text)
    assert await open_doc(client, copy) == []
    [loc] = await definition(client, copy, pos(text, "use: taskflow:lib/screw_", offset=-2))
    assert loc.uri == LIB.resolve().as_uri()
