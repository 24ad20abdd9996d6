"""A new user's first mission, written with only the editor's help: an empty file, then completion, diagnostics
and quick fixes from `taskflow lsp` through a real LSP client, then `taskflow run` on the saved file, judged
from the simulator's ground truth.  The steps and what the server answered are the transcript in
docs/editors.md ("A first mission with only the editor's help"); this test fails when the two differ
(TASKFLOW_WRITE_TRANSCRIPT=1 rewrites the document's transcript from the run)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from lsp_session import ROOT, change_doc, open_doc
from lsprotocol import types

from taskflow.registry import ROBOTS

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]

DOC = ROOT / "docs" / "editors.md"
TARGET = (2.0, 1.0)
"""Where the user wants the car's control point."""
FENCE = re.compile(r"(## A first mission with only the editor's help\n.*?```text\n)(.*?)(```)", re.S)


class Editor:
    """What an editor does with one buffer: typing at the cursor, moving it to the end of a line, asking for
    completion there and accepting an item, applying a quick fix; each step and the server's answer written to
    ``log`` (the transcript)."""

    def __init__(self, client, path: Path):
        self.client, self.path, self.uri = client, path, path.resolve().as_uri()
        self.text, self.cursor, self.version, self.log = "", 0, 1, []
        self.diagnostics: list[types.Diagnostic] = []

    async def open(self):
        self.diagnostics = await open_doc(self.client, self.path, self.text)
        self.log.append(f"open {self.path.name} (empty)")
        self._note_diagnostics()

    async def _changed(self):
        self.version += 1
        self.diagnostics = await change_doc(self.client, self.path, self.text, self.version)

    def _note_diagnostics(self):
        for d in self.diagnostics:
            self.log.append(f"    ! {d.range.start.line + 1}:{d.range.start.character + 1} {d.message}")

    async def type(self, s: str, note: bool = False):
        self.text = self.text[:self.cursor] + s + self.text[self.cursor:]
        self.cursor += len(s)
        await self._changed()
        self.log.append(f"type {s!r}")
        if note:
            self._note_diagnostics()

    def end_of_line(self, needle: str):
        """Move the cursor to the end of the line holding ``needle``."""
        at = self.text.index(needle)
        self.cursor = self.text.find("\n", at) % (len(self.text) + 1)
        self.log.append(f"cursor to the end of line {self.text.count(chr(10), 0, at) + 1}")

    def _position(self) -> types.Position:
        line = self.text.count("\n", 0, self.cursor)
        return types.Position(line=line, character=self.cursor - (self.text.rfind("\n", 0, self.cursor) + 1))

    async def complete(self, pick: str, show: int = 6) -> types.CompletionItem:
        """Ask for completion at the end of the buffer and accept ``pick`` (its text edit applied)."""
        result = await self.client.text_document_completion_async(types.CompletionParams(
            text_document=types.TextDocumentIdentifier(uri=self.uri), position=self._position()))
        assert result is not None, f"no completion at {self._position()} of:\n{self.text}"
        items = {i.label: i for i in result.items}
        assert pick in items, f"{pick!r} not offered: {sorted(items)}"
        labels = list(items)
        shown = ", ".join(f"{lab} ({items[lab].detail})" if items[lab].detail and lab == pick else lab
                          for lab in labels[:show])
        more = f", … {len(labels) - show} more" if len(labels) > show else ""
        self.log.append(f"complete → {shown}{more}")
        if pick not in labels[:show]:
            self.log.append(f"    … and {pick} ({items[pick].detail})")
        edit = items[pick].text_edit
        assert isinstance(edit, types.TextEdit)
        self._apply([edit])
        await self._changed()
        self.log.append(f"    accept {pick!r} → {self.text.split(chr(10))[edit.range.start.line].strip()!r}")
        return items[pick]

    def _apply(self, edits: list[types.TextEdit]):
        lines = self.text.split("\n")
        offsets = [0]
        for line in lines:
            offsets.append(offsets[-1] + len(line) + 1)
        for e in sorted(edits, key=lambda e: (e.range.start.line, e.range.start.character), reverse=True):
            a = offsets[e.range.start.line] + e.range.start.character
            b = offsets[e.range.end.line] + e.range.end.character
            self.text = self.text[:a] + e.new_text + self.text[b:]
            if a <= self.cursor:  # the cursor stays after what it was after (the end of an accepted item)
                self.cursor = max(self.cursor, b) + len(e.new_text) - (b - a)

    async def quick_fix(self, message_part: str) -> str:
        """Apply the quick fix the server offers for the diagnostic whose message contains ``message_part``."""
        ds = [d for d in self.diagnostics if message_part in d.message]
        assert ds, f"no diagnostic with {message_part!r}: {[d.message for d in self.diagnostics]}"
        actions = await self.client.text_document_code_action_async(types.CodeActionParams(
            text_document=types.TextDocumentIdentifier(uri=self.uri), range=ds[0].range,
            context=types.CodeActionContext(diagnostics=ds)))
        assert actions, f"no code action for {ds[0].message!r}"
        action = actions[0]
        assert isinstance(action, types.CodeAction) and action.edit is not None and action.edit.changes
        self._apply(action.edit.changes[self.uri])
        await self._changed()
        self.log.append(f"quick fix {action.title!r}")
        self._note_diagnostics()
        return action.title

    async def hover(self, needle: str) -> str:
        at = self.text.index(needle)
        line = self.text.count("\n", 0, at)
        h = await self.client.text_document_hover_async(types.HoverParams(
            text_document=types.TextDocumentIdentifier(uri=self.uri),
            position=types.Position(line=line, character=at - (self.text.rfind("\n", 0, at) + 1))))
        assert h is not None and isinstance(h.contents, types.MarkupContent)
        first = next(s for s in h.contents.value.splitlines() if s.strip() and not s.startswith("<a "))
        self.log.append(f"hover {needle!r} → {first.strip()}")
        return h.contents.value


