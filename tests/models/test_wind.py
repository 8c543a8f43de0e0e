"""The Dryden gusts (models/wind.py) against the model written here: MIL-F-8785C's low-altitude
intensities and scale lengths from their formulas, and on a long record the variances and the
autocorrelations of the Dryden spectra, sigma^2 exp(-V tau / L) (along the wind) and
sigma^2 (1 - V tau / (2 L)) exp(-V tau / L) (across and vertical), within a stated tolerance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aerorelay.models.wind import DrydenParameters, DrydenTurbulence, low_altitude_parameters

# 400k samples 0.1 s apart at V = 10 m/s: thousands of correlation times per component, so the
# estimates' spread is about 2% (variance) and 0.02 sigma^2 (correlation): 6% and 0.06 are 3 spreads
VAR_TOL, CORR_TOL = 0.06, 0.06


def test_low_altitude_parameters_are_the_specifications_formulas():
    h_ft = 50.0 / 0.3048  # 50 m
    k = 0.177 + 0.000823 * h_ft
    p = low_altitude_parameters(15.0, 50.0)
    assert p.length[2] == pytest.approx(50.0)
    assert p.length[0] == p.length[1] == pytest.approx(h_ft / k**1.2 * 0.3048)
    assert p.sigma[2] == pytest.approx(1.5)
    assert p.sigma[0] == p.sigma[1] == pytest.approx(1.5 / k**0.4)
    assert low_altitude_parameters(15.0, 1.0) == low_altitude_parameters(15.0, 3.048)  # clamped at 10 ft
    with pytest.raises(ValueError, match="wind speed at 6 m"):
        low_altitude_parameters(-1.0, 10.0)


def _autocorr(x: np.ndarray, lag: int) -> float:
    x = x - x.mean()
    return float(np.mean(x[:-lag] * x[lag:])) if lag else float(np.mean(x * x))


def test_long_record_has_the_dryden_variances_and_correlations():
    params = DrydenParameters(sigma=(1.2, 1.2, 0.8), length=(40.0, 40.0, 12.0))
    V, dt = 10.0, 0.1
    x = DrydenTurbulence(params, V, dt, seed=3).record(400_000)
    for i in range(3):
        s2, L = params.sigma[i] ** 2, params.length[i]
        assert np.var(x[:, i]) == pytest.approx(s2, rel=VAR_TOL), i
        for frac in (0.5, 1.0, 2.0):  # lags of half, one and two correlation times L / V
            tau = frac * L / V
            lag = int(round(tau / dt))
            tau = lag * dt
            want = math.exp(-V * tau / L) if i == 0 else (1 - V * tau / (2 * L)) * math.exp(-V * tau / L)
            assert _autocorr(x[:, i], lag) / s2 == pytest.approx(want, abs=CORR_TOL), (i, frac)


def test_seeded_and_still_air_is_still():
    p = low_altitude_parameters(10.0, 20.0)
    a, b = DrydenTurbulence(p, 10.0, 0.02, seed=1).record(50), DrydenTurbulence(p, 10.0, 0.02, seed=1).record(50)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, DrydenTurbulence(p, 10.0, 0.02, seed=2).record(50))
    still = DrydenTurbulence(low_altitude_parameters(0.0, 20.0), 0.0, 0.02).record(20)
    assert not still.any()
