import math

import numpy as np
import pytest
from scipy import stats

from aerorelay.models.fading import RicianFading, k_factor_linear
from aerorelay.models.jammer import AlwaysOn, Jammer, PeriodicOnOff


def test_on_off_schedule():
    j = Jammer(np.zeros(3), 1.0, PeriodicOnOff(5.0, 5.0), localization_delay=2.0)
    t = np.array([0.0, 4.99, 5.0, 9.99, 10.0, 17.0])
    np.testing.assert_array_equal(j.power_at(t), [1, 1, 0, 0, 1, 0])
    assert not j.is_localized(1.9) and j.is_localized(2.0)


def test_fast_switching_is_just_parameters():
    s = PeriodicOnOff(0.1, 0.1)
    assert s.is_on(0.05) and not s.is_on(0.15) and s.is_on(0.25)
    assert AlwaysOn().is_on(123.0)


def test_k_factor_conversion():
    assert k_factor_linear(10.0) == pytest.approx(10.0)
    assert math.isinf(k_factor_linear(math.inf))
    with pytest.raises(ValueError, match="K-factor"):
        k_factor_linear(-1.0)


@pytest.mark.parametrize("k_db", [6.0, 12.0, 18.0])
def test_rician_unit_mean_power_and_distribution(k_db):
    a = RicianFading(k_db, seed=1).amplitude(200_000)
    assert np.mean(a**2) == pytest.approx(1.0, abs=0.01)
    # independent reference: scipy's Rice law with nu = sqrt(K/(K+1)), sigma^2 = 1/(2(K+1))
    k = 10 ** (k_db / 10)
    sigma = math.sqrt(1 / (2 * (k + 1)))
    ref = stats.rice(b=math.sqrt(k / (k + 1)) / sigma, scale=sigma)
    assert stats.kstest(a[:5000], ref.cdf).pvalue > 1e-3


def test_rician_seeded_and_no_fading():
    assert np.array_equal(RicianFading(6.0, seed=3).amplitude(10), RicianFading(6.0, seed=3).amplitude(10))
    assert np.all(RicianFading(math.inf).amplitude(5) == 1.0)
