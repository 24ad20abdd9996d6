"""What a check of ``taskflow verify`` answers: its verdict, in words, with a counterexample when it fails."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from taskflow.verify.counterexample import Counterexample

__all__ = ["FAILS", "HOLDS", "MONITORED", "CheckResult"]

HOLDS, FAILS = "holds", "fails"
MONITORED = "monitored"
"""The verdict of a property that compares metrics: the model cannot decide it; every run's monitor does."""


@dataclass
class CheckResult:
    """One check's verdict (``holds`` | ``fails``), in words, with a counterexample when it fails."""

    name: str
    verdict: str
    detail: str
    counterexample: Counterexample | None = None
    seconds: float = 0.0
    data: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "verdict": self.verdict, "detail": self.detail, "seconds": round(self.seconds, 4),
                **({"counterexample": self.counterexample.as_dict()} if self.counterexample is not None else {}),
                **self.data}
