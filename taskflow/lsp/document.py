"""Where things are in a mission's text, for the language server: every node of the YAML document with the
span of its key and its value (:class:`DocumentIndex`, from the composed node tree), and what the cursor is
in even when the text does not parse (:func:`cursor_at`, from the lines around it).

Positions here are 0-based lines and code points, as PyYAML's marks count them; the server converts them to
the client's units (UTF-16 by default) at the protocol boundary.  A :class:`~taskflow.errors.Problem`'s
1-based line and column name the start of a key or a value, so :meth:`DocumentIndex.span_of_problem` finds
the node that starts there and gives its whole extent.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from taskflow.mission.model import YPath
from taskflow.mission.yamlsrc import MAX_BYTES, MAX_NODES, compose_text, too_many_nodes


@dataclass(frozen=True, order=True)
class Span:
    """A range of text: 0-based start and end (exclusive) line and column, in code points."""

    line: int
    col: int
    end_line: int
    end_col: int

    def contains(self, line: int, col: int) -> bool:
        return (self.line, self.col) <= (line, col) <= (self.end_line, self.end_col)

    @staticmethod
    def of(node: yaml.Node) -> Span:
        return Span(node.start_mark.line, node.start_mark.column, node.end_mark.line, node.end_mark.column)


@dataclass(frozen=True)
class Entry:
    """One node of the document: its path, the span of its key (None for a list item or the root), the span
    of its value, its kind and, for a scalar, its text as written (after YAML's unquoting)."""

    path: YPath
    key: Span | None
    value: Span
    kind: str  # "scalar" | "mapping" | "sequence"
    text: str | None = None


@dataclass
class DocumentIndex:
    """Every node of one YAML text by path, and by position; ``error`` holds the YAML error when the text
    does not compose (then the index is empty and :func:`cursor_at` is what remains)."""

    text: str
    entries: dict[YPath, Entry] = field(default_factory=dict)
    error: str | None = None

    @classmethod
    def build(cls, text: str) -> DocumentIndex:
        index = cls(text)
        if len(text) > MAX_BYTES or too_many_nodes(text, MAX_NODES):
            index.error = "too big to index"  # the loader refuses it with its own message
            return index
        try:
            node = compose_text(text)
        except (yaml.YAMLError, ValueError, TypeError, RecursionError) as exc:
            index.error = str(exc)
            return index
        if node is not None:
            index._walk(node)
        return index

    @classmethod
    def of_node(cls, text: str, node: yaml.Node) -> DocumentIndex:
        """The index of ``text`` whose node tree ``node`` is already composed (by the loader)."""
        index = cls(text)
        index._walk(node)
        return index

    def _walk(self, root: yaml.Node) -> None:
        """Every node under ``root`` (depth first, no recursion: a deeply nested text is fine), at most
        :data:`~taskflow.mission.yamlsrc.MAX_NODES` of them and 32 path elements a node on average (a 10,000-state
        machine needs about 15; a text nested tens of thousands deep would need gigabytes); an alias's node is
        indexed where it first appears."""
        stack: list[tuple[yaml.Node, YPath, Span | None]] = [(root, (), None)]
        budget = MAX_NODES
        cells = 32 * MAX_NODES  # path elements kept: a text nested thousands deep would need depth² of them
        while stack and budget > 0 and cells > 0:
            node, path, key = stack.pop()
            budget -= 1
            cells -= len(path)
            if path in self.entries:
                continue
            if isinstance(node, yaml.MappingNode):
                self.entries[path] = Entry(path, key, Span.of(node), "mapping")
                for k, v in reversed(node.value):
                    name = k.value if isinstance(k, yaml.ScalarNode) else str(k.value)
                    stack.append((v, path + (name,), Span.of(k)))
            elif isinstance(node, yaml.SequenceNode):
                self.entries[path] = Entry(path, key, Span.of(node), "sequence")
                stack.extend((item, path + (i,), None) for i, item in reversed(list(enumerate(node.value))))
            else:
                self.entries[path] = Entry(path, key, Span.of(node), "scalar", str(node.value))

    def get(self, path: YPath) -> Entry | None:
        return self.entries.get(tuple(path))

    def at(self, line: int, col: int) -> tuple[Entry, bool] | None:
        """The innermost node at a position and whether the position is on its key (rather than its value)."""
        best: tuple[Entry, bool] | None = None
        best_len = -1
        for e in self.entries.values():
            for on_key, span in ((True, e.key), (False, e.value)):
                if span is not None and span.contains(line, col) and len(e.path) > best_len:
                    if not on_key and e.kind != "scalar":
                        continue  # a collection's value span holds its children: they are more telling
                    best, best_len = (e, on_key), len(e.path)
        return best

    def span_of_problem(self, line1: int, col1: int) -> Span:
        """The extent of the key or value a problem's 1-based position names: a key with a scalar value on its
        line spans both (``task: toy_gotoo``), a key of a collection its key, a scalar its text; elsewhere the
        word at the position (a YAML error's mark)."""
        if line1 <= 0:
            return Span(0, 0, 0, 0)
        line, col = line1 - 1, col1 - 1
        for e in self.entries.values():
            if e.key is not None and (e.key.line, e.key.col) == (line, col):
                if e.kind == "scalar" and e.value.end_line == line:
                    return Span(line, col, line, e.value.end_col)
                return e.key
        for e in self.entries.values():
            if (e.value.line, e.value.col) == (line, col):
                if e.kind == "scalar" or e.value.end_line == line:
                    return e.value
                return Span(line, col, line, len(self._line(line)))
        return self.word_span(line, col)

    def _line(self, line: int) -> str:
        lines = self.text.split("\n")
        return lines[line] if 0 <= line < len(lines) else ""

    def word_span(self, line: int, col: int) -> Span:
        """The run of non-blank characters from ``col`` (at least one character, within the line)."""
        text = self._line(line)
        end = col
        while end < len(text) and not text[end].isspace() and text[end] not in ",}]":
            end += 1
        return Span(line, col, line, max(end, min(col + 1, len(text))))

    def paths_with_text(self, text: str) -> list[Entry]:
        """Scalar nodes whose text is ``text``."""
        return [e for e in self.entries.values() if e.kind == "scalar" and e.text == text]


# -- the cursor in text that may not parse -------------------------------------------------------------------

_KEY = re.compile(r"(?P<key>[^\s:#{}\[\],'\"][^:#{}\[\],]*?|\"[^\"]*\"|'[^']*')\s*:(?:\s|$)")
_WORD = re.compile(r"[A-Za-z0-9_.$/\-]*$")
_AFTER = re.compile(r"[A-Za-z0-9_.$/\-]*")
_ITEM_MAPPINGS = ("transitions", "properties")
"""Sequences whose items are mappings: a `- ` typed under them starts a key (else a value: `exits`, `in`)."""


@dataclass(frozen=True)
class Cursor:
    """What the cursor is in: the path of the mapping or value around it (keys, and list indices: -1 where
    the item could not be counted), whether a key or a value is being typed there, the text typed so far of
    the word at the cursor (``prefix``; ``span`` covers the whole word, for a completion that replaces it),
    and the value typed so far when a value is typed (``value``)."""

    path: YPath
    role: str  # "key" | "value"
    prefix: str
    span: Span
    value: str = ""

    @property
    def key(self) -> Any:
        """The key whose value is typed (role "value"), or the mapping's last key."""
        return self.path[-1] if self.path else None

    def keys(self) -> tuple[str, ...]:
        """The path without list indices."""
        return tuple(p for p in self.path if isinstance(p, str))


@dataclass(frozen=True)
class _Line:
    indent: int  # column of the first character
    dashes: int  # `- ` markers before the key or value
    key_col: int  # column after the dashes
    key: str | None  # a block key on the line (`key:`), if any


def _strip_comment(line: str) -> str:
    out, quote = [], ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            break
        out.append(ch)
    return "".join(out)


def _key_text(raw: str) -> str:
    raw = raw.strip()
    return raw[1:-1] if len(raw) >= 2 and raw[0] == raw[-1] and raw[0] in "\"'" else raw


def _parse_line(raw: str) -> _Line | None:
    text = _strip_comment(raw).rstrip()
    if not text.strip() or text.lstrip().startswith("---"):
        return None
    indent = len(text) - len(text.lstrip())
    rest = text[indent:]
    dashes = 0
    while rest.startswith("-") and (len(rest) == 1 or rest[1].isspace()):
        dashes += 1
        stripped = rest[1:].lstrip()
        rest = stripped
    key_col = len(text) - len(rest)
    m = _KEY.match(rest)
    return _Line(indent, dashes, key_col, _key_text(m.group("key")) if m else None)


def _block_parents(lines: list[str], line: int, want: int, item_at: int | None = None) -> YPath:
    """The keys and list indices of the block collections that hold something at column ``want`` on ``line``
    (``item_at``: the line itself starts an item of a sequence whose dashes are at that column)."""
    path: list[Any] = []
    counting: tuple[int, int] | None = None  # (column of a sequence's dashes, index in `path` of its item)
    seq_col: int | None = None  # the current mapping is an item of a sequence at this column
    if item_at is not None:
        path.append(0)
        counting, seq_col, want = (item_at, 0), item_at, item_at
    for i in range(line - 1, -1, -1):
        ln = _parse_line(lines[i])
        if ln is None:
            continue
        if counting is not None and ln.dashes and ln.indent == counting[0]:
            path[counting[1]] += 1  # an earlier item of the same sequence
            if ln.key_col >= want:
                continue
        if ln.key_col == want and ln.dashes and seq_col is None:
            path.append(0)  # a sibling key on the item's first line: the cursor is in that item
            counting = (ln.indent, len(path) - 1)
            seq_col, want = ln.indent, ln.indent
            continue
        parent = ln.key_col < want or (seq_col is not None and ln.indent == seq_col and not ln.dashes)
        if not parent:
            continue
        if ln.key is not None and (ln.key_col < want or not ln.dashes):
            path.append(ln.key)
            counting, seq_col = None, None
        if ln.dashes:
            for _ in range(ln.dashes):
                path.append(0)
            counting = (ln.indent, len(path) - 1)
            seq_col, want = ln.indent, ln.indent
            continue
        want = ln.indent
        if want == 0:
            break
    return tuple(reversed(path))


def _flow_context(text: str) -> tuple[list[tuple[str, str]], str] | None:
    """Inside a flow collection: the stack of (opener, key written before it) and the text of the innermost
    collection after its last comma; None when ``text`` closes every collection it opens."""
    stack: list[tuple[str, str]] = []
    quote = ""
    seg_start = 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "{[":
            before = text[seg_start:i]
            key = before.rsplit(":", 1)[0] if ":" in before else ""
            stack.append((ch, _key_text(key)))
            seg_start = i + 1
        elif ch in "}]" and stack:
            stack.pop()
            seg_start = i + 1
        elif ch == "," and stack:
            seg_start = i + 1
    if not stack:
        return None
    return stack, text[seg_start:]


def cursor_at(text: str, line: int, col: int) -> Cursor:
    """What the cursor at (``line``, ``col``) is in, read from the lines above it: works on text that does not
    parse (half-typed), block and flow style alike."""
    lines = text.split("\n")
    current = lines[line] if 0 <= line < len(lines) else ""
    col = max(0, min(col, len(current)))
    before = current[:col]
    word = _WORD.search(before)
    prefix = word.group(0) if word else ""
    after = _AFTER.match(current, col)
    span = Span(line, col - len(prefix), line, col + (len(after.group(0)) if after else 0))
    ln = _parse_line(before + "x")  # the `x` stands for what is typed next, so a blank line has a column
    if ln is None:  # inside a comment (or a `---`): the cursor is in no key or value
        return Cursor((), "comment", prefix, span)
    if ln.dashes:
        path = list(_block_parents(lines, line, ln.indent, item_at=ln.indent)) + [0] * (ln.dashes - 1)
    else:
        path = list(_block_parents(lines, line, ln.key_col))
    rest = before[ln.key_col:]
    flow = _flow_context(rest)
    if flow is not None:
        stack, segment = flow
        for opener, key in stack:
            if key:
                path.append(key)
            if opener == "[":
                path.append(-1)
        if stack[-1][0] == "{" and ":" in segment:
            k, _, v = segment.partition(":")
            return Cursor(tuple(path) + (_key_text(k),), "value", prefix, span, v.lstrip())
        if stack[-1][0] == "[":
            return Cursor(tuple(path), "value", prefix, span, segment.lstrip())
        return Cursor(tuple(path), "key", prefix, span)
    m = _KEY.match(rest)
    if m is not None:
        return Cursor(tuple(path) + (_key_text(m.group("key")),), "value", prefix, span, rest[m.end():].lstrip())
    keys = [p for p in path if isinstance(p, str)]
    if ln.dashes and not (keys and keys[-1] in _ITEM_MAPPINGS):
        return Cursor(tuple(path), "value", prefix, span, rest.lstrip())
    return Cursor(tuple(path), "key", prefix, span)
