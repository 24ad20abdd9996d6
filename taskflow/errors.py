"""Errors a mission file can produce, each pinned to a file, line and column."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a mission: where, what, and what would be valid."""

    file: str
    line: int  # 1-based; 0 when unknown
    col: int  # 1-based; 0 when unknown
    message: str
    hint: str = ""
    via: tuple[str, ...] = ()  # where ``file`` was used from (``FILE:LINE:COL``, innermost first): sub-missions

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}:{self.col}" if self.line else f"{self.file}"
        tail = f" — {self.hint}" if self.hint else ""
        used = ", ".join(("used from " if i == 0 else "itself used from ") + v for i, v in enumerate(self.via))
        return f"{where}: {self.message}{tail}" + (f" ({used})" if used else "")


class MissionError(Exception):
    """A mission file that cannot be run; carries every :class:`Problem` found — once each: a problem in a
    sub-mission file used several times (one place of that file, reached through several uses) is kept at its
    first use, so a file used a thousand times through a ladder of uses gives one line, not a thousand."""

    def __init__(self, problems: list[Problem]) -> None:
        seen: set[tuple[object, ...]] = set()
        self.problems = []
        for p in problems:
            key = (p.file, p.line, p.col) if p.via else (p.file, p.line, p.col, p.message, p.hint)
            if key not in seen:
                seen.add(key)
                self.problems.append(p)
        super().__init__("\n".join(str(p) for p in problems))

    @property
    def first(self) -> Problem:
        return self.problems[0]
