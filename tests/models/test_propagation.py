"""Propagation and time-correlated fading against independent values: Friis, log-distance,
3GPP TR 36.777 RMa-AV at sample heights and distances, Gudmundson shadowing statistics, Clarke
fading's power, K factor and autocorrelation."""

import math
import os

import casadi as ca
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.special import j0

from aerorelay.models.fading import ClarkeRicianFading
from aerorelay.models.propagation import (
    LargeScaleRealization,
    PathGain,
    RmaAvPathGain,
    ShadowingField,
    check_rma_av_range,
    free_space_loss_db,
    link_heights,
    rma_av_expected_gain,
    rma_av_los_probability,
    rma_av_path_loss_db,
    rma_av_shadow_std_db,
)


def test_friis_at_1_km_and_2_4_ghz_is_100_05_db():
    assert free_space_loss_db(1000.0, 2.4e9) == pytest.approx(100.05, abs=0.01)
    assert PathGain.free_space(2.4e9).loss_db(1000.0) == pytest.approx(100.05, abs=0.01)


@settings(max_examples=200, deadline=None)
@given(st.floats(1.5, 6.0), st.floats(0.5, 50.0), st.floats(0.0, 80.0), st.floats(0.1, 5000.0))
def test_log_distance_is_its_reference_loss_plus_10_n_per_decade(n, d0, pl0, d):
    g = PathGain.log_distance(n, d0, pl0)
    assert g.loss_db(d) == pytest.approx(pl0 + 10.0 * n * math.log10(d / d0), abs=1e-9)
    assert g.gain_from_d2(d * d) == pytest.approx(10.0 ** (-g.loss_db(d) / 10.0), rel=1e-9)


def test_the_papers_free_space_is_one_over_d_squared():
    g = PathGain()
    assert g.is_paper and g.gain_from_d2(16.0) == 1.0 / 16.0


# TR 36.777 Table B-1..B-3 (RMa-AV), evaluated by hand from the standard's printed formulas:
# h = 30 m, d3D = 500 m, fc = 2 GHz: LoS (23.9 - 1.8 log10 30) log10 500 + 20 log10(40 pi 2/3)
# = 21.2412 x 2.69897 + 38.4622 = 95.792 dB; NLoS -12 + (35 - 5.3 log10 30) log10 500 + 38.4622
# = -12 + 27.1713 x 2.69897 + 38.4622 = 99.797 dB; h = 20 m, d2D = 500 m: d1 = 1350.8 x 1.30103
# - 1602 = 155.43 m, p1 = 15021 x 1.30103 - 16053 = 3489.8 m, P_LoS = 155.43/500 + e^(-500/3489.8)
# (1 - 155.43/500) = 0.9080; sigma_LoS(30 m) = 4.2 e^(-0.138) = 3.659 dB.
def test_rma_av_matches_the_standards_equations_at_sample_points():
    assert rma_av_path_loss_db(500.0, 30.0, 2e9, True) == pytest.approx(95.792, abs=0.005)
    assert rma_av_path_loss_db(500.0, 30.0, 2e9, False) == pytest.approx(99.797, abs=0.005)
    assert rma_av_los_probability(500.0, 20.0) == pytest.approx(0.9080, abs=1e-4)
    assert rma_av_los_probability(100.0, 20.0) == 1.0  # d2D <= d1
    assert rma_av_los_probability(5000.0, 50.0) == 1.0  # above 40 m always LoS
    assert rma_av_shadow_std_db(30.0, True) == pytest.approx(3.659, abs=1e-3)
    assert rma_av_shadow_std_db(30.0, False) == 6.0
    # NLoS never below LoS (the standard's max), and the expected gain lies between the two
    for d in (50.0, 300.0, 3000.0):
        lo, hi = rma_av_path_loss_db(d, 25.0, 2e9, True), rma_av_path_loss_db(d, 25.0, 2e9, False)
        assert hi >= lo
        g = rma_av_expected_gain(d, d, 25.0, 2e9)
        assert 10 ** (-hi / 10) <= g <= 10 ** (-lo / 10)


def test_rma_av_validity_range_is_a_named_error():
    with pytest.raises(ValueError, match=r"RMa-AV .* aerial heights in \(10, 300\] m"):
        check_rma_av_range(5.0, 100.0, "relay-bs")
    with pytest.raises(ValueError, match="2D distances <= 10000 m"):
        check_rma_av_range(50.0, 2e4)
    check_rma_av_range(50.0, 500.0)


