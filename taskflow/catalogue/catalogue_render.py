"""The catalogue (:mod:`taskflow.catalogue.catalogue`) as terminal text and markdown.

``taskflow list`` prints :func:`list_text`, ``taskflow describe NAME`` :func:`describe_text` (or
:func:`describe_markdown` with ``--markdown``), and ``taskflow describe --all --markdown`` prints
:func:`reference_markdown`, the page ``docs/reference.md`` is generated as.  Both formats render the same
sections (:func:`sections`), so they cannot drift apart.
"""

from __future__ import annotations

import json
import re
from typing import Any, NamedTuple

from taskflow.catalogue.catalogue import KINDS, Catalogue, Entry, Kind
from taskflow.catalogue.declarations import Param

REFERENCE_COMMAND = "taskflow describe --all --markdown > docs/reference.md"
"""The command ``docs/reference.md`` is generated with (its header and the README say so)."""


class Section(NamedTuple):
    """One part of a description: a title, an optional paragraph, one line per item."""

    title: str
    intro: str
    lines: list[str]


def _value(v: Any) -> str:
    return json.dumps(v, ensure_ascii=False)


def param_line(p: Param) -> str:
    """``name: type, default 2.0, unit s, > 0 — description``."""
    parts = [p.type, "required" if p.required else f"default {_value(p.default)}"]
    if p.unit:
        parts.append(f"unit {p.unit}")
    if p.bounds:
        parts.append(p.bounds)
    return f"{p.name}: {', '.join(parts)}" + (f" — {p.description}" if p.description else "")


def _params(params: tuple[Param, ...]) -> list[str]:
    return [param_line(p) for p in params] or ["(none)"]


def sections(e: Entry) -> list[Section]:
    """What :func:`describe_text` and :func:`describe_markdown` show of ``e``, in order."""
    out: list[Section] = []

    def add(title: str, lines: list[str], intro: str = "") -> None:
        out.append(Section(title, intro, lines))

    if e.kind != "sensor":
        add(f"parameters (`{e.kind}: {{name: {e.name}, params: {{...}}}}`)", _params(e.params), e.params_doc)
    if e.slots:
        add("profile slots (`bind: {SLOT: PROFILE}`: a profile of `profiles.KIND`, or the fields inline)",
            [f"{sl.name}: kind {sl.profile_kind} ({sl.model}; "
             f"{'binding required' if sl.required else 'optional, defaults apply'})" for sl in e.slots])
        for sl in {sl.profile_kind: sl for sl in e.slots}.values():
            add(f"profile kind {sl.profile_kind} ({sl.model}) fields", _params(sl.fields), sl.summary)
    if e.kind in ("task", "world"):
        add("metrics (guards: `when: NAME < 2 cm`)",
            [f"{m.name}: {m.unit or '(dimensionless)'}" + (f", {m.bounds}" if m.bounds else "")
             + (f" ({m.reason})" if m.reason else "") for m in e.metrics] or ["(none)"])
        add("events (`on: NAME`)", list(e.events) or ["(none)"])
    if e.actions:
        add("actions (`action: {name, params}`)", [f"{a.name}: ends with {', '.join(a.ends_with)}" for a in e.actions])
        for a in e.actions:
            add(f"action {a.name} params", _params(a.params))
    if e.kind == "task":
        add("command interface", [e.command_interface or "(none: it commands no motion)"])
    elif e.kind == "robot":
        add("command interface", [e.command_interface] + [f"{p.name}: {p.type}" for p in e.command_keys])
    elif e.kind == "world":
        add("command interfaces it actuates", [e.command_interface or "(any)"])
    if e.robot_params:
        add("robot parameters it reads (the robot's params must have them)",
            [f"{p.name}: {p.type}" for p in e.robot_params])
    if e.sensors:
        add("sensor mounts it carries" if e.kind == "robot" else "sensor mounts the robot must carry",
            [f"{p.name}: {p.type}" for p in e.sensors])
    if e.needs_body:
        add("robot body", ["the robot needs a registered simulator body (entry point group taskflow.bodies)"])
    if e.kind == "sensor":
        add("provided by", [f"{st.by[0]}: {st.type}" for st in e.provides] or ["(nothing registered)"])
        add("read by", [f"{st.by[0]}: {st.type}" for st in e.requires] or ["(no task)"])
    else:
        if e.requires:
            add("observations it requires (provided by)",
                [f"{st.key}: {st.type} ({', '.join(st.by) or 'no registered provider'})" for st in e.requires])
        if e.provides:
            add("observations it provides (read by)",
                [f"{st.key}: {st.type}" + (f" ({', '.join(st.by)})" if st.by else "") for st in e.provides])
    if e.ground_truth_keys:
        add("ground-truth keys (trace columns and summary; never in observations)", [", ".join(e.ground_truth_keys)])
    for lv in e.fidelity:
        add(f"fidelity {lv.name} (`world.params.fidelity: {lv.name}`; keys the mission sets win)",
            [f"{v.param}: {_value(v.value)} — {v.source}" for v in lv.values] or ["(sets nothing)"])
    if e.kind != "sensor":
        title = {"task": "runs with (robot on world)", "robot": "hosted by, driven by", "world": "hosts"}[e.kind]
        add(title, list(e.works_with) or ["(nothing registered)"])
    for m in e.types:
        add(f"type {m.name}", [param_line(p) if e.kind != "sensor" else f"{p.name}: {p.type}" for p in m.fields],
            m.summary)
    return out


