"""The nested machine as a Mermaid ``stateDiagram-v2`` or a Graphviz ``dot`` digraph.

A parallel state's regions are drawn as its concurrent blocks (Mermaid's ``--`` concurrency separator;
in dot, dashed clusters stacked top to bottom by invisible edges, so a wide region does not widen the
row of the others), each labelled with the command parts it owns.

Dot output is laid out top to bottom with every composite a cluster.  Each non-parallel composite (and
the machine itself) holds a small filled start node with an edge to its initial state; a transition to or
from a composite is drawn from/to that start node, clipped at the cluster's border (``lhead`` /
``ltail``, ``compound=true``), so no stray node sits on a border.  A parallel state has no single initial
state: its anchor is an invisible node (each region shows its own start).  Long labels are wrapped to
:data:`WRAP` characters a line so a wide machine stays readable.

Mermaid labels are written with Mermaid's own entity codes (``#lt;``, ``#gt;``, ``#58;`` …), which
it renders as the characters written — never HTML escapes such as ``&lt;``; a label is one line (a line
break would end Mermaid's statement), and the few sequences Mermaid's lexer reads as syntax anywhere on a
line (``[[``, ``%%``) have their first character written as its code.  Mermaid has no invisible edges, so
its regions are only separated by ``--`` (Mermaid lays them out itself); a state id that is one of
Mermaid's keywords (``note``, ``state``, ``class`` …) gets a trailing ``_``, and ids that would clash
are told apart (:func:`diagram_ids`).  Both outputs are checked by
their own parsers over every shipped mission in ``tests/catalogue/test_graph.py``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Collection
from dataclasses import dataclass, field

from taskflow.mission.model import CompiledMission, StateNode

WRAP = 28
"""Longest line of a dot label before it wraps (characters)."""
HIGHLIGHT = "#d62728"
"""The colour of a highlighted path (a counterexample of ``taskflow verify``)."""


@dataclass(frozen=True)
class Highlight:
    """What to draw in :data:`HIGHLIGHT`: states by path and transitions by index (a path through the machine)."""

    states: Collection[str] = field(default_factory=frozenset)
    transitions: Collection[int] = field(default_factory=frozenset)

_MERMAID_ENTITIES = {"#": "#35;", "<": "#lt;", ">": "#gt;", ":": "#58;", ";": "#59;", '"': "#quot;",
                     "{": "#123;", "}": "#125;"}
_MERMAID_PAIRS = {"[[": "#91;[", "]]": "#93;]", "%%": "#37;%"}
"""Two-character sequences Mermaid's lexer takes as syntax wherever they stand (``[[fork]]``, ``%%{``)."""
_MERMAID_KEYWORDS = frozenset({"as", "class", "classdef", "click", "default", "href", "note", "scale", "state",
                               "statediagram", "style"})
"""Words Mermaid's state-diagram lexer reads as a keyword when one stands where a state id is expected
(matched without regard to case, as the lexer does)."""


def _mid(node: StateNode) -> str:
    return node.path.replace(".", "__").replace("-", "_")


def diagram_ids(m: CompiledMission, mermaid: bool = False) -> dict[str, str]:
    """State path → its id in a diagram: the path with ``.`` written ``__`` and ``-`` written ``_`` (for
    Mermaid, with a trailing ``_`` when that is one of Mermaid's keywords).  Two states whose ids would be
    the same (``a-b`` beside ``a_b``, ``a.b`` beside a top-level ``a__b``), or one named like the machine's
    start node, keep them apart: the later one in the mission gets ``_2``, ``_3`` …"""
    ids: dict[str, str] = {}
    taken = {start_id(None)}
    for path, node in m.states.items():
        base = _mid(node)
        if mermaid and base.lower() in _MERMAID_KEYWORDS:
            base += "_"
        cand, k = base, 2
        while cand in taken:
            cand, k = f"{base}_{k}", k + 1
        ids[path] = cand
        taken.add(cand)
    return ids


