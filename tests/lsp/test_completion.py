"""Completion through a real LSP client over stdio: on shipped missions, a sub-mission and half-typed text."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml
from lsp_session import MISSIONS, change_doc, open_doc, pos
from lsprotocol import types

from taskflow.registry import TASKS, WORLDS
from taskflow.units import UNITS

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

VIKI = MISSIONS / "viki_hyco.yaml"
SCREW = MISSIONS / "screw_fastening.yaml"
SUB = MISSIONS / "lib" / "screw_operation.yaml"
OVAL = MISSIONS / "visual_path_oval.yaml"


async def complete(client, path: Path, text: str, needle: str, offset: int = 0) -> dict[str, types.CompletionItem]:
    result = await client.text_document_completion_async(types.CompletionParams(
        text_document=types.TextDocumentIdentifier(uri=path.resolve().as_uri()), position=pos(text, needle, offset)))
    assert result is not None, needle
    return {i.label: i for i in result.items}


async def test_half_typed_task_name_lists_tasks_and_replaces_the_word(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    cut = text.replace("task: {name: viki_hyco, params: {camera: front", "task: {name: viki_hy", 1)
    await change_doc(client, VIKI, cut, 2)
    items = await complete(client, VIKI, cut, "task: {name: viki_hy")
    assert {"viki_hyco", "viki_rotate", "pbvs_arm"} <= set(items) <= set(TASKS.names())  # (tests add toy tasks)
    edit = items["viki_hyco"].text_edit
    assert isinstance(edit, types.TextEdit) and edit.new_text == "viki_hyco"
    line = cut[:cut.index("{name: viki_hy")].count("\n")
    start = cut.split("\n")[line].index("viki_hy")
    assert (edit.range.start.line, edit.range.start.character, edit.range.end.character) == (line, start, start + 7)


async def test_a_new_state_half_typed_gets_state_keys(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    cut = text.replace("    placed: {final: succeeded}", "    extra:\n      ta\n    placed: {final: succeeded}", 1)
    await change_doc(client, VIKI, cut, 2)
    items = await complete(client, VIKI, cut, "extra:\n      ta")
    assert {"task", "bind", "transitions", "states", "final"} <= set(items)
    assert items["task"].text_edit.new_text == "task: "
    assert "mission" not in items
    # in a state that has them, the keys already written are not offered again; the one being typed is
    items = await complete(client, VIKI, cut, "    backward:\n      descr")
    assert "description" in items and "task" not in items and "transitions" not in items
    assert {"final", "states", "regions"} <= set(items)


async def test_top_level_keys_of_a_mission_and_of_a_sub_mission(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    items = await complete(client, VIKI, text, "rate_hz", -7)  # on the key `rate_hz`: it, and keys not written
    assert {"rate_hz", "seed", "events", "data"} <= set(items)
    assert not {"mission", "robot", "world", "machine", "profiles"} & set(items)
    sub = SUB.read_text()
    await open_doc(client, SUB)
    items = await complete(client, SUB, sub, "exits", -5)
    assert set(items) == {"exits"}  # a sub-mission's keys (no `robot`), all written but the one typed


async def test_transition_keys_robot_and_world_names(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    items = await complete(client, VIKI, text, "- {to: rotate, ", 0)
    assert {"when", "after", "on", "blend"} <= set(items) and not {"to", "for"} & set(items)  # (written already)
    assert "racecar" in await complete(client, VIKI, text, "robot: ")
    worlds = set(await complete(client, VIKI, text, "  name: viki_g"))
    assert {"viki_ground", "screw_conveyor"} <= worlds <= set(WORLDS.names())


async def test_task_params_with_type_default_and_unit(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    items = await complete(client, VIKI, text, "params: {radius", -6)
    # viki_rotate's, not viki_hyco's; `turn` is written already, `radius` is the key under the cursor
    assert set(items) == {"radius", "lookahead", "leg_tolerance", "camera", "keep_out_body", "keep_out_margin"}
    cut = text.replace("params: {camera: front, desired: $front_goal, ", "params: {camera: front, ", 1)
    await change_doc(client, VIKI, cut, 2)
    items = await complete(client, VIKI, cut, "params: {camera", -6)
    assert "required" in items["camera"].detail and "[m]" in items["desired"].detail
    assert "keep_out_body" not in items


async def test_bind_slots_profile_fields_and_profile_names_of_the_slot_kind(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    assert "gains" in await complete(client, VIKI, text, "bind: {", 0)
    fields = await complete(client, VIKI, text, "front: {", 0)
    assert {"lam", "d"} <= set(fields) and "k1" not in fields  # (`k1` is written; `lam` under the cursor)
    names = await complete(client, VIKI, text, "bind: {gains: fr")
    assert set(names) == set(yaml.safe_load(text)["profiles"]["viki_gains"])  # not the `gains` kind's `rotate`


async def test_transition_targets_events_and_guards(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    targets = await complete(client, VIKI, text, "- {to: no_t")
    assert {"rotate", "placed", "no_target", "forward_timeout"} <= set(targets) and "machine" not in targets
    events = await complete(client, VIKI, text, "on: no_t")
    assert "no_target" in events and "rotate" not in events
    metrics = await complete(client, VIKI, text, 'when: "feature_e')
    assert metrics["feature_error"].detail == "px" and "goal_error" in metrics and "$body" in metrics
    units = await complete(client, VIKI, text, "goal_error < 1 c")
    assert set(units) == {u for u, (dim, _) in UNITS.items() if dim == "length"}


async def test_sub_mission_files_their_parameters_and_targets_inside_the_sub_mission(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    assert "lib/screw_operation.yaml" in await complete(client, SCREW, text, "use: lib/")
    params = await complete(client, SCREW, text, "with: {", 0)  # on the first key: it alone is not written
    assert set(params) == {"camera_target"}
    cut = text.replace(" approach: $approach,", "", 1)
    await change_doc(client, SCREW, cut, 2)
    params = await complete(client, SCREW, cut, "with: {", 0)
    assert set(params) == {"camera_target", "approach"} and "approach" in yaml.safe_load(SUB.read_text())["parameters"]
    await change_doc(client, SCREW, text, 3)
    sub = SUB.read_text()
    await open_doc(client, SUB)
    targets = await complete(client, SUB, sub, "{to: s3_arm")
    assert {"s3_arm_destination_approach", "screw_failed", "error_stop"} <= set(targets)
    dollars = await complete(client, SUB, sub, "target: $screw", -5)
    assert {"$camera_target", "$screw"} <= set(dollars)


async def test_foreach_and_retry_keys(client):
    sub = SUB.read_text()
    line = "      foreach: {in: screws, as: screw, on_failure: continue, require: all, retry: {times: 2, on: [attempt_failed]}}"
    assert line in sub
    await open_doc(client, SUB)
    cut = sub.replace(line, "      foreach:\n        in: screws\n        as: screw\n        re", 1)
    await change_doc(client, SUB, cut, 2)
    items = await complete(client, SUB, cut, "as: screw\n        re")
    assert {"in", "as", "on_failure", "require", "retry"} <= set(items) and "task" not in items and "states" not in items
    cut = sub.replace(line, "      foreach:\n        in: screws\n        as: screw\n        retry:\n          ti", 1)
    await change_doc(client, SUB, cut, 3)
    items = await complete(client, SUB, cut, "retry:\n          ti")
    assert set(items) == {"times", "on"}


async def test_world_params_and_fidelity_levels(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    world = WORLDS.get(yaml.safe_load(text)["world"]["name"])
    cut = text.replace("motion: conveyor", "fidelity: \n    motion: conveyor", 1)
    await change_doc(client, SCREW, cut, 2)
    levels = await complete(client, SCREW, cut, "fidelity: ")
    assert set(levels) == set(world.Params.fidelity_names())
    keys = await complete(client, SCREW, cut, "\n    motion", -6)  # on `motion`: it, and the ones not written
    written = set(yaml.safe_load(cut)["world"]["params"])
    assert {"fidelity", "motion"} <= written and set(keys) == (set(world.Params.model_fields) - written) | {"motion"}


async def test_completion_is_fast_on_the_largest_mission(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    await complete(client, SCREW, text, "to: ")
    start = time.perf_counter()
    for _ in range(10):
        await complete(client, SCREW, text, "to: ")
    assert (time.perf_counter() - start) / 10 < 0.1


async def test_oval_mission_and_nonsense_never_fail(client):
    text = OVAL.read_text()
    await open_doc(client, OVAL)
    data = yaml.safe_load(text)
    first = next(iter(data["machine"]["states"]))
    assert first in await complete(client, OVAL, text, "initial: ")
    junk = "{[: :: - -\n\t- ]]"
    await change_doc(client, OVAL, junk, 2)
    for line in range(2):
        for col in range(6):
            await client.text_document_completion_async(types.CompletionParams(
                text_document=types.TextDocumentIdentifier(uri=OVAL.resolve().as_uri()),
                position=types.Position(line=line, character=col)))
