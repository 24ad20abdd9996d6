"""taskflow.campaigns.stats against hand-computed values and closed forms."""

from __future__ import annotations

import math

import pytest

from taskflow.campaigns.stats import fisher_exact, mann_whitney, mean_interval, two_proportion_z, wilson_interval

Z95 = 1.959963984540054


def test_wilson_interval_matches_the_formula_worked_by_hand() -> None:
    # 8 of 10: p = 0.8, z^2/n = 0.38415; centre 0.99207/1.38415 = 0.71673, half 1.41600 * 0.16001 = 0.22658
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.49016, abs=1e-5) and hi == pytest.approx(0.94332, abs=1e-5)


@pytest.mark.parametrize("n", [1, 5, 12, 40])
def test_wilson_interval_at_none_and_all_has_its_closed_form(n: int) -> None:
    # k = 0: [0, z^2 / (n + z^2)]; k = n: its mirror.  The Wald interval would be the single point 0 or 1.
    edge = Z95 ** 2 / (n + Z95 ** 2)
    assert wilson_interval(0, n) == (0.0, pytest.approx(edge))
    assert wilson_interval(n, n) == (pytest.approx(1.0 - edge), 1.0)


def test_wilson_interval_is_symmetric_and_narrows_with_n() -> None:
    lo, hi = wilson_interval(3, 10)
    lo2, hi2 = wilson_interval(7, 10)
    assert lo == pytest.approx(1.0 - hi2) and hi == pytest.approx(1.0 - lo2)
    assert wilson_interval(50, 100)[1] - wilson_interval(50, 100)[0] < hi - lo
    # 99 % is wider than 95 %
    assert wilson_interval(3, 10, 0.99)[0] < lo


@pytest.mark.parametrize("args", [(0, 0), (5, 4), (-1, 4)])
def test_wilson_interval_refuses_impossible_counts(args: tuple[int, int]) -> None:
    with pytest.raises(ValueError):
        wilson_interval(*args)


def test_mean_interval_is_students_t() -> None:
    # 1..5: mean 3, s = sqrt(2.5) = 1.58114, t(4, 0.975) = 2.776445: half-width 2.776445 * 1.58114 / sqrt(5) = 1.96324
    ci = mean_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    assert ci.mean == 3.0 and ci.n == 5 and ci.std == pytest.approx(math.sqrt(2.5))
    assert ci.low == pytest.approx(3.0 - 1.96324, abs=1e-5) and ci.high == pytest.approx(3.0 + 1.96324, abs=1e-5)
    one = mean_interval([2.5])
    assert (one.mean, one.low, one.high) == (2.5, None, None)
    same = mean_interval([4.0, 4.0, 4.0])
    assert same.low == same.high == 4.0
    with pytest.raises(ValueError):
        mean_interval([])
    with pytest.raises(ValueError):
        mean_interval([1.0, math.nan])


def test_fisher_exact_is_the_lady_tasting_tea() -> None:
    # Fisher's own example: 3 of 4 right against 1 of 4: two-sided p = (1 + 16 + 16 + 1) / 70 = 0.4857
    assert fisher_exact(3, 4, 1, 4) == pytest.approx(34 / 70)
    # 4 of 4 against 0 of 4: p = 2 / 70
    assert fisher_exact(4, 4, 0, 4) == pytest.approx(2 / 70)
    assert fisher_exact(5, 10, 5, 10) == pytest.approx(1.0)


def test_two_proportion_z_by_hand() -> None:
    # 45/50 vs 35/50: pooled 0.8, se = sqrt(0.8 * 0.2 * (2/50)) = 0.08, z = 0.2 / 0.08 = 2.5, p = 2 (1 - Phi(2.5))
    z, p = two_proportion_z(45, 50, 35, 50)
    assert z == pytest.approx(2.5) and p == pytest.approx(0.0124193, abs=1e-6)
    assert two_proportion_z(35, 50, 45, 50)[0] == pytest.approx(-2.5)
    assert two_proportion_z(10, 10, 5, 5) == (0.0, 1.0)


def test_mann_whitney_exact_small_samples() -> None:
    # every value of a below every value of b: U_a = 0; exact two-sided p = 2 / C(6, 3) = 0.1
    assert mann_whitney([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]) == (0.0, pytest.approx(0.1))
    # U counts the pairs a wins: a = [1, 5], b = [2, 3, 4] -> 5 beats 2, 3, 4: U = 3
    assert mann_whitney([1.0, 5.0], [2.0, 3.0, 4.0])[0] == 3.0
    assert mann_whitney([2.0, 2.0], [2.0, 2.0, 2.0]) == (3.0, 1.0)  # nothing to tell apart
    with pytest.raises(ValueError):
        mann_whitney([], [1.0])


@pytest.mark.parametrize("confidence", [0.5, 0.8, 0.9, 0.95, 0.99, 0.999, 1e-6, 1.0 - 1e-9])
def test_the_quantiles_are_scipy_stats_own_to_the_last_bit(confidence: float) -> None:
    # the module calls scipy.special (ndtri, stdtrit, ndtr) instead of importing scipy.stats: batch.json
    # prints every interval at full precision, so they must be the very floats scipy.stats gives
    from scipy import stats

    from taskflow.campaigns.stats import _t, _z

    q = 0.5 + confidence / 2.0
    assert _z(confidence) == float(stats.norm.ppf(q))
    for df in (1, 2, 3, 4, 9, 19, 29, 99, 1000, 10**6):
        assert _t(confidence, df) == float(stats.t.ppf(q, df)), df
    for k1, n1, k2, n2 in ((3, 10, 7, 10), (1, 40, 39, 40), (20, 25, 5, 30)):
        z, p = two_proportion_z(k1, n1, k2, n2)
        assert p == float(2.0 * stats.norm.sf(abs(z)))