async def write_first_mission(client, path: Path) -> Editor:
    ed = Editor(client, path)
    await ed.open()
    await ed.complete("mission")
    await ed.type("first_drive\n")
    await ed.complete("robot")
    await ed.complete("racecar")
    await ed.type("\nrate_hz: 20\n")
    await ed.complete("world")
    await ed.complete("flat_ground")
    await ed.type("\n")
    await ed.complete("machine")
    await ed.type("\n  ")
    await ed.complete("initial")
    await ed.type("go\n  ")
    await ed.complete("states")
    await ed.type("\n    go:\n      ")
    await ed.complete("task")
    await ed.type("\n        ")
    await ed.complete("name")
    await ed.complete("car_goto")
    await ed.hover("car_goto")
    await ed.type("\n        ")
    await ed.complete("params")
    await ed.type("\n          ")
    await ed.complete("target")
    await ed.type(f"[{TARGET[0]}, {TARGET[1]}]\n    done: {{final: succeeded}}\n    failed: {{final: failed}}\n",
                  note=True)
    await ed.quick_fix("has no way out")
    ed.end_of_line("- {to: failed")
    await ed.type("\n        - ")
    await ed.complete("to")
    await ed.type("don\n          ")
    await ed.complete("when")
    await ed.complete("pos_error")
    await ed.type(" < 0.03", note=True)
    await ed.quick_fix("did you mean")
    await ed.quick_fix("needs a unit")
    assert ed.diagnostics == [], [d.message for d in ed.diagnostics]
    return ed


async def test_a_new_user_writes_a_mission_that_runs_with_only_the_editor(client, tmp_path):
    path = tmp_path / "first.mission.yaml"
    ed = await write_first_mission(client, path)
    path.write_text(ed.text)
    run = subprocess.run([sys.executable, "-m", "taskflow.cli", "run", path.name, "--out", "run", "--quiet"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "succeeded" and summary["final_state"] == "done"
    # the simulator's pose of the rear axle at the end, and the control point d ahead of it (no gains bound:
    # d is the robot's wheelbase, car_goto's default)
    d = ROBOTS.get("racecar").Params().wheelbase
    x, y, yaw = (summary["metrics"][k] for k in ("gt_x_m", "gt_y_m", "gt_yaw_rad"))
    err = math.dist((x + d * math.cos(yaw), y + d * math.sin(yaw)), TARGET)
    assert err < 0.04, f"control point {100 * err:.1f} cm from the target"
    ed.log.append("save, then in a terminal:")
    ed.log.append(f"$ taskflow run {path.name}")
    ed.log.append(f"outcome: {summary['outcome']} (reached final state 'done') at {summary['sim_time_s']:.2f} s")
    ed.log.append(f"ground truth: control point {100 * err:.1f} cm from {list(TARGET)}")
    transcript = "\n".join(ed.log) + "\n\nthe file written:\n\n" + ed.text
    doc = DOC.read_text()
    m_ = FENCE.search(doc)
    assert m_, "docs/editors.md has no transcript block under 'A first mission with only the editor's help'"
    if os.environ.get("TASKFLOW_WRITE_TRANSCRIPT"):
        DOC.write_text(doc[:m_.start(2)] + transcript + doc[m_.end(2):])
    else:
        assert m_.group(2) == transcript, (
            "docs/editors.md's transcript is not what the server answers now; TASKFLOW_WRITE_TRANSCRIPT=1 rewrites"
            " it:\n" + transcript)
