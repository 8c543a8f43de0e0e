import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from aerorelay.models.sensing import KAPPA_DB, EnergyDetector, detector_log_mean_db, detector_log_std_db


@pytest.mark.parametrize("n", [1, 10, 100])
def test_readings_are_scaled_chi_square(n):
    """An energy detector over n complex samples reads P chi^2_(2n) / (2n): mean P, variance P^2 / n."""
    p = 3.7
    y = EnergyDetector(n, seed=5).measure(np.full(100_000, p))
    assert y.mean() == pytest.approx(p, rel=0.01)
    assert y.var() == pytest.approx(p * p / n, rel=0.03)
    assert stats.kstest(y[:4000] * 2 * n / p, stats.chi2(2 * n).cdf).pvalue > 1e-3


@pytest.mark.parametrize("n", [2, 30, 600])
def test_log_reading_moments(n):
    """The log moments the estimator models, against samples and against the large-n limits
    -kappa / (2n) and kappa / sqrt(n)."""
    z = 10 * np.log10(stats.chi2(2 * n).rvs(size=200_000, random_state=1) / (2 * n))
    assert detector_log_mean_db(n) == pytest.approx(z.mean(), abs=4 * z.std() / math.sqrt(z.size))
    assert detector_log_std_db(n) == pytest.approx(z.std(), rel=0.01)
    if n >= 30:
        assert detector_log_mean_db(n) == pytest.approx(-KAPPA_DB / (2 * n), rel=2 / n)
        assert detector_log_std_db(n) == pytest.approx(KAPPA_DB / math.sqrt(n), rel=1 / n)


def test_bias_scales_every_reading():
    a = EnergyDetector(50, bias_db=3.0, seed=2).measure(np.ones(1000))
    b = EnergyDetector(50, bias_db=0.0, seed=2).measure(np.ones(1000))
    np.testing.assert_allclose(a / b, 10 ** 0.3)
    with pytest.raises(ValueError, match="n_samples"):
        EnergyDetector(0)


@settings(max_examples=40, deadline=None)
@given(st.floats(1e-12, 1e6), st.integers(1, 10_000))
def test_readings_positive_and_shaped(p, n):
    y = EnergyDetector(n, seed=0).measure(np.full((2, 3), p))
    assert y.shape == (2, 3) and np.all(y > 0) and np.all(np.isfinite(y))
