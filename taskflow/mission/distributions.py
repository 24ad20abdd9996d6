"""Random world parameters: ``{uniform: [a, b]}``, ``{normal: [mu, sigma]}``, ``{choice: [...]}``,
``{randint: [a, b]}``, ``{signed_uniform: [a, b]}`` (a magnitude uniform in ``[a, b]`` with a random sign: ±[a, b])
anywhere inside a world's ``params``.

A batch is a Monte Carlo campaign: every trial draws its own values from its seed.  Draws go through
one ``numpy.random.Generator`` seeded from the run seed, in document order, so a seed reproduces them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

KINDS = ("uniform", "normal", "choice", "randint", "signed_uniform")


class DistributionError(ValueError):
    def __init__(self, path: tuple[Any, ...], message: str) -> None:
        super().__init__(message)
        self.path = path


def is_distribution(value: Any) -> bool:
    return isinstance(value, dict) and len(value) == 1 and next(iter(value)) in KINDS


def _draw(spec: dict[str, Any], rng: np.random.Generator, path: tuple[Any, ...]) -> Any:
    kind, args = next(iter(spec.items()))
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise DistributionError(path, "choice needs a non-empty list of values")
        return args[int(rng.integers(len(args)))]
    if not (isinstance(args, list) and len(args) == 2 and all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args)):
        raise DistributionError(path, f"{kind} needs two numbers, e.g. {{{kind}: [1.0, 2.0]}}")
    a, b = float(args[0]), float(args[1])
    if kind == "uniform":
        if b < a:
            raise DistributionError(path, f"uniform bounds must be ordered: [{a:g}, {b:g}]")
        return float(rng.uniform(a, b))
    if kind == "signed_uniform":
        if b < a or a < 0:
            raise DistributionError(path, f"signed_uniform draws a magnitude in [a, b] with a random sign: a and b "
                                    f"must be ordered and not negative, got [{a:g}, {b:g}]")
        magnitude = float(rng.uniform(a, b))  # the magnitude first, then the sign: one stream, in document order
        return magnitude if rng.integers(2) else -magnitude
    if kind == "normal":
        if b < 0:
            raise DistributionError(path, f"normal standard deviation must be ≥ 0, got {b:g}")
        return float(rng.normal(a, b))
    if b < a or int(a) != a or int(b) != b:
        raise DistributionError(path, f"randint bounds must be ordered integers: [{a:g}, {b:g}]")
    return int(rng.integers(int(a), int(b) + 1))


def support(spec: dict[str, Any]) -> list[tuple[Any, str]]:
    """Values at the edges of a distribution's support, each with how to say it: a field that accepts
    all of them accepts every draw (for a normal, whose support is unbounded, ±10¹² σ stand in)."""
    kind, args = next(iter(spec.items()))
    if kind == "choice":
        return [(v, f"choice {v!r}") for v in args]
    a, b = float(args[0]), float(args[1])
    if kind == "normal":
        if b == 0.0:
            return [(a, f"normal [{a:g}, 0]")]
        return [(a - 1e12 * b, f"normal [{a:g}, {b:g}] (unbounded: any value)"),
                (a + 1e12 * b, f"normal [{a:g}, {b:g}] (unbounded: any value)")]
    if kind == "randint":
        return [(int(a), f"randint bound {int(a)}"), (int(b), f"randint bound {int(b)}")]
    if kind == "signed_uniform":
        return [(v, f"signed_uniform bound {v:g}") for v in (-b, -a, a, b)]
    return [(a, f"uniform bound {a:g}"), (b, f"uniform bound {b:g}")]


def distributions_in(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[tuple[Any, ...], dict[str, Any]]]:
    """Every distribution inside ``value`` with its path."""
    if is_distribution(value):
        return [(path, value)]
    if isinstance(value, dict):
        return [d for k, v in value.items() for d in distributions_in(v, path + (k,))]
    if isinstance(value, list):
        return [d for i, v in enumerate(value) for d in distributions_in(v, path + (i,))]
    return []


def replaced(value: Any, path: tuple[Any, ...], new: Any) -> Any:
    """A copy of ``value`` with the item at ``path`` replaced by ``new``."""
    if not path:
        return new
    head, rest = path[0], path[1:]
    if isinstance(value, dict):
        return {**value, head: replaced(value[head], rest, new)}
    out = list(value)
    out[head] = replaced(value[head], rest, new)
    return out


def sample(value: Any, rng: np.random.Generator, path: tuple[Any, ...] = ()) -> Any:
    """A copy of ``value`` with every distribution replaced by a draw."""
    if is_distribution(value):
        return _draw(value, rng, path)
    if isinstance(value, dict):
        return {k: sample(v, rng, path + (k,)) for k, v in value.items()}
    if isinstance(value, list):
        return [sample(v, rng, path + (i,)) for i, v in enumerate(value)]
    return value


def world_rng(seed: int) -> np.random.Generator:
    """The generator for world-parameter draws (its own stream, apart from sensor noise)."""
    return np.random.default_rng([seed, 0x5EED])
