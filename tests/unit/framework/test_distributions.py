"""World-parameter distributions (:mod:`taskflow.mission.distributions`): draws, their support, their errors."""

from __future__ import annotations

import numpy as np
import pytest

from taskflow.mission.distributions import DistributionError, sample, support, world_rng

pytestmark = pytest.mark.unit


def test_signed_uniform_draws_a_magnitude_in_range_with_either_sign() -> None:
    rng = world_rng(3)
    draws = np.array([sample({"signed_uniform": [0.2, 0.5]}, rng) for _ in range(2000)])
    assert np.all((np.abs(draws) >= 0.2) & (np.abs(draws) <= 0.5))
    negative = np.mean(draws < 0)
    assert 0.45 < negative < 0.55  # a fair sign: 2000 draws put the fraction within ±0.05 (5 sigma ≈ 0.056)
    assert np.abs(draws).mean() == pytest.approx(0.35, abs=0.01)  # the magnitude uniform on [0.2, 0.5]
    again = world_rng(3)
    assert [sample({"signed_uniform": [0.2, 0.5]}, again) for _ in range(2000)] == draws.tolist()  # seeded


def test_signed_uniform_with_a_zero_lower_bound_is_uniform_on_the_symmetric_interval() -> None:
    rng = world_rng(0)
    draws = np.array([sample({"signed_uniform": [0.0, 1.0]}, rng) for _ in range(4000)])
    hist, _ = np.histogram(draws, bins=4, range=(-1.0, 1.0))
    assert np.all(np.abs(hist - 1000) < 120), hist


def test_signed_uniform_support_is_both_ends_on_both_sides() -> None:
    assert [v for v, _ in support({"signed_uniform": [0.1, 0.3]})] == [-0.3, -0.1, 0.1, 0.3]


@pytest.mark.parametrize("args", [[0.5, 0.2], [-0.1, 0.2], [0.1], "x"])
def test_signed_uniform_refuses_bounds_it_cannot_draw_from(args: object) -> None:
    with pytest.raises(DistributionError) as err:
        sample({"world": {"offset": {"signed_uniform": args}}}, world_rng(0))
    assert err.value.path == ("world", "offset")
    assert "signed_uniform" in str(err.value)