def mermaid_text(text: str, quoted: bool = False) -> str:
    """``text`` on one line (runs of white space, line breaks included, become one space) with each character
    Mermaid would read as syntax written as its entity code; inside a quoted state description
    (``quoted``) only ``"``, ``#``, ``<`` and ``>`` need it.  ``[[``, ``]]`` and ``%%`` are read as syntax
    in both places, so their first character is written as its code."""
    keep = set(":;{}") if quoted else set()
    out = "".join(c if c in keep else _MERMAID_ENTITIES.get(c, c) for c in " ".join(text.split()))
    for pair, code in _MERMAID_PAIRS.items():
        out = out.replace(pair, code)
    return out


def _state_label(node: StateNode) -> str:
    label = node.name
    if node.owns is not None:
        label += f" [region: {', '.join(node.owns) or 'commands nothing'}]"
    if node.parallel:
        label += " [parallel]"
    if node.task_cls is not None and node.is_leaf and not node.final:
        label += f" ({node.task_cls.name})"
    if node.loop:
        label += f" [foreach {node.loop.item} in {node.loop.items}]"
    if node.history:
        label += " [H]"
    if node.use:
        label += f" [use {node.use}]"
    if node.final:
        label += f" = {node.final}"
    return label


def to_mermaid(m: CompiledMission, highlight: Highlight | None = None) -> str:
    """``m`` as a Mermaid ``stateDiagram-v2``: composites as nested ``state … {}`` blocks, a parallel
    state's regions separated by ``--``, every transition drawn at the top level with its trigger as label;
    ``highlight``'s states in a ``classDef`` of :data:`HIGHLIGHT` and its transitions with ``linkStyle``."""
    lines = ["stateDiagram-v2", f"    %% mission {mermaid_text(m.name)}"]
    ids = diagram_ids(m, mermaid=True)

    def block(node: StateNode, indent: str) -> None:
        if node.children and not node.parallel:
            lines.append(f"{indent}[*] --> {ids[node.initial_child().path]}")
        for i, child in enumerate(node.children.values()):
            if node.parallel and i:
                lines.append(f"{indent}--")
            label = mermaid_text(_state_label(child), quoted=True)
            if child.children:
                lines.append(f'{indent}state "{label}" as {ids[child.path]} {{')
                block(child, indent + "    ")
                lines.append(f"{indent}}}")
            else:
                lines.append(f'{indent}state "{label}" as {ids[child.path]}')
            if child.final:
                lines.append(f"{indent}{ids[child.path]} --> [*]")

    block(m.root, "    ")
    links = sum(1 for line in lines if " --> " in line)  # linkStyle counts every arrow, the [*] ones too
    marked: list[int] = []
    for t in m.transitions:
        if highlight is not None and t.index in highlight.transitions:
            marked.append(links)
        lines.append(f"    {ids[t.source.path]} --> {ids[t.target.path]} : {mermaid_text(t.label)}")
        links += 1
    if highlight is not None:
        lines.append(f"    classDef counterexample stroke:{HIGHLIGHT},stroke-width:3px")
        states = [ids[p] for p in m.states if p in highlight.states]
        if states:
            lines.append(f"    class {','.join(states)} counterexample")
        if marked:
            lines.append(f"    linkStyle {','.join(map(str, marked))} stroke:{HIGHLIGHT},stroke-width:3px")
    return "\n".join(lines)


def _dot_escape(text: str) -> str:
    """``text`` inside a dot quoted string: backslashes and quotes escaped."""
    return text.replace("\\", "\\\\").replace('"', '\\"')


def _dot_text(text: str) -> str:
    """A dot label: quotes escaped, wrapped at :data:`WRAP` characters (``\\n`` line breaks)."""
    lines = textwrap.wrap(text, WRAP, break_long_words=False, break_on_hyphens=False) or [""]
    return "\\n".join(_dot_escape(line) for line in lines)


def start_id(node: StateNode | None, ids: dict[str, str] | None = None) -> str:
    """The dot id of a composite's start node (the machine's, ``node`` None or the root: ``__start``);
    ``ids`` are the mission's :func:`diagram_ids` (default: the plain path-derived id)."""
    if node is None or not node.path:
        return "__start"
    return f"__start__{ids[node.path] if ids is not None else _mid(node)}"


