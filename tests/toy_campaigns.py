"""A toy campaign with declared properties (tests/machine/missions/toy_full.yaml plus a ``properties:`` block),
shared by the campaign page's tests (tests/operate/test_campaign_view.py, test_view_browser.py).

Swept over ``world.params.tool_ok=true,false`` the tool fails in condition 1: the mission fails there and
``never_broken`` is violated, so both rates are 50 % over the campaign."""

from __future__ import annotations

from pathlib import Path

TOY = Path(__file__).resolve().parent / "machine" / "missions" / "toy_full.yaml"
PROPS = """properties:
  never_broken: {never: "event(tool_failed)"}
  always_near: {always: "pos_error < 0.5 m"}
  tool_after_approach: {only_after: "state(operate.visit.approach)", occurs: "event(tool_done)"}
"""
SWEEP = ["world.params.tool_ok=true,false"]


def toy_with_properties(folder: Path) -> Path:
    """The toy mission with :data:`PROPS`, written into ``folder``."""
    mission = folder / "toy_props.yaml"
    mission.write_text(TOY.read_text().replace("machine:\n", PROPS + "machine:\n", 1))
    return mission