def test_rma_av_constants_are_the_ones_tr3gpp_prints():
    """Cross-check against the PyPI package tr3gpp (the standard's tables as data), if installed."""
    try:
        import tr3gpp.tr36777 as tr
    except ImportError:
        if os.environ.get("AERORELAY_REQUIRE_TR3GPP") == "1":
            pytest.fail("tr3gpp is required here (AERORELAY_REQUIRE_TR3GPP=1; the dev extra installs it) but cannot be imported")
        pytest.skip("tr3gpp is not installed (the dev extra has it)")
    b = tr.annex("B")
    los = " ".join(e.los_probability for e in b.los_probability(scenario="RMa-AV"))
    assert all(c in los for c in ("15021", "16053", "1350.8", "1602"))
    pl = " ".join(e.pathloss for e in b.pathloss(scenario="RMa-AV", condition="LOS"))
    pl += " ".join(e.pathloss for e in b.pathloss(scenario="RMa-AV", condition="NLOS"))
    assert all(c in pl for c in ("23.9 - 1.8", "-12 + (35 - 5.3", "40\\pi f_c}{3}"))


def test_shadowing_field_has_unit_std_and_autocorrelation_exp_minus_one_at_the_decorrelation_distance():
    """Across 4000 independent links (fields): std 1 at any point, correlation exp(-|Delta| / d_corr)
    between two points (exp(-1) at d_corr, exp(-1/2) at half of it, in any direction)."""
    n, dc = 4000, 10.0
    field = ShadowingField(n, dc, seed=3)
    a = np.array([1.0, -2.0, 3.0])
    x0 = np.array([field.value(k, a) for k in range(n)])
    assert np.std(x0) == pytest.approx(1.0, rel=0.05) and abs(np.mean(x0)) < 4.0 / math.sqrt(n)
    for delta in (np.array([dc, 0.0, 0.0]), np.array([0.0, 0.6, 0.8]) * dc, np.array([0.0, 0.0, dc / 2])):
        x = np.array([field.value(k, a + delta) for k in range(n)])
        rho = np.corrcoef(x0, x)[0, 1]
        assert rho == pytest.approx(math.exp(-np.linalg.norm(delta) / dc), abs=4.0 / math.sqrt(n))
    # one field is one function of the geometry: the same point reads the same value
    np.testing.assert_allclose(field.value(7, np.tile(a, (5, 1))), np.full(5, field.value(7, a)), rtol=1e-12)


def test_large_scale_realization_scales_the_field_and_draws_los_states():
    """Log-distance: the shadowing is std_db times the unit field; RMa-AV: the gain is the state's over
    the expected one and the std the standard's for that state; the same seed, the same realization."""
    ld = LargeScaleRealization(PathGain(), 2, std_db=6.0, decorrelation_m=5.0, seed=11)
    a, b = np.zeros(3), np.array([3.0, 4.0, 5.0])
    r = ld.link(1, a, b)
    assert float(r.shadow_db) == pytest.approx(6.0 * float(ld.field.value(1, b - a)))
    assert float(r.gain) == pytest.approx(10 ** (float(r.shadow_db) / 10)) and r.los is None
    assert float(LargeScaleRealization(PathGain(), 2, std_db=6.0, decorrelation_m=5.0, seed=11).link(1, a, b).shadow_db) \
        == float(r.shadow_db)
    rma = RmaAvPathGain(carrier_hz=2e9)
    real = LargeScaleRealization(rma, 1, std_db=0.0, decorrelation_m=37.0, seed=5)
    far = np.array([300.0, 400.0, 30.0])
    rr = real.link(0, a, far)
    d2 = float(far @ far)
    d3 = math.sqrt(d2)
    los = bool(real.u[0] < float(rma_av_los_probability(500.0, 30.0)))
    assert bool(rr.los) == los
    expected = float(rma.gain_between(a, far, d2))
    state = 10 ** (-float(rma_av_path_loss_db(d3, 30.0, 2e9, los)) / 10)
    std = float(rma_av_shadow_std_db(30.0, los))
    assert float(rr.gain) == pytest.approx(state / expected * 10 ** (std * float(real.field.value(0, far - a)) / 10))
    assert not LargeScaleRealization(PathGain(), 3, std_db=0.0, decorrelation_m=5.0, seed=0).active


