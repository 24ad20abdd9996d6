"""Property-based tests of the loader (hypothesis).

Random *mutations* of a valid mission (keys deleted or renamed, values replaced, junk text
inserted) never make :func:`load_mission_text` raise anything but :class:`MissionError`.
"""

from __future__ import annotations

from typing import Any

import yaml
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st
from properties_machines import TOY

from taskflow.errors import MissionError
from taskflow.mission.loader import load_mission_text
from taskflow.mission.yamlsrc import MissionLoader

# -- mutations never escape as anything but MissionError --------------------------------------------

_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml when available: the loader is the slow part
BASE_TEXT = TOY.read_text()
TINY_TEXT = """\
mission: tiny
robot: toy_point
world: toy_line
rate_hz: 10
machine:
  initial: wait
  states:
    wait:
      transitions:
        - {to: done, after: 1 s}
        - {to: wait, on: target_lost}
    done: {final: true}
"""
BASE_DOCS = [yaml.load(t, Loader=MissionLoader) for t in (BASE_TEXT, TINY_TEXT)]

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(max_size=12), st.sampled_from(["$goals", "$goal", "$nope", "1 cm", "3 deg", "-1 s",
                                                           "toy_goto", "operate", "done", ".nan", "{}", "[]"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                      st.dictionaries(st.text(max_size=8), inner, max_size=3)),
                      max_leaves=8)


def _paths(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [path] if path else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, path + (i,))
    return out


def _mutate(doc: Any, data: Any) -> Any:
    import copy

    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        key = path[-1]
        op = data.draw(st.sampled_from(["delete", "rename", "replace", "replace"]))
        if op == "delete":
            del parent[key]
        elif op == "rename" and isinstance(parent, dict):
            new = data.draw(st.one_of(st.text(max_size=10), st.sampled_from(
                ["to", "when", "on", "done", "after", "for", "task", "states", "initial", "final", "history",
                 "foreach", "bind", "params", "name", "in", "as", "action", "transitions", "blend", "resume"])))
            parent[new] = parent.pop(key)
        else:
            parent[key] = data.draw(values)
    return doc


def _load_or_mission_error(text: str) -> None:
    try:
        load_mission_text(text, "mutant.yaml")
    except MissionError as exc:
        assert exc.problems
        for p in exc.problems:
            assert p.file == "mutant.yaml" and p.line >= 0 and p.col >= 0 and p.message
            str(p)


@settings(max_examples=120, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_document_mutations_give_only_mission_errors(data: Any) -> None:
    doc = _mutate(data.draw(st.sampled_from(BASE_DOCS)), data)
    text = yaml.dump(doc, Dumper=_Dumper, sort_keys=False, allow_unicode=True)
    note(text)
    _load_or_mission_error(text)


_printable = st.characters(codec="utf-8", exclude_categories=("Cs",))


@settings(max_examples=120, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_text_mutations_give_only_mission_errors(data: Any) -> None:
    text = data.draw(st.sampled_from([BASE_TEXT, TINY_TEXT]))
    for _ in range(data.draw(st.integers(1, 3))):
        pos = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["insert", "insert", "delete", "yaml"]))
        if op == "insert":
            text = text[:pos] + data.draw(st.text(_printable, min_size=1, max_size=8)) + text[pos:]
        elif op == "delete":
            text = text[:pos] + text[pos + data.draw(st.integers(1, 20)):]
        else:  # YAML punctuation is the likeliest to produce odd structures
            text = text[:pos] + data.draw(st.sampled_from(
                ["[", "]", "{", "}", ":", ": ", "- ", "&a ", "*a", "!!str ", "? ", "|", ">", "'", '"', "#", "\n  ",
                 "\t", "%", "@", "`", "---\n", "...\n", "!!binary ", "!!set ", "!!float "])) + text[pos:]
    note(text)
    _load_or_mission_error(text)


@settings(max_examples=60, deadline=None, database=None)
@given(ch=st.characters(categories=("Cc",), exclude_characters="\t\n\r"), pos=st.integers(0, len(BASE_TEXT)))
def test_control_characters_give_mission_errors(ch: str, pos: int) -> None:
    _load_or_mission_error(BASE_TEXT[:pos] + ch + BASE_TEXT[pos:])
