"""Graph output: every diagram accepted by its own parser (Mermaid's, Graphviz's), initial states marked,
no stray nodes on cluster borders, top-to-bottom layout with wrapped labels, Mermaid labels that render as
written."""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest
from diagram_parsers import ParserMissing, dot_errors, mermaid_errors

from taskflow.catalogue.graph import WRAP, mermaid_text, start_id, to_dot, to_mermaid
from taskflow.mission.loader import load_mission

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = sorted((ROOT / "missions").glob("*.yaml"))
REGIONS = Path(__file__).parents[1] / "machine" / "missions" / "toy_regions.yaml"  # drive (owns v), watch
EVERY_FEATURE = Path(__file__).parents[1] / "graph" / "every_feature.yaml"  # nested regions, history, use:, keywords
DIAGRAMMED = MISSIONS + sorted((Path(__file__).parents[1] / "machine" / "missions").glob("*.yaml")) + [EVERY_FEATURE]
"""Every shipped mission and the test missions with regions, nested regions, history, foreach and sub-missions."""


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT))


def test_every_mermaid_diagram_is_accepted_by_mermaids_own_parser() -> None:
    texts = [to_mermaid(load_mission(p)) for p in DIAGRAMMED]
    t0 = time.perf_counter()
    errors = mermaid_errors(texts)  # one Node process for all of them
    took = time.perf_counter() - t0
    bad = [f"{_name(p)}: {e.splitlines()[0]} {' '.join(e.splitlines()[1:3])}" for p, e in zip(DIAGRAMMED, errors) if e]
    assert not bad, "\n".join(bad)
    print(f"Mermaid's parser accepted {len(texts)} diagrams in {took:.2f} s (one node process)")


def test_every_dot_diagram_is_accepted_by_graphviz() -> None:
    bad = [f"{_name(p)}: {e}" for p in DIAGRAMMED if (e := dot_errors(to_dot(load_mission(p))))]
    assert not bad, "\n".join(bad)


def test_the_parsers_reject_what_they_should() -> None:
    # the check has teeth: Graphviz's lines inside Mermaid (what main drew for regions), a state id that is a
    # Mermaid keyword, and a label broken over two lines are refused; a broken digraph is refused by dot
    good = "stateDiagram-v2\n    [*] --> a\n    a --> b : go\n"
    errors = mermaid_errors([good, good + '    "a" -> "b" [style=invis, weight=0];\n',
                             "stateDiagram-v2\n    [*] --> note\n    state \"n\" as note\n"])
    assert errors[0] is None and errors[1] is not None and errors[2] is not None
    assert "Lexical error" in errors[1] or "Parse error" in errors[1]
    assert dot_errors('digraph "x" { "a" -> "b" [label="ok"]; }') is None
    assert dot_errors('digraph "x" { "a" -> [label="no head"]; }') is not None


TRICKY_NAMES = ["note", "state", "class", "classDef", "style", "click", "scale", "default", "as", "href",
                "stateDiagram", "stateDiagram-v2", "Note", "STATE", "end", "direction", "hide", "fork", "ä_größe",
                "1st", "x-y", "root"]
"""State names a mission may use (letters, digits, '_', '-') that Mermaid's lexer reads as keywords, or
that look like syntax."""


def test_state_names_that_are_mermaid_keywords_draw_in_both_formats() -> None:
    from taskflow.mission.loader import load_mission_text

    states = "\n".join(f"    {n}:\n      transitions: [{{to: {nxt}, after: 1 s}}]"
                       for n, nxt in zip(TRICKY_NAMES, TRICKY_NAMES[1:] + ["fin"]))
    comp = "\n".join(f"        {n}:\n          transitions: [{{to: {nxt}, after: 1 s}}]"
                     for n, nxt in zip(TRICKY_NAMES, TRICKY_NAMES[1:] + ["ok"]))
    text = (f"mission: tricky\nrobot: toy_point\nworld: toy_line\nrate_hz: 20\nmax_time: 30 s\nmachine:\n  initial: {TRICKY_NAMES[0]}\n  states:\n"
            f"{states}\n    fin:\n      history: true\n      initial: {TRICKY_NAMES[0]}\n"
            f"      transitions: [{{to: done, done: true}}]\n      states:\n{comp}\n        ok: {{final: true}}\n"
            "    done: {final: succeeded}\n")
    m = load_mission_text(text, "tricky.yaml")
    assert len(m.states) == 2 * len(TRICKY_NAMES) + 3
    (error,) = mermaid_errors([to_mermaid(m)])
    assert error is None, error
    assert dot_errors(to_dot(m)) is None


