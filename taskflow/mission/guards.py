"""Guard expressions: parsed once when the mission loads, compiled to closures, never ``eval``-ed.

Grammar (keywords are lower case)::

    expr       := and_expr ("or" and_expr)*
    and_expr   := not_expr ("and" not_expr)*
    not_expr   := "not" not_expr | primary
    primary    := "(" expr ")" | comparison
    comparison := operand OP operand              OP: < <= > >= == !=
    operand    := metric | "abs" "(" metric ")" | quantity | "$" parameter
    metric     := NAME ("." NAME)* ["[" INDEX "]"]
    quantity   := NUMBER [UNIT]                   e.g. 2 px, 1 cm, 3 deg, 0.5 m/s

A property's expression (:mod:`taskflow.mission.properties`, parsed with ``atoms=True``) may also use
three atoms a transition's guard may not::

    primary    := ... | atom
    atom       := ("state" | "event" | "outcome") "(" NAME ("." NAME)* ")"

``state(operate.screw)`` holds while that state is active (a leaf, or an ancestor of an active leaf),
``event(target_lost)`` in the tick the event arrives, ``outcome(failed)`` once the run ended with it.

Parentheses and ``not`` nest at most :data:`MAX_DEPTH` levels deep (a deeper guard is a load-time
error, not a stack overflow).

Examples: ``feature_error < 2 px``, ``pos_error < 1 cm and yaw_error < 2 deg``,
``abs(lateral_error) <= $eps_t``.  A quantity is converted to the SI base unit of the metric it
is compared with; comparing a length metric with ``3 deg`` is a load-time error.  A comparison whose
metric has no value this tick is false.

A metric named ``data.<key>`` reads the run's mission data instead of the tick's metrics
(:mod:`taskflow.mission.data`): a scalar key as a number, a flag as 1 (true) or 0 (false), and component ``i`` of
a 1-D array key as ``data.<key>[i]`` (``data.viki.object[0] < 2 m``); the key's declared unit converts
the quantity.  Which names exist is the loader's business (it passes them with their units); a key
with no value yet compares false, as a missing metric does.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, cast

from taskflow.units import BASE_UNIT_OF, UNITS, dimension
from taskflow.units import with_article as _a

Metrics = Mapping[str, float]
Data = Mapping[str, Any]
Predicate = Callable[[Metrics, Data], bool]
"""``pred(metrics, data)``: the tick's metrics and the run's mission data values."""

DATA_PREFIX = "data."


class GuardSyntaxError(ValueError):
    """A guard that does not parse; ``offset`` is the character position in the expression."""

    def __init__(self, message: str, offset: int, hint: str = "") -> None:
        super().__init__(message)
        self.offset, self.hint = offset, hint


_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
    r"|(?P<op><=|>=|==|!=|<|>)"
    r"|(?P<par>[()])"
    r"|(?P<param>\$[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<unit>(?:deg|rad|cm|mm|m|px|ms|s|min|N|Nm)/s|%)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*(?:\[\d+\])?)"
    r"|(?P<neg>-))"
)
_OPS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge, "==": operator.eq, "!=": operator.ne,
}
_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}
KEYWORDS = {"and", "or", "not", "abs"}
ATOM_KINDS = ("state", "event", "outcome")
"""The atoms of a property's expression (``state(PATH)``, ``event(NAME)``, ``outcome(NAME)``)."""
MAX_DEPTH = 32
"""Deepest nesting of parentheses and ``not`` a guard may have."""


@dataclass
class Comparison:
    metric: str
    absolute: bool
    op: str
    value: float | None  # base units; None when taken from a parameter
    unit: str | None  # unit as written (None: from parameter)
    param: str | None
    offset: int


@dataclass
class Atom:
    """``state(PATH)``, ``event(NAME)`` or ``outcome(NAME)`` in a property's expression."""

    kind: str  # one of ATOM_KINDS
    name: str
    offset: int

    @property
    def text(self) -> str:
        return f"{self.kind}({self.name})"


@dataclass
class Node:
    kind: str  # "and" | "or" | "not" | "cmp" | "atom"
    children: list[Node] = field(default_factory=list)
    cmp: Comparison | None = None
    atom: Atom | None = None