def to_dot(m: CompiledMission, highlight: Highlight | None = None) -> str:
    """``m`` as a Graphviz digraph laid out top to bottom (see the module's docstring); ``highlight``'s states
    and transitions drawn in :data:`HIGHLIGHT`."""
    marked = highlight if highlight is not None else Highlight()
    ids = diagram_ids(m)

    def sid(node: StateNode) -> str:
        return start_id(node, ids)

    def anchor(node: StateNode) -> str:
        """The node an edge to or from ``node`` attaches to: the leaf itself, a composite's start node."""
        return sid(node) if node.children else ids[node.path]

    lines = [f'digraph "{_dot_escape(m.name)}" {{',
             "    compound=true; rankdir=TB; newrank=true; nodesep=0.25; ranksep=0.35;",
             '    node [shape=box, style=rounded, fontsize=11]; edge [fontsize=9];']

    def start_node(node: StateNode, indent: str) -> None:
        if node.parallel:
            lines.append(f'{indent}"{sid(node)}" [shape=point, style=invis, width=0, height=0, label=""];')
        else:
            lines.append(f'{indent}"{sid(node)}" [shape=circle, style=filled, fillcolor=black, width=0.15, '
                         'height=0.15, fixedsize=true, label=""];')

    def block(node: StateNode, indent: str) -> None:
        start_node(node, indent)
        if not node.parallel and node.initial is not None:
            first = node.children[node.initial]
            lhead = f', lhead="cluster_{ids[first.path]}"' if first.children else ""
            lines.append(f'{indent}"{sid(node)}" -> "{anchor(first)}" [weight=10{lhead}];')
        for child in node.children.values():
            if child.children:
                lines.append(f'{indent}subgraph "cluster_{ids[child.path]}" {{')
                extra = [f"use {child.use}"] if child.use else []
                if child.loop:
                    extra.append(f"foreach {child.loop.item} in {child.loop.items}")
                if child.history:
                    extra.append("history")
                if child.parallel:
                    extra.append("parallel")
                if child.owns is not None:
                    extra.append(f"region: {', '.join(child.owns) or 'commands nothing'}")
                    lines.append(f"{indent}    style=dashed;")
                title = f"{child.name}{' (' + ', '.join(extra) + ')' if extra else ''}"
                lines.append(f'{indent}    label="{_dot_text(title)}"; labeljust=l;')
                block(child, indent + "    ")
                lines.append(f"{indent}}}")
                if node.parallel and child is not next(iter(node.children.values())):
                    # regions are stacked top to bottom, so a wide region does not widen the others' row
                    above = list(node.children.values())[list(node.children).index(child.name) - 1]
                    for leaf in (d for d in above.walk() if d.is_leaf):
                        lines.append(f'{indent}"{ids[leaf.path]}" -> "{sid(child)}" [style=invis, weight=0];')
            else:
                shape = ", peripheries=2" if child.final else ""
                task = f" ({child.task_cls.name})" if child.task_cls is not None and not child.final else ""
                fin = f" = {child.final}" if child.final else ""
                second = _dot_text((task + fin).strip())
                label = _dot_text(child.name) + (f"\\n{second}" if second else "")
                if child.path in marked.states:
                    shape += f', color="{HIGHLIGHT}", penwidth=2.5'
                lines.append(f'{indent}"{ids[child.path]}" [label="{label}"{shape}];')

    block(m.root, "    ")
    for t in m.transitions:
        attrs = [f'label="{_dot_text(t.label)}"']
        if t.source.children and not _contains(t.source, t.target):
            attrs.append(f'ltail="cluster_{ids[t.source.path]}"')
        if t.target.children and not _contains(t.target, t.source):
            attrs.append(f'lhead="cluster_{ids[t.target.path]}"')
        if t.index in marked.transitions:
            attrs += [f'color="{HIGHLIGHT}"', f'fontcolor="{HIGHLIGHT}"', "penwidth=2.5"]
        lines.append(f'    "{anchor(t.source)}" -> "{anchor(t.target)}" [{", ".join(attrs)}];')
    lines.append("}")
    return "\n".join(lines)


def _contains(outer: StateNode, node: StateNode) -> bool:
    return any(a is outer for a in node.ancestors())
