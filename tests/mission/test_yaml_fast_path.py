"""The libyaml fast path of :mod:`taskflow.mission.yamlsrc` reads every file exactly as the Python loader does:
the same data and the same line and column for every value (so every position in a message stays true),
and text the Python reader refuses still gets the Python loader's message."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from taskflow.errors import MissionError
from taskflow.mission import yamlsrc
from taskflow.mission.yamlsrc import MissionLoader, SourceMap, _walk, load_yaml_text

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted(p for p in [*ROOT.glob("missions/**/*.yaml"), *ROOT.glob("tests/**/*.yaml")]
               if not p.name.startswith(("yaml_", "gap_yaml", "gap_control", "gap_duplicate"))
               and "node_modules" not in p.parts)  # the diagram test's npm packages (tests/js) are not ours


def _python_reading(text: str) -> tuple[object, dict[tuple[object, ...], tuple[int, int]]]:
    loader = MissionLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None, {}
        smap = SourceMap("f")
        _walk(node, (), smap, [10**6])
        return loader.construct_document(node), smap.marks
    finally:
        loader.dispose()


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_fast_path_reads_every_file_as_the_python_loader(path: Path) -> None:
    text = path.read_text()
    data, marks = _python_reading(text)
    if data is None and not marks:  # an empty document: refused either way
        with pytest.raises(MissionError, match="empty"):
            load_yaml_text(text, "f")
        return
    fast, smap = load_yaml_text(text, "f")
    assert fast == data
    assert smap.marks == marks


def test_text_the_python_reader_refuses_keeps_its_message() -> None:
    with pytest.raises(MissionError) as exc:
        load_yaml_text("mission: a\x07b\n", "f.yaml")
    p = exc.value.first
    assert (p.line, p.col) == (1, 11) and "not allowed in YAML" in p.message, p


def test_a_yaml_error_keeps_the_python_loaders_message_and_position() -> None:
    with pytest.raises(MissionError) as exc:
        load_yaml_text("mission: m\nmachine: {initial: a\n", "f.yaml")
    p = exc.value.first
    assert p.message.startswith("YAML error: expected ',' or '}'") and p.line == 3, p


def test_the_installed_pyyaml_has_libyaml() -> None:
    """The lock installs PyYAML's wheel, which ships libyaml: missions are composed by its C composer."""
    assert yamlsrc.COMPOSER == "libyaml"


@pytest.mark.parametrize("text", ["a: [1, 2, {b: c}]\nd: &x e\nf: *x\n",  # 12 nodes as written: the alias is one
                                  "--- [1, 2]\n--- {a: b, c: d}\n--- [x, y, z]\n",  # 12 over three documents
                                  "a: [1, 2, {b: c}]\nd: &x e\nf: *x\n]\n"])  # 12, then a syntax error
def test_the_node_count_is_exact_around_the_limit(text: str) -> None:
    """The C event count only lets through what is under the limit: the count is the exact one either side."""
    assert not yamlsrc.too_many_nodes(text, 12)
    assert yamlsrc.too_many_nodes(text, 11)
    assert yamlsrc.too_many_nodes(text, 0)


def test_a_document_over_the_node_limit_is_refused_at_one_place(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(yamlsrc, "MAX_NODES", 50)
    with pytest.raises(MissionError) as exc:
        load_yaml_text("s:\n" + "".join(f"  k{i}: {i}\n" for i in range(30)), "f.yaml")
    p = exc.value.first
    assert (p.line, p.col) == (1, 1) and "more than 50 YAML nodes" in p.message, p


@pytest.mark.parametrize("enabled", [True, False])
def test_gc_paused_holds_the_collector_off_and_restores_it(enabled: bool) -> None:
    was = gc.isenabled()
    (gc.enable if enabled else gc.disable)()
    try:
        with yamlsrc.gc_paused():
            assert not gc.isenabled()
        assert gc.isenabled() == enabled
        with pytest.raises(KeyError), yamlsrc.gc_paused():
            raise KeyError("x")
        assert gc.isenabled() == enabled
    finally:
        (gc.enable if was else gc.disable)()
