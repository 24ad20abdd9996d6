"""Statistics a campaign reports: intervals for success rates and means, and tests between two campaigns.

Pure functions of counts and samples (scipy for the distributions).  Every interval is two-sided at
``confidence`` (0.95 unless told).

scipy is imported by the function that needs it, not with this module (``import scipy.stats`` takes seconds,
and ``taskflow batch`` imports this module before its first trial): the intervals call the two special
functions behind ``scipy.stats.norm.ppf`` and ``scipy.stats.t.ppf`` — ``scipy.special.ndtri(q)`` and
``scipy.special.stdtrit(df, q)``, which those return unchanged (``_ppf(q) * scale + loc`` with scale 1, loc 0:
the same float, ``tests/unit/framework/test_stats.py`` checks it) — and only the tests between two campaigns import
``scipy.stats``.

* :func:`wilson_interval` — the Wilson score interval of a binomial proportion (Wilson 1927; Agresti &
  Coull 1998 recommend it over the normal "Wald" interval, which collapses to a point at 0 % and 100 %
  and undercovers for the 10–40 trials robot papers report):
  ``(p̂ + z²/2n ± z·sqrt(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n)``, ``z`` the normal quantile.
* :func:`mean_interval` — Student's t interval of a mean: ``x̄ ± t(n−1)·s/√n`` with ``s`` the sample
  standard deviation (ddof = 1).
* :func:`fisher_exact` — Fisher's exact test of two success counts (two-sided, scipy's convention:
  the tables no more probable than the observed one), exact at any count.
* :func:`two_proportion_z` — the pooled two-proportion z test, the large-sample approximation of the
  same question.
* :func:`mann_whitney` — the Mann–Whitney U test of two samples (two-sided; exact for small samples
  without ties, normal approximation otherwise, as scipy chooses): do the errors of one campaign tend
  to be larger than the other's, without assuming they are normal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def _z(confidence: float) -> float:
    """The two-sided normal quantile: ``scipy.stats.norm.ppf(0.5 + confidence / 2)``."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    from scipy.special import ndtri

    return float(ndtri(0.5 + confidence / 2.0))


def _t(confidence: float, df: int) -> float:
    """The two-sided Student t quantile: ``scipy.stats.t.ppf(0.5 + confidence / 2, df)``."""
    from scipy.special import stdtrit

    return float(stdtrit(df, 0.5 + confidence / 2.0))


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval ``(low, high)`` of ``successes`` out of ``n`` trials (``n`` ≥ 1)."""
    if n < 1:
        raise ValueError(f"a proportion needs at least one trial, got n={n}")
    if not 0 <= successes <= n:
        raise ValueError(f"successes must lie in [0, n={n}], got {successes}")
    z = _z(confidence)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n))
    # at 0 and n the interval touches the bound exactly; rounding must not push it past
    return (0.0 if successes == 0 else max(0.0, centre - half), 1.0 if successes == n else min(1.0, centre + half))


@dataclass(frozen=True)
class MeanInterval:
    """A sample's mean with its t interval; ``low``/``high`` are None for a single value (no spread
    to estimate)."""

    mean: float
    low: float | None
    high: float | None
    std: float  # sample standard deviation, ddof = 1 (0 for one value)
    n: int


def mean_interval(values: Sequence[float] | np.ndarray, confidence: float = 0.95) -> MeanInterval:
    """Student's t interval of the mean of ``values`` (at least one finite value)."""
    a = np.asarray(values, dtype=float)
    if a.size < 1 or not np.all(np.isfinite(a)):
        raise ValueError("a mean interval needs at least one value, all finite")
    _z(confidence)
    mean = float(a.mean())
    if a.size == 1:
        return MeanInterval(mean, None, None, 0.0, 1)
    s = float(a.std(ddof=1))
    half = _t(confidence, a.size - 1) * s / math.sqrt(a.size)
    return MeanInterval(mean, mean - half, mean + half, s, int(a.size))


def _check_counts(k1: int, n1: int, k2: int, n2: int) -> None:
    for k, n in ((k1, n1), (k2, n2)):
        if n < 1 or not 0 <= k <= n:
            raise ValueError(f"need 0 <= successes <= trials and trials >= 1, got {k} of {n}")


def fisher_exact(k1: int, n1: int, k2: int, n2: int) -> float:
    """Two-sided p-value of Fisher's exact test: ``k1`` of ``n1`` against ``k2`` of ``n2`` successes."""
    from scipy.stats import fisher_exact as _fisher

    _check_counts(k1, n1, k2, n2)
    return float(_fisher([[k1, n1 - k1], [k2, n2 - k2]], alternative="two-sided").pvalue)


def two_proportion_z(k1: int, n1: int, k2: int, n2: int) -> tuple[float, float]:
    """``(z, p)`` of the pooled two-proportion z test (two-sided); ``z`` > 0 when the first rate is higher.
    Both rates 0 or both 1: no evidence of a difference, ``(0, 1)``."""
    _check_counts(k1, n1, k2, n2)
    pooled = (k1 + k2) / (n1 + n2)
    se = math.sqrt(pooled * (1.0 - pooled) * (1.0 / n1 + 1.0 / n2))
    if se == 0.0:
        return 0.0, 1.0
    z = (k1 / n1 - k2 / n2) / se
    from scipy.special import ndtr  # scipy.stats.norm.sf(x) is ndtr(-x)

    return z, float(2.0 * ndtr(-abs(z)))


def mann_whitney(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """``(U, p)`` of the two-sided Mann–Whitney U test; ``U`` is the first sample's statistic (the number
    of pairs in which its value is the larger, ties counting one half)."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.size < 1 or y.size < 1 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("the Mann-Whitney test needs at least one finite value in each sample")
    if np.ptp(np.concatenate([x, y])) == 0.0:
        return x.size * y.size / 2.0, 1.0  # every value equal: nothing to tell apart (scipy returns nan)
    from scipy.stats import mannwhitneyu

    res = mannwhitneyu(x, y, alternative="two-sided")
    return float(res.statistic), float(res.pvalue)