def _plain(text: str) -> str:
    """Docstring markup for a terminal: ````x```` → ```x```."""
    return text.replace("``", "`")


def list_text(cat: Catalogue, kind: Kind | None = None) -> str:
    """``taskflow list [KIND]``: one line per name with its summary, grouped by kind."""
    lines: list[str] = []
    for k in KINDS if kind is None else (kind,):
        entries = cat.of_kind(k)
        width = max((len(e.name) for e in entries), default=0)
        body = [f"  {e.name:<{width}}  {_plain(e.summary)}" for e in entries] or ["  (none registered)"]
        lines += ([f"{k}s:"] + body + [""]) if kind is None else body
    for name, why in cat.broken.items():
        lines.append(f"(not loaded: {name}: {why})")
    return "\n".join(lines).rstrip("\n") + "\n"


def describe_text(e: Entry) -> str:
    """``taskflow describe NAME``: the entry as terminal text."""
    lines = [f"{e.kind} {e.name}" + (f"  ({e.source})" if e.source else "")]
    lines += [f"  {_plain(line)}".rstrip() for line in (e.doc or e.summary).splitlines()]
    for s in sections(e):
        lines += ["", f"{_plain(s.title)}:"]
        if s.intro:
            lines.append(f"  {_plain(' '.join(s.intro.split()))}")
        lines += [f"  {_plain(b)}" for b in s.lines]
    return "\n".join(lines) + "\n"


def anchor(e: Entry) -> str:
    """The markdown anchor of ``e``'s section in the reference page."""
    return re.sub(r"[^a-z0-9_-]", "", f"{e.kind}-{e.name}".lower().replace(".", "-"))


def describe_markdown(e: Entry, level: int = 3, anchored: bool = True) -> str:
    """The entry as a markdown section (``level``: its heading's; ``anchored``: with the anchor the reference
    page links to — an editor's hover has no use for it)."""
    out = [f'<a id="{anchor(e)}"></a>', ""] if anchored else []
    out += [f"{'#' * level} {e.kind} `{e.name}`", "", e.doc or e.summary, ""]
    if e.source:
        out += [f"Declared by `{e.source}`.", ""]
    for s in sections(e):
        out += [f"**{s.title}**", ""]
        if s.intro:
            out += [s.intro, ""]
        out += [f"- {b}" for b in s.lines] + [""]
    return "\n".join(out)


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def reference_markdown(cat: Catalogue) -> str:
    """The whole catalogue as one markdown page (``docs/reference.md``)."""
    out = ["# Reference: registered tasks, robots, worlds and sensors", "",
           f"<!-- Generated by `{REFERENCE_COMMAND}`: do not edit by hand "
           "(tests/catalogue/test_catalogue.py checks it is current). -->", "",
           f"Generated from the registry by `{REFERENCE_COMMAND}`; regenerate it after changing a task, robot "
           "or world. `taskflow list` and `taskflow describe NAME` print the same for what is installed, "
           "plugins included. Metric units are the SI base units values are published in; a guard may write "
           "any unit of the same dimension (`2 cm`, `3 deg`). The mission file format: [missions.md](missions.md).",
           ""]
    for k in KINDS:
        out += [f"## {k.capitalize()}s", "", "| name | summary |", "|---|---|"]
        out += [f"| [`{e.name}`](#{anchor(e)}) | {_cell(e.summary)} |" for e in cat.of_kind(k)]
        out.append("")
    for k in KINDS:
        out += [f"## {k.capitalize()}s in detail", ""]
        out += [describe_markdown(e) for e in cat.of_kind(k)]
    return "\n".join(out).rstrip("\n") + "\n"
