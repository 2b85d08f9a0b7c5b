"""error_stats' median is np.median's (evo's) to the bit, without importing numpy.ma."""

from __future__ import annotations

import numpy as np
import pytest

from mrnc_eval.evaluation.stats import median


@pytest.mark.parametrize("n", [1, 2, 3, 4, 101, 1000, 4097])
def test_median_equals_numpy(n: int) -> None:
    rng = np.random.default_rng(n)
    for values in (rng.lognormal(size=n), rng.integers(0, 5, size=n).astype(float), np.full(n, 0.1)):
        assert median(values) == np.median(values)
        assert np.float64(median(values)).tobytes() == np.median(values).tobytes()
    with_nan = rng.normal(size=n)
    with_nan[n // 2] = np.nan
    assert np.isnan(median(with_nan))


def test_median_of_two_rounds_as_numpy() -> None:
    """(a + b) / 2 as np.mean does it: the sum first (it overflows to inf for huge values)."""
    for a, b in ((0.1, 0.2), (1e308, 1e308), (5e-324, 5e-324), (1.0, np.nextafter(1.0, 2.0))):
        values = np.array([b, a])
        with np.errstate(over="ignore"):
            assert np.float64(median(values)).tobytes() == np.median(values).tobytes()