@dataclass
class Guard:
    """A parsed guard: its tree, the metrics it reads and the parameters it references."""

    text: str
    tree: Node

    def comparisons(self) -> list[Comparison]:
        out: list[Comparison] = []

        def visit(n: Node) -> None:
            if n.cmp is not None:
                out.append(n.cmp)
            for c in n.children:
                visit(c)

        visit(self.tree)
        return out

    def atoms(self) -> list[Atom]:
        """Its ``state``/``event``/``outcome`` atoms in the order written (none in a transition's guard)."""
        out: list[Atom] = []

        def visit(n: Node) -> None:
            if n.atom is not None:
                out.append(n.atom)
            for c in n.children:
                visit(c)

        visit(self.tree)
        return out

    @property
    def metrics(self) -> set[str]:
        """The tick metrics it reads (``data.…`` names excluded)."""
        return {c.metric for c in self.comparisons() if not c.metric.startswith(DATA_PREFIX)}

    @property
    def data(self) -> set[str]:
        """The mission-data keys it reads (without ``data.`` and any ``[i]``)."""
        return {_data_key(c.metric)[0] for c in self.comparisons() if c.metric.startswith(DATA_PREFIX)}


def _data_key(name: str) -> tuple[str, int | None]:
    """``data.viki.object[1]`` → (``viki.object``, 1); ``data.count`` → (``count``, None)."""
    key = name[len(DATA_PREFIX):]
    if key.endswith("]"):
        key, index = key[:-1].split("[")
        return key, int(index)
    return key, None


def _tokenize(text: str) -> list[tuple[str, str, int]]:
    toks: list[tuple[str, str, int]] = []
    pos = 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            bad = text[pos:].lstrip()
            at = len(text) - len(bad)
            raise GuardSyntaxError(f"unexpected character {bad[0]!r}", at,
                                   "write comparisons like 'pos_error < 1 cm' joined by and/or/not")
        kind = m.lastgroup or ""
        toks.append((kind, m.group(kind), m.start(kind)))
        pos = m.end()
    return toks


