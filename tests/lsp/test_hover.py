"""Hover through a real LSP client over stdio: catalogue text, metrics, profiles, states and guard thresholds."""

from __future__ import annotations

from pathlib import Path

import pytest
from lsp_session import MISSIONS, change_doc, open_doc, pos
from lsprotocol import types

from taskflow.registry import TASKS, WORLDS

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

VIKI = MISSIONS / "viki_hyco.yaml"
SCREW = MISSIONS / "screw_fastening.yaml"
SUB = MISSIONS / "lib" / "screw_operation.yaml"
OVAL = MISSIONS / "visual_path_oval.yaml"


async def hover(client, path: Path, text: str, needle: str, offset: int = -1) -> str:
    result = await client.text_document_hover_async(types.HoverParams(
        text_document=types.TextDocumentIdentifier(uri=path.resolve().as_uri()), position=pos(text, needle, offset)))
    assert result is not None, needle
    assert isinstance(result.contents, types.MarkupContent) and result.contents.kind == types.MarkupKind.Markdown
    return result.contents.value


async def test_task_and_world_with_their_parameters(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    md = await hover(client, VIKI, text, "name: viki_rot")
    assert "viki_rotate" in md and all(f in md for f in TASKS.get("viki_rotate").Params.model_fields)
    md = await hover(client, VIKI, text, "name: viki_gr")
    assert "viki_ground" in md and "physics_hz" in md
    md = await hover(client, VIKI, text, "    physics_h")
    assert "Hz" in md and "240" in md  # type, unit and default of the world parameter


async def test_world_parameter_names_its_fidelity_sources(client):
    text = SCREW.read_text()
    await open_doc(client, SCREW)
    world = WORLDS.get("screw_conveyor")
    levels = world.Params.FIDELITY
    assert levels, "screw_conveyor declares no fidelity level"
    name, level = next(iter(levels.items()))
    param, sourced = next(iter(level.items()))
    cut = text.replace("    motion: conveyor", f"    {param}: {sourced.value!r}\n    motion: conveyor", 1)
    await change_doc(client, SCREW, cut, 2)
    md = await hover(client, SCREW, cut, f"    {param[:-1]}", 0)
    assert sourced.source in md and name in md


async def test_metric_unit_publisher_and_threshold_in_base_units(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    md = await hover(client, VIKI, text, '"feature_err')
    assert "feature_error" in md and "px" in md and "task viki_hyco" in md
    md = await hover(client, VIKI, text, "goal_error < 1 c", 0)
    assert "0.01 m" in md
    md = await hover(client, VIKI, text, "view_shift < 2 c", 0)
    assert "0.02 m" in md


async def test_profile_resolved_values_and_state_task_and_bindings(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    md = await hover(client, VIKI, text, "bind: {gains: fr")
    assert "lam" in md and "0.85" in md and "(default)" in md  # the model's defaults filled in
    md = await hover(client, VIKI, text, "    rotate:\n      description", -len(":\n      description") - 1)
    assert "viki_rotate" in md and "gains" in md and "rotate" in md


async def test_sub_mission_opened_alone_knows_its_states_and_profiles(client):
    await open_doc(client, SCREW)
    sub = SUB.read_text()
    await open_doc(client, SUB)
    md = await hover(client, SUB, sub, "bind: {platform: platform_b")
    assert "pid.platform_boost" in md and "kd" in md
    md = await hover(client, SUB, sub, "camera_error.t <", -3)
    assert "camera_error.t" in md and "task pbvs_platform" in md


async def test_half_typed_buffer_still_hovers_and_nonsense_returns_nothing(client):
    text = OVAL.read_text()
    await open_doc(client, OVAL)
    cut = text + "\n  bad: [unclosed\n"
    await change_doc(client, OVAL, cut, 2)
    result = await client.text_document_hover_async(types.HoverParams(
        text_document=types.TextDocumentIdentifier(uri=OVAL.resolve().as_uri()), position=types.Position(0, 0)))
    assert result is None or isinstance(result, types.Hover)
    await change_doc(client, OVAL, "{[: :: -", 3)
    result = await client.text_document_hover_async(types.HoverParams(
        text_document=types.TextDocumentIdentifier(uri=OVAL.resolve().as_uri()), position=types.Position(0, 2)))
    assert result is None


async def test_parameter_value_event_sources_and_no_catalogue_anchor(client):
    text = VIKI.read_text()
    await open_doc(client, VIKI)
    md = await hover(client, VIKI, text, "desired: $zo")
    assert "$zone" in md and "[-0.9, 0.0]" in md
    md = await hover(client, VIKI, text, "{to: no_target, on: no_tar")
    assert "event `no_target`" in md and "task `viki_hyco`" in md and "task `viki_rotate`" in md  # both declare it
    assert "world" not in md  # viki_ground does not raise it
    md = await hover(client, VIKI, text, "name: viki_rot")
    assert "<a id" not in md
