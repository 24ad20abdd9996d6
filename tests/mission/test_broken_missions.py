"""The broken-mission corpus: every file in ``tests/broken/`` has exactly one thing wrong.

Each file starts with an expectation comment::

    # expect: line=12 col=7 message="unknown task 'toy_gotoo'" hint="did you mean 'toy_goto'"

``line`` (``a|b`` accepts either) and ``col`` are those of the first problem reported; ``message``
and ``hint`` are fragments of its message and hint; ``absent`` is a fragment the message must NOT
contain; ``xfail="why"`` marks a known loader bug (strict: the test fails once the bug is fixed, so
the marker gets removed).  A ``# <-- here`` comment marks the line the problem should point at.

Loading must raise :class:`MissionError` and nothing else.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from taskflow.errors import MissionError, Problem
from taskflow.mission.loader import load_mission, load_mission_text

BROKEN = Path(__file__).parents[1] / "broken"
TOY = Path(__file__).parents[1] / "machine" / "missions" / "toy_full.yaml"
_PAIR = re.compile(r'(\w+)=(?:"((?:[^"\\]|\\.)*)"|(\S+))')


def parse_expect(path: Path) -> dict[str, str]:
    first = path.read_text(encoding="utf-8", errors="replace").splitlines()[0]
    assert first.startswith("# expect:"), f"{path.name}: first line must be '# expect: ...'"
    out = {m.group(1): (m.group(2) if m.group(2) is not None else m.group(3)) for m in _PAIR.finditer(first[9:])}
    assert "line" in out, f"{path.name}: the expectation needs line="
    return out


def _cases() -> list:
    params = []
    for path in sorted(BROKEN.glob("*.yaml")):
        exp = parse_expect(path)
        marks = [pytest.mark.xfail(strict=True, reason=exp["xfail"])] if "xfail" in exp else []
        params.append(pytest.param(path, exp, id=path.stem, marks=marks))
    return params


def test_corpus_is_big_enough() -> None:
    assert len(list(BROKEN.glob("*.yaml"))) >= 30


@pytest.mark.parametrize("path, exp", _cases())
def test_broken_mission(path: Path, exp: dict[str, str]) -> None:
    try:
        load_mission(path)
    except MissionError as exc:
        err = exc
    else:
        pytest.fail(f"{path.name} loaded without a MissionError")
    assert err.problems, "a MissionError must carry at least one problem"
    p = err.first
    shown = "\n".join(str(q) for q in err.problems)
    assert p.file == str(path), shown
    marked = [i for i, text in enumerate(path.read_text(errors="replace").splitlines(), 1) if "# <-- here" in text]
    assert all(str(i) in exp["line"].split("|") for i in marked), f"{path.name}: '# <-- here' is not on line {exp['line']}"
    assert str(p.line) in exp["line"].split("|"), f"line {p.line}, expected {exp['line']}:\n{shown}"
    if "col" in exp:
        assert p.col == int(exp["col"]), f"col {p.col}, expected {exp['col']}:\n{shown}"
    if "message" in exp:
        assert exp["message"] in p.message, shown
    if "hint" in exp:
        assert exp["hint"] in p.hint, shown
    if "absent" in exp:
        assert exp["absent"] not in p.message, shown
    # the printed form is FILE:LINE:COL: message — hint
    assert str(p).startswith(f"{path}:{p.line}:{p.col}: {p.message}")


# -- inputs that are not a readable mission file ---------------------------------------------------


def _only_problem(exc: pytest.ExceptionInfo[MissionError]) -> Problem:
    assert len(exc.value.problems) == 1
    return exc.value.first


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(MissionError) as exc:
        load_mission(tmp_path / "nope.yaml")
    p = _only_problem(exc)
    assert p.message == "no such file" and "nope.yaml" in str(p)


def test_directory(tmp_path: Path) -> None:
    with pytest.raises(MissionError) as exc:
        load_mission(tmp_path)
    assert "is a directory" in _only_problem(exc).message


def test_not_utf8(tmp_path: Path) -> None:
    f = tmp_path / "latin1.yaml"
    f.write_bytes(TOY.read_bytes().replace(b"mission: toy_full", "mission: toy_f\u00fcll".encode("latin-1")))
    with pytest.raises(MissionError) as exc:
        load_mission(f)
    p = _only_problem(exc)
    assert "not UTF-8" in p.message and "UTF-8" in p.hint


@pytest.mark.parametrize("content", [b"", b"\n\n", b"   \n", b"# nothing\n# at all\n"],
                         ids=["zero-bytes", "newlines", "spaces", "comments"])
def test_empty_files(tmp_path: Path, content: bytes) -> None:
    f = tmp_path / "empty.yaml"
    f.write_bytes(content)
    with pytest.raises(MissionError) as exc:
        load_mission(f)
    assert "empty" in _only_problem(exc).message


@pytest.mark.parametrize("text, fragment", [
    ("42\n", "got int"), ("just a string\n", "got str"), ("null\n", "a mission is a mapping"),
    ("---\n", "a mission is a mapping"),
], ids=["int", "str", "null", "empty-document"])
def test_scalar_documents(text: str, fragment: str) -> None:
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "m.yaml")
    assert fragment in exc.value.first.message


def test_two_documents() -> None:
    with pytest.raises(MissionError) as exc:
        load_mission_text(TOY.read_text() + "---\nmission: second\n", "m.yaml")
    p = exc.value.first
    assert "YAML error" in p.message and p.line == len(TOY.read_text().splitlines()) + 1


def test_duplicate_key_is_an_error_at_the_second_key() -> None:
    """PyYAML would keep the last of two equal keys without a word; the loader refuses them."""
    text = TOY.read_text().replace("rate_hz: 20", "rate_hz: 20\nrate_hz: 50")
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "dup.yaml")
    first = exc.value.problems[0]
    line = text.splitlines().index("rate_hz: 50") + 1
    assert (first.line, first.col) == (line, 1)
    assert "duplicate key 'rate_hz'" in first.message and "already given on line" in first.hint


def test_recursive_alias_is_a_mission_error() -> None:
    text = TOY.read_text().replace("goals: [1.0, 2.0, 3.0]", "goals: &g [1.0, *g]")
    with pytest.raises(MissionError):
        load_mission_text(text, "m.yaml")


def test_every_problem_is_reported_at_once() -> None:
    """Two independent problems in different states are both reported, sorted by line."""
    text = (TOY.read_text().replace("to: searching, on: target_lost", "to: searchin, on: target_lost")
            .replace("pos_error < 2 cm", "pos_eror < 2 cm"))
    with pytest.raises(MissionError) as exc:
        load_mission_text(text, "m.yaml")
    msgs = [p.message for p in exc.value.problems]
    assert any("'searchin'" in m for m in msgs) and any("'pos_eror'" in m for m in msgs)
    lines = [p.line for p in exc.value.problems]
    assert lines == sorted(lines)


def test_corpus_files_are_otherwise_valid_yaml_or_meant_to_be_broken() -> None:
    """Guard against a corpus file that is broken in an unintended way: unless the file is about
    YAML itself, it must parse as YAML (so the one thing wrong is the mission, not the syntax)."""
    yaml_cases = {"gap_control_character", "gap_yaml_tag_bad_float", "gap_yaml_tag_bad_bool"}
    for path in BROKEN.glob("*.yaml"):
        if path.stem.startswith("yaml_") or path.stem in yaml_cases:
            continue
        yaml.safe_load(path.read_text())