class _Parser:
    def __init__(self, text: str, atoms: bool = False) -> None:
        self.text = text
        self.atoms = atoms
        self.toks = _tokenize(text)
        self.i = 0
        self.depth = 0

    def deeper(self, offset: int) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise GuardSyntaxError(f"the guard nests parentheses and 'not' more than {MAX_DEPTH} levels deep", offset,
                                   f"at most {MAX_DEPTH} levels; simplify the expression")

    def peek(self) -> tuple[str, str, int] | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self) -> tuple[str, str, int]:
        tok = self.peek()
        if tok is None:
            raise GuardSyntaxError("the expression ends too early", len(self.text), "complete the comparison")
        self.i += 1
        return tok

    def is_word(self, word: str) -> bool:
        t = self.peek()
        return t is not None and t[0] == "name" and t[1] == word

    def parse(self) -> Node:
        if not self.toks:
            raise GuardSyntaxError("empty guard", 0, "write e.g. 'feature_error < 2 px'")
        node = self.expr()
        rest = self.peek()
        if rest is not None:
            raise GuardSyntaxError(f"unexpected {rest[1]!r}", rest[2], "join comparisons with 'and' / 'or'")
        return node

    def expr(self) -> Node:
        return self.chain("or", self.and_expr)

    def and_expr(self) -> Node:
        return self.chain("and", self.not_expr)

    def chain(self, word: str, operand: Callable[[], Node]) -> Node:
        """``operand (word operand)*``: one operand, or a ``word`` node of them all."""
        parts = [operand()]
        while self.is_word(word):
            self.take()
            parts.append(operand())
        return parts[0] if len(parts) == 1 else Node(word, parts)

    def not_expr(self) -> Node:
        if self.is_word("not"):
            self.deeper(self.take()[2])
            node = Node("not", [self.not_expr()])
            self.depth -= 1
            return node
        return self.primary()

    def primary(self) -> Node:
        tok = self.peek()
        if tok is not None and tok[0] == "par" and tok[1] == "(":
            self.deeper(self.take()[2])
            node = self.expr()
            close = self.take()
            if close[1] != ")":
                raise GuardSyntaxError(f"expected ')' but found {close[1]!r}", close[2])
            self.depth -= 1
            return node
        if tok is not None and tok[0] == "name" and tok[1] in ATOM_KINDS and self.i + 1 < len(self.toks) \
                and self.toks[self.i + 1][1] == "(":
            return self.atom()
        return self.comparison()

    def atom(self) -> Node:
        """``state(PATH)`` / ``event(NAME)`` / ``outcome(NAME)``: only in a property's expression."""
        _, kind, off = self.take()
        if not self.atoms:
            raise GuardSyntaxError(f"{kind}( ) is an atom of a mission property, not of a transition's guard", off,
                                   "a guard compares metrics (e.g. 'pos_error < 1 cm'); use `on: EVENT` for an event")
        self.take()  # "("
        k2, name, o2 = self.take()
        if k2 != "name" or name in KEYWORDS or name.endswith("]"):
            raise GuardSyntaxError(f"{kind}( ) takes a name", o2, f"write e.g. '{kind}(NAME)'")
        close = self.take()
        if close[1] != ")":
            raise GuardSyntaxError(f"expected ')' after {kind}({name}", close[2])
        return Node("atom", atom=Atom(kind, name, off))

    def operand(self) -> tuple[str, object, int]:
        """('metric', (name, abs), off) | ('qty', (value, unit), off) | ('param', name, off)."""
        kind, val, off = self.take()
        if kind == "neg":
            k2, v2, o2 = self.take()
            if k2 != "num":
                raise GuardSyntaxError("'-' must be followed by a number", o2)
            kind, val = "num", "-" + v2
        if kind == "num":
            unit = ""
            nxt = self.peek()
            if nxt is not None and nxt[0] in ("name", "unit") and nxt[1] not in KEYWORDS:
                unit = nxt[1]
                if unit not in UNITS:
                    raise GuardSyntaxError(f"unknown unit {unit!r}", nxt[2], "valid units: " + ", ".join(u for u in UNITS if u))
                self.take()
            return "qty", (float(val), unit), off
        if kind == "param":
            return "param", val[1:], off
        if kind == "name" and val == "abs":
            p = self.take()
            if p[1] != "(":
                raise GuardSyntaxError("abs must be followed by '('", p[2])
            k2, name, o2 = self.take()
            if k2 != "name" or name in KEYWORDS:
                raise GuardSyntaxError("abs( ) takes a metric name", o2)
            p = self.take()
            if p[1] != ")":
                raise GuardSyntaxError("expected ')' after the metric", p[2])
            return "metric", (name, True), off
        if kind == "name" and val not in KEYWORDS:
            return "metric", (val, False), off
        raise GuardSyntaxError(f"unexpected {val!r}", off, "a comparison starts with a metric name or a number")

    def comparison(self) -> Node:
        left = self.operand()
        optok = self.take()
        if optok[0] != "op":
            raise GuardSyntaxError(f"expected a comparison operator (<, <=, >, >=, ==, !=) but found {optok[1]!r}", optok[2])
        right = self.operand()
        op = optok[1]
        if left[0] != "metric" and right[0] == "metric":
            left, right, op = right, left, _FLIP[op]
        if left[0] != "metric" or right[0] == "metric":
            raise GuardSyntaxError("a comparison needs exactly one metric and one value", left[2],
                                   "write e.g. 'pos_error < 1 cm'")
        name, absolute = cast(tuple[str, bool], left[1])  # operand(): a metric's value is (name, abs)
        if right[0] == "param":
            cmp = Comparison(name, absolute, op, None, None, cast(str, right[1]), left[2])
        else:
            value, unit = cast(tuple[float, str], right[1])  # operand(): a quantity's value is (value, unit)
            cmp = Comparison(name, absolute, op, value, unit, None, left[2])
        return Node("cmp", cmp=cmp)


def parse_guard(text: str, *, atoms: bool = False) -> Guard:
    """Parse ``text``; raises :class:`GuardSyntaxError` with the offending offset.  ``atoms`` admits the
    ``state()``/``event()``/``outcome()`` atoms of a property's expression (never a transition's guard)."""
    return Guard(text, _Parser(text, atoms).parse())