def test_states_whose_ids_would_clash_stay_apart() -> None:
    from taskflow.mission.loader import load_mission_text

    # `a-b` beside `a_b`, the composite `p`'s child `q` beside a top-level `p__q`, and `note` beside `note_`
    text = """mission: clash
robot: toy_point
world: toy_line
rate_hz: 20
max_time: 30 s
machine:
  initial: a-b
  states:
    a-b: {transitions: [{to: a_b, after: 1 s}]}
    a_b: {transitions: [{to: p, after: 1 s}]}
    p:
      initial: q
      states:
        q: {transitions: [{to: r, after: 1 s}]}
        r: {final: true}
      transitions: [{to: p__q, done: true}]
    p__q: {transitions: [{to: note, after: 1 s}]}
    note: {transitions: [{to: note_, after: 1 s}]}
    note_: {final: succeeded}
"""
    m = load_mission_text(text, "clash.yaml")
    mer, dot = to_mermaid(m), to_dot(m)
    declared = re.findall(r'state "[^"]*" as (\S+)', mer)
    assert len(declared) == len(set(declared)) == len(m.states) == 8
    assert declared[:2] == ["a_b", "a_b_2"] and "p__q_2" in declared and declared[-2:] == ["note_", "note__2"]
    assert len(_nodes(dot)) == len(set(_nodes(dot))) == 7 + 2  # 7 leaves, the machine's and p's start nodes
    assert '"a_b" -> "a_b_2" [label="after 1 s"];' in dot
    assert mermaid_errors([mer]) == [None] and dot_errors(dot) is None


def test_a_missing_parser_is_an_error_that_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", "/nonexistent")  # neither node nor dot can be found: fail, never skip
    with pytest.raises(ParserMissing, match="node is not on PATH: install Node.js"):
        mermaid_errors(["stateDiagram-v2\n    [*] --> a\n"])
    with pytest.raises(ParserMissing, match="install graphviz"):
        dot_errors("digraph x {}")


def test_mermaid_ids_that_are_keywords_and_labels_over_several_lines_stay_mermaid() -> None:
    m = load_mission(EVERY_FEATURE)
    mer = to_mermaid(m)
    # states named `note`, `state` and `class` (Mermaid keywords) get a trailing `_`; other ids are the dot ids
    assert '    state "note" as note_\n' in mer and 'state "state [H]" as state_ {' in mer
    assert "    note_ --> class_ : on target_lost when visible #lt; 1 and not (visible #gt;= 2)" in mer
    assert 'state "default [foreach goal in goals] [use lib/part.yaml]" as state__default {' in mer
    # the guard written over three lines is drawn on one
    assert (": (pos_error #lt; $tol or abs(pos_error) #lt;= 2 mm) and not pos_error != 0 m for 0.1 s\n"
            in mer + "\n")
    # nested regions: the inner parallel state's regions are separated inside the outer region
    assert re.search(r'state "inner \[parallel\]" as state__both__watch__inner \{\n(.*\n)+? {20}--\n', mer)
    assert " -> " not in mer and "[style=" not in mer  # no Graphviz inside Mermaid
    assert mer.splitlines()[1] == "    %% mission every_feature #quot;quoted#quot; #123;braces#125; #37;%"
    dot = to_dot(m)
    assert dot.startswith('digraph "every_feature \\"quoted\\" {braces} %%" {')


def _nodes(dot: str) -> dict[str, str]:
    """node id → its attribute text."""
    return dict(re.findall(r'^\s*"([^"]+)" \[(.*)\];$', dot, re.M))


def _edges(dot: str) -> list[tuple[str, str, str]]:
    return re.findall(r'^\s*"([^"]+)" -> "([^"]+)" \[(.*)\];$', dot, re.M)


def _cluster_members(dot: str) -> dict[str, set[str]]:
    """cluster name → every node id declared inside it (nested clusters included)."""
    members: dict[str, set[str]] = {}
    stack: list[str] = []
    for line in dot.splitlines():
        m = re.match(r'\s*subgraph "(cluster_[^"]+)" \{', line)
        if m:
            stack.append(m.group(1))
            members[m.group(1)] = set()
        elif line.strip() == "}" and stack:
            stack.pop()
        else:
            n = re.match(r'^\s*"([^"]+)" \[', line)
            if n:
                for c in stack:
                    members[c].add(n.group(1))
    return members


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.stem)
def test_dot_marks_every_initial_state_and_has_no_stray_nodes(path: Path) -> None:
    m = load_mission(path)
    dot = to_dot(m)
    assert "rankdir=TB" in dot and "compound=true" in dot
    nodes, edges = _nodes(dot), _edges(dot)
    # the only point-shaped nodes are invisible anchors of parallel states; start nodes are filled dots
    for nid, attrs in nodes.items():
        if "shape=point" in attrs:
            assert "style=invis" in attrs and any(start_id(n) == nid for n in m.states.values() if n.parallel)
    composites = [m.root, *(n for n in m.states.values() if n.children and not n.parallel)]
    for node in composites:
        sid = start_id(node)
        assert "style=filled" in nodes[sid] and "fillcolor=black" in nodes[sid]
        first = node.children[node.initial]  # type: ignore[index]
        out = [e for e in edges if e[0] == sid and "weight=10" in e[2]]
        assert len(out) == 1, f"{node.path or 'root'}: one start edge"
        _, head, attrs = out[0]
        if first.children:
            assert head == start_id(first) and f'lhead="cluster_{first.path.replace(".", "__")}"' in attrs
        else:
            assert head == first.path.replace(".", "__")
    # every lhead/ltail names a cluster that holds the edge's end, so dot clips the edge at its border
    members = _cluster_members(dot)
    for tail, head, attrs in edges:
        for key, end in (("lhead", head), ("ltail", tail)):
            mm = re.search(rf'{key}="([^"]+)"', attrs)
            if mm:
                assert end in members[mm.group(1)]
    # one drawn edge per transition (start edges weigh 10; the invisible edges only stack parallel regions)
    drawn = [e for e in edges if "weight=10" not in e[2] and "style=invis" not in e[2]]
    assert len(drawn) == len(m.transitions)