def test_clarke_fading_has_unit_power_its_k_factor_and_a_j0_autocorrelation():
    n_links, k_db, f_d, dt = 3000, 6.0, 20.0, 0.005
    fad = ClarkeRicianFading(k_db, n_links, seed=5)
    amps = np.array([fad.amplitude(np.full(n_links, f_d), dt) for _ in range(6)])  # (lags, links)
    p = amps**2
    assert p.mean() == pytest.approx(1.0, abs=0.03)
    # K from the moments (Rician: E|h|^4 / E|h|^2^2 = (K^2 + 4K + 2) / (K + 1)^2)
    m = (p**2).mean() / p.mean() ** 2
    k_est = (2 - m + math.sqrt(2 - m)) / (m - 1)
    assert 10 * math.log10(k_est) == pytest.approx(k_db, abs=1.0)
    # the diffuse part's autocorrelation at the first lags is J0(2 pi f_D tau)
    z = []
    for _ in range(6):
        z.append(fad.diffuse())
        fad.advance(np.full(n_links, f_d), dt)
    z = np.array(z)
    for lag in (1, 2, 3, 5):
        r = np.mean(z[lag] * np.conj(z[0])).real
        assert r == pytest.approx(j0(2 * np.pi * f_d * lag * dt), abs=0.05)


def test_rma_av_as_a_scene_path_gain_takes_the_links_heights():
    """A link from the ground (0, 0, 0) to (300, 400, 30): d2D = 500 m, d3D = 500.9 m, h_UT = 30 m, in
    either direction; the expected gain is rma_av_expected_gain there."""
    a, b = np.array([0.0, 0.0, 0.0]), np.array([300.0, 400.0, 30.0])
    d2 = float(b @ b)
    d3, d2d, h = link_heights(a, b, d2)
    assert (d3, d2d, h) == pytest.approx((math.sqrt(500.0**2 + 30.0**2), 500.0, 30.0))
    path = RmaAvPathGain(carrier_hz=2e9)
    g = rma_av_expected_gain(math.sqrt(d2), 500.0, 30.0, 2e9)
    assert path.gain_between(a, b, d2) == pytest.approx(g, rel=1e-12)
    assert path.gain_between(b, a, d2) == pytest.approx(g, rel=1e-12)
    # the state drawn by u: LoS below P_LoS, NLoS above; its gain over the expected one; its shadowing std
    p_los = float(rma_av_los_probability(500.0, 30.0))
    for u, los in ((0.5 * p_los, True), (0.5 * (1 + p_los), False)):
        state, ratio, std = path.realize(a, b, u)
        assert bool(state) == los and float(std) == pytest.approx(float(rma_av_shadow_std_db(30.0, los)))
        assert float(ratio) * g == pytest.approx(10 ** (-float(rma_av_path_loss_db(d3, 30.0, 2e9, los)) / 10), rel=1e-12)


@given(st.floats(-500, 500), st.floats(-500, 500), st.floats(10.5, 300.0), st.floats(0.0, 10.0))
@example(0.0, 0.0, 10.5, 10.0)  # 0.5 m at 10.5 m height: above the 20 dB/decade floor's d^-2 (found by hypothesis)
@example(0.0, 0.0, 10.5, 10.49)  # 1 cm
@settings(max_examples=60, deadline=None)
def test_rma_av_path_gain_is_dual_and_bounded_by_its_los_ceiling(x, y, h, z0):
    """numpy and CasADi give the same expected gain; ``gain_from_d2`` (the estimator's cap) bounds it,
    also closer than 1 m, where the LoS exponent (up to 22.1 dB/decade) gives more than ``d^-2``."""
    a, b = np.array([0.0, 0.0, z0]), np.array([x, y, h])
    d2 = float((b - a) @ (b - a))
    path = RmaAvPathGain(carrier_hz=2.4e9)
    g = float(path.gain_between(a, b, d2))
    pa, pb = ca.SX.sym("pa", 3), ca.SX.sym("pb", 3)
    f = ca.Function("g", [pa, pb], [path.gain_between(pa, pb, ca.dot(pb - pa, pb - pa))])
    assert float(f(a, b)) == pytest.approx(g, rel=1e-9)
    assert 0.0 < g <= float(path.gain_from_d2(d2)) * (1 + 1e-12)
    s2 = ca.SX.sym("d2")
    assert float(ca.Function("cap", [s2], [path.gain_from_d2(s2)])(d2)) == pytest.approx(float(path.gain_from_d2(d2)), rel=1e-12)
