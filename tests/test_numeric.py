"""``robovib._numeric`` (median/percentile without numpy.ma) against NumPy's own functions."""

from __future__ import annotations

import numpy as np
import pytest

from robovib._numeric import median, percentile


@pytest.mark.parametrize("n", [1, 2, 3, 10, 51])
def test_percentile_and_median_match_numpy(n):
    a = np.random.default_rng(n).normal(size=n) * 10.0 ** np.arange(n) % 7.3
    q = np.array([0.0, 2.5, 25.0, 50.0, 97.5, 100.0])
    np.testing.assert_allclose(percentile(a, q), np.percentile(a, q), rtol=1e-14, atol=1e-14)
    assert percentile(a, 2.5) == pytest.approx(float(np.percentile(a, 2.5)), rel=1e-14, abs=1e-14)
    assert median(a) == pytest.approx(float(np.median(a)), rel=1e-14, abs=1e-14)


def test_nan_and_bad_input():
    assert np.isnan(median([1.0, np.nan, 3.0])) and np.isnan(np.median([1.0, np.nan, 3.0]))
    with pytest.raises(ValueError, match="no values"):
        percentile([], 50)
    with pytest.raises(ValueError, match=r"\[0, 100\]"):
        percentile([1.0], 101)