def test_dot_labels_are_wrapped_so_wide_machines_stay_narrow() -> None:
    dot = to_dot(load_mission(ROOT / "missions" / "screw_fastening.yaml"))
    labels = re.findall(r'label="([^"]*)"', dot)
    longest_word = max(len(w) for lab in labels for w in lab.replace("\\n", " ").split())
    assert max(len(line) for lab in labels for line in lab.split("\\n")) <= max(WRAP, longest_word)
    assert "ee_error.t < $eps_t and\\nee_error.r <= $eps_r" in dot


def test_the_screw_graph_is_at_most_2000_px_wide() -> None:
    # 5,554 px before the top-to-bottom layout; 1,196 px for the machine without its safety region; the
    # operation and safety regions (parallel) now stack top to bottom: 1,841 px (side by side: 2,207 px); with s5's
    # slip retried (an edge s5 → retract_to_retry, issue 25) 2,040 px at nodesep 0.3, 1,981 px at 0.25
    svg = subprocess.run(["dot", "-Tsvg"], input=to_dot(load_mission(ROOT / "missions" / "screw_fastening.yaml")),
                         capture_output=True, text=True, check=True).stdout
    width = float(re.search(r'<svg width="([\d.]+)pt"', svg).group(1))  # type: ignore[union-attr]
    assert width * 4 / 3 <= 2000


def test_parallel_states_get_an_invisible_anchor_and_each_region_its_start() -> None:
    m = load_mission(REGIONS)
    dot = to_dot(m)
    nodes = _nodes(dot)
    assert "style=invis" in nodes["__start__work"]
    for region in ("work__drive", "work__watch"):
        assert "fillcolor=black" in nodes[f"__start__{region}"]
    assert 'label="watch (region: commands\\nnothing)";' in dot.replace(" labeljust=l;", "")  # wrapped
    assert 'label="drive (region: v)";' in dot.replace(" labeljust=l;", "")
    mer = to_mermaid(m)
    assert "state work__drive {" not in mer and "\n        --\n" in mer
    assert " -> " not in mer  # regions are stacked in dot only: Mermaid has no invisible edges


def _decode(text: str) -> str:
    names = {"lt": "<", "gt": ">", "quot": '"'}
    return re.sub(r"#(\w+);", lambda mm: names.get(mm.group(1)) or chr(int(mm.group(1))), text)


@pytest.mark.parametrize("path", MISSIONS + [EVERY_FEATURE], ids=lambda p: p.stem)
def test_mermaid_labels_render_as_written(path: Path) -> None:
    m = load_mission(path)
    mer = to_mermaid(m)
    assert "&lt;" not in mer and "&gt;" not in mer and "&amp;" not in mer
    arrows = [line for line in mer.splitlines() if " --> " in line and " : " in line]
    assert [_decode(a.split(" : ", 1)[1]) for a in arrows] == [" ".join(t.label.split()) for t in m.transitions]
    for a in arrows:
        bare = re.sub(r"#\w+;", "", a.split(" : ", 1)[1])  # what is left once every entity code is taken out
        assert not set("<>:;#\"{}") & set(bare)


def test_mermaid_text_escapes_with_entity_codes() -> None:
    assert mermaid_text('a < 2 px: "x" #1') == "a #lt; 2 px#58; #quot;x#quot; #35;1"
    assert mermaid_text("[[fork]] 5 %%\n\tb", quoted=True) == "#91;[fork#93;] 5 #37;%  b".replace("  ", " ")
    assert _decode(mermaid_text("[[fork]] %%{init}")) == "[[fork]] %%{init}"
