"""``datasets.range_bearing``: the unbiased converted measurement against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.range_bearing import convert

BEARING_SIGMA = np.deg2rad(3.75)  # the paper's laser tuning, where the bias shows


def _monte_carlo(conversion: str, true_range: float, range_sigma: float, draws: int = 100_000):
    rng = np.random.default_rng(0)
    bearing = 0.7
    ranges = true_range + range_sigma * rng.standard_normal(draws)
    bearings = bearing + BEARING_SIGMA * rng.standard_normal(draws)
    points, covariances = convert(
        ranges, bearings, np.full(draws, range_sigma), BEARING_SIGMA, conversion
    )
    errors = true_range * np.array([np.cos(bearing), np.sin(bearing)]) - points
    nees = np.einsum("ni,ni->n", errors, np.linalg.solve(covariances, errors[..., None])[..., 0])
    return errors.mean(axis=0), float(nees.mean()), errors.std(axis=0) / np.sqrt(draws)


@pytest.mark.parametrize(("true_range", "range_sigma"), [(4.0, 0.15), (25.0, 0.25)])
def test_unbiased_conversion_is_unbiased_and_consistent(
    true_range: float, range_sigma: float
) -> None:
    bias, nees, standard_error = _monte_carlo("unbiased", true_range, range_sigma)
    assert np.all(np.abs(bias) < 4 * standard_error)
    assert nees == pytest.approx(2.0, abs=0.03)


def test_first_order_conversion_is_biased_and_optimistic_far_away() -> None:
    bias, nees, standard_error = _monte_carlo("first-order", 25.0, 0.25)
    # E[r_m cos a_m] = r exp(-s_a^2 / 2) cos a: the plain conversion falls short by r (1 - l)
    expected = 25.0 * (1.0 - np.exp(-0.5 * BEARING_SIGMA**2)) * np.array([np.cos(0.7), np.sin(0.7)])
    np.testing.assert_array_less(np.abs(bias - expected), 4 * standard_error)
    assert np.all(np.abs(bias) > 5 * standard_error)
    assert nees > 2.08
