"""Read a YAML mission with the safe loader and remember where every value came from.

The result is the plain Python data plus a map ``path → (line, col)`` (1-based) so that validation
errors can point at the offending key.  Only the safe loader is used: ``!!python/...`` tags are refused.
Aliases are allowed (handy for sharing gains), but a document that expands past ``MAX_NODES`` nodes
(an alias bomb) is refused before anything walks it.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from .errors import MissionError, Problem

Path_ = tuple[Any, ...]
MAX_NODES = 200_000
MAX_BYTES = 5_000_000


class MissionLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` with YAML 1.2 booleans: only ``true``/``false`` are booleans, so
    ``on: target_lost`` keeps its key (YAML 1.1 would read ``on``/``off``/``yes``/``no`` as booleans)."""


MissionLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:bool"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
MissionLoader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))


class SourceMap:
    """Where each value of a loaded document sits in its file."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.marks: dict[Path_, tuple[int, int]] = {}

    def where(self, path: Path_) -> tuple[int, int]:
        """Line and column of ``path``, or of its nearest ancestor that has a mark."""
        p = tuple(path)
        while p:
            if p + ("__key__",) in self.marks:
                return self.marks[p + ("__key__",)]
            if p in self.marks:
                return self.marks[p]
            p = p[:-1]
        return self.marks.get((), (1, 1))

    def problem(self, path: Path_, message: str, hint: str = "") -> Problem:
        line, col = self.where(path)
        return Problem(self.file, line, col, message, hint)


def _walk(node: yaml.Node, path: Path_, smap: SourceMap, budget: list[int]) -> None:
    budget[0] -= 1
    if budget[0] < 0:
        raise _TooBig()
    smap.marks.setdefault(path, (node.start_mark.line + 1, node.start_mark.column + 1))
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else str(key_node.value)
            smap.marks.setdefault(path + (key, "__key__"), (key_node.start_mark.line + 1, key_node.start_mark.column + 1))
            _walk(value_node, path + (key,), smap, budget)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _walk(item, path + (i,), smap, budget)


class _TooBig(Exception):
    pass


def load_yaml_text(text: str, file: str) -> tuple[Any, SourceMap]:
    smap = SourceMap(file)
    if len(text) > MAX_BYTES:
        raise MissionError([Problem(file, 1, 1, f"file is {len(text)} bytes", f"a mission must be under {MAX_BYTES} bytes")])
    loader = MissionLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise MissionError([Problem(file, 1, 1, "the file is empty", "a mission needs at least `mission`, `robot`, `world`, `rate_hz` and `machine`")])
        try:
            _walk(node, (), smap, [MAX_NODES])
        except _TooBig:
            raise MissionError([Problem(file, 1, 1, f"the document expands to more than {MAX_NODES} nodes (alias bomb?)",
                                        "remove the nested aliases")]) from None
        data = loader.construct_document(node)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        what = exc.problem or "malformed YAML"
        hint = exc.context or ""
        if isinstance(exc, yaml.constructor.ConstructorError):
            hint = "only plain YAML is accepted (no !!python tags or custom tags)"
        raise MissionError([Problem(file, line, col, f"YAML error: {what}", hint)]) from None
    except yaml.YAMLError as exc:
        raise MissionError([Problem(file, 1, 1, f"YAML error: {exc}")]) from None
    except RecursionError:
        raise MissionError([Problem(file, 1, 1, "the document nests too deeply")]) from None
    finally:
        loader.dispose()
    return data, smap


def load_yaml_file(path: str | Path) -> tuple[Any, SourceMap, str]:
    """Read ``path``; every I/O problem becomes a :class:`MissionError`, never a traceback."""
    p = Path(path)
    file = str(path)
    if not p.exists():
        raise MissionError([Problem(file, 0, 0, "no such file", "check the path")])
    if p.is_dir():
        raise MissionError([Problem(file, 0, 0, "is a directory, not a mission file", "give a .yaml file")])
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise MissionError([Problem(file, 0, 0, f"cannot read: {exc.strerror or exc}")]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MissionError([Problem(file, 1, 1, f"not UTF-8 text (byte {exc.start})", "save the file as UTF-8")]) from None
    data, smap = load_yaml_text(text, file)
    return data, smap, text