def bind_units(guard: Guard, metric_units: Mapping[str, str], params: Mapping[str, tuple[float, str]],
               skip: set[str] | frozenset[str] = frozenset()) -> list[str]:
    """Convert every quantity to its metric's base unit; return a list of problems (empty: fine).

    ``metric_units`` maps metric → declared base unit; ``params`` maps parameter → (base value,
    dimension) for ``$name`` operands; parameters in ``skip`` are reported by the caller.
    """
    problems: list[str] = []
    for c in guard.comparisons():
        unit = metric_units.get(c.metric)
        if unit is None or (c.param is not None and c.param in skip):
            continue  # unknown metrics are reported by the loader with the valid names
        want = dimension(unit)
        if c.param is not None:
            if c.param not in params:
                problems.append(f"unknown parameter ${c.param} — valid: {', '.join('$' + p for p in sorted(params)) or '(none)'}")
                continue
            value, dim = params[c.param]
            if dim != want:
                problems.append(f"${c.param} is {_a(dim)}, but {c.metric} is {_a(want)} (in {unit or 'no unit'})")
                continue
            c.value = value
            continue
        assert c.unit is not None and c.value is not None
        have = dimension(c.unit)
        if have != want:
            if c.unit == "":
                problems.append(f"{c.value:g} needs a unit: {c.metric} is {_a(want)} — write e.g. '{c.value:g} {BASE_UNIT_OF[want]}'")
            else:
                problems.append(f"'{c.value:g} {c.unit}' is {_a(have)}, but {c.metric} is {_a(want)} — use {_a(want)} unit such as {BASE_UNIT_OF[want]!r}")
            continue
        c.value = c.value * UNITS[c.unit][1]
        c.unit = BASE_UNIT_OF[want]
    return problems


def never_holds(c: Comparison, low: float | None, high: float | None) -> bool:
    """Whether no value of a metric in ``[low, high]`` (None: unbounded) satisfies the bound comparison
    ``c`` (its value in base units).  ``abs(metric)`` ranges over ``[0, ...]``: ``abs(x) < 0`` never holds
    whatever the metric's declared range."""
    if c.value is None:
        return False
    if c.absolute:
        lo_mag = 0.0 if low is None or high is None or low <= 0.0 <= high else min(abs(low), abs(high))
        hi_mag = None if low is None or high is None else max(abs(low), abs(high))
        low, high = lo_mag, hi_mag
    v = float(c.value)
    below = low is not None and (v <= low if c.op == "<" else v < low)  # only values under low would do
    above = high is not None and (v >= high if c.op == ">" else v > high)
    if c.op in ("<", "<="):
        return below
    if c.op in (">", ">="):
        return above
    if c.op == "==":
        return (low is not None and v < low) or (high is not None and v > high)
    return False  # '!=' holds for any other value


def _data_comparison(c: Comparison) -> Predicate:
    """A comparison of a mission-data value: a scalar, a flag (1/0) or one component of an array."""
    assert c.value is not None, "bind_units() must run first"
    fn, (key, index), value, absolute = _OPS[c.op], _data_key(c.metric), float(c.value), c.absolute

    def pred(m: Metrics, d: Data) -> bool:
        x = d.get(key)
        if x is None:
            return False
        x = float(x if index is None else x[index])
        if absolute:
            return not math.isnan(x) and fn(abs(x), value)
        return fn(x, value)

    return pred


def compile_guard(guard: Guard, atom: Callable[[Atom], Predicate] | None = None) -> Predicate:
    """A closure over plain floats: ``pred(metrics, data) -> bool``; missing or NaN metrics compare false.
    ``atom`` gives the predicate of each ``state``/``event``/``outcome`` atom (a property's monitor:
    :mod:`taskflow.execution.monitors`)."""

    def build(n: Node) -> Predicate:
        if n.kind == "atom":
            assert n.atom is not None and atom is not None, "a guard with atoms is compiled with their predicates"
            return atom(n.atom)
        if n.kind == "cmp":
            c = n.cmp
            assert c is not None and c.value is not None, "bind_units() must run first"
            if c.metric.startswith(DATA_PREFIX):
                return _data_comparison(c)
            fn, name, value = _OPS[c.op], c.metric, float(c.value)
            if c.absolute:
                def pred(m: Metrics, d: Data, fn: Callable[[float, float], bool] = fn, name: str = name,
                         value: float = value) -> bool:
                    x = m.get(name)
                    return x is not None and not math.isnan(x) and fn(abs(x), value)
            else:
                def pred(m: Metrics, d: Data, fn: Callable[[float, float], bool] = fn, name: str = name,
                         value: float = value) -> bool:
                    x = m.get(name)
                    return x is not None and fn(x, value)  # NaN compares false except '!='
            return pred
        kids = [build(k) for k in n.children]
        if n.kind == "not":
            k0 = kids[0]
            return lambda m, d: not k0(m, d)
        if n.kind == "and":
            if len(kids) == 2:
                a, b = kids
                return lambda m, d: a(m, d) and b(m, d)
            return lambda m, d: all(k(m, d) for k in kids)
        return lambda m, d: any(k(m, d) for k in kids)

    return build(guard.tree)
