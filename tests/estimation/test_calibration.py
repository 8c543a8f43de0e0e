"""The jammer estimator's reported spread against its error when the readings fade (issue 61, item 5): the
relay circling near the jammer and the base station reporting, as ``test_jammer_estimator``, with a log-normal
fade on the jammer's received power, a Gauss-Markov process in dB per receiver (3 dB std; correlation time
0.05 s: about independent from one measurement of 10 steps to the next; 10 s: a fade that lasts). Before the
residuals' scale was read from the residuals (``residual_scale2``) a fade down read as a jammer switching and
left the fit: over 8 seeds the estimate ended 21 m off at a reported 3.3 m (mean NEES 1922); a lasting fade
is now seen in the residuals' correlation (``residual_inflation``) and the estimate is not trusted."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from aerorelay.estimation.jammer_estimator import JammerEstimator, residual_inflation, residual_scale2
from aerorelay.models.antenna import IsotropicPattern
from aerorelay.models.geometry import E3
from aerorelay.models.propagation import PathGain
from aerorelay.models.radio import link_gain
from aerorelay.models.sensing import EnergyDetector

from .test_jammer_estimator import BS_RX, DIPOLE, DT, JAMMER, RELAY_RX, SETTINGS, inr_10db_power, relay_pose


def _faded_run(fade_db: float, tau_s: float, seed: int, duration_s: float = 25.0):
    """The estimate after ``duration_s`` of faded readings: (NEES, trusted)."""
    est = JammerEstimator(1, [RELAY_RX, BS_RX], PathGain(), SETTINGS(), DT)
    det = EnergyDetector(100, seed=seed)
    rng = np.random.default_rng(seed + 1000)
    a = math.exp(-DT / tau_s)
    f = rng.normal(0.0, fade_db, 2)
    power = inr_10db_power()
    g_bs = link_gain(JAMMER, E3, IsotropicPattern(), np.zeros(3), E3, DIPOLE)
    for k in range(int(duration_s / DT)):
        t = k * DT
        f = a * f + math.sqrt(1.0 - a * a) * rng.normal(0.0, fade_db, 2)
        fade = 10.0 ** (f / 10.0)
        rx, ax = relay_pose(t)
        est.add(t, 0, rx, ax, float(det.measure(1.0 + fade[0] * power * link_gain(JAMMER, E3, IsotropicPattern(), rx, ax, DIPOLE))))
        est.add(t, 1, np.zeros(3), E3, float(det.measure(1.0 + fade[1] * power * g_bs)))
        e = est.update(t)
    d = e.positions[0] - JAMMER
    return float(d @ np.linalg.solve(e.covariances[0], d)), bool(e.confident[0])


def test_with_fast_fading_the_reported_spread_is_the_error_s():
    """16 seeds: the mean NEES (3 degrees of freedom) within its two-sided 95% chi-square band."""
    seeds = 16
    nees = np.array([_faded_run(3.0, 0.05, s)[0] for s in range(seeds)])
    lo, hi = stats.chi2.ppf([0.025, 0.975], 3 * seeds) / seeds
    assert lo <= nees.mean() <= hi, (nees.mean(), lo, hi, nees.round(2))


def test_a_lasting_fade_is_not_trusted():
    """A fade lasting 10 s biases a window of 40 s the same way for seconds: an estimate the planners would
    trust must still be consistent (NEES below the 99.9% point), else it is not trusted."""
    for s in range(6):
        nees, trusted = _faded_run(3.0, 10.0, s)
        assert not trusted or nees < stats.chi2.ppf(0.999, 3), (s, nees)


def test_the_residual_scale_is_the_normal_sigma_read_robustly():
    rng = np.random.default_rng(3)
    u = rng.normal(0.0, 5.0, 20_000)
    u[:1000] = 1e3  # 5% wild rows move a median little: to the clean |u|'s quantile 0.5 / 0.95
    expected = (stats.norm.ppf(0.5 + 0.5 * 0.5 / 0.95) / stats.norm.ppf(0.75) * 5.0) ** 2
    assert residual_scale2(u, np.ones_like(u)) == pytest.approx(expected, rel=0.03)
    assert residual_scale2(rng.normal(0.0, 0.5, 1000), np.ones(1000)) == 1.0  # never below the model's own noise


@pytest.mark.parametrize("rho", [0.5, 0.8, 0.95])
def test_correlated_residuals_inflate_the_variance_as_an_ar1_process(rho):
    """Two receivers' rows interleaved, each an AR(1) series: the factor is (1 + rho) / (1 - rho) of the series' lag-1
    correlation; white rows keep 1."""
    rng = np.random.default_rng(7)
    n = 20_000
    series = []
    for _ in range(2):
        x = np.empty(n)
        x[0] = rng.normal()
        for k in range(1, n):
            x[k] = rho * x[k - 1] + math.sqrt(1 - rho * rho) * rng.normal()
        series.append(x)
    e = np.column_stack(series).ravel()  # r0, r1, r0, r1, ...
    receiver = np.tile([0, 1], n)
    assert residual_inflation(e, receiver, np.ones(2 * n, bool)) == pytest.approx((1 + rho) / (1 - rho), rel=0.08)
    white = rng.normal(size=2 * n)
    assert residual_inflation(white, receiver, np.ones(2 * n, bool)) == 1.0


def test_an_estimate_pinned_at_the_search_box_is_not_trusted(caplog):
    """The jammer 2.8 m outside the box (its y below the box's -3 m): the fit settles on the box's face, where no
    spread the window gives covers the jammer; the estimate is marked at the edge, not trusted, and the setting to
    widen is named once."""
    from aerorelay.estimation.jammer_estimator import EstimatorSettings

    from .test_jammer_estimator import BOX, fly

    lo = BOX[0].copy()
    lo[1] = -3.0
    with caplog.at_level("WARNING"):
        _, out = fly(inr_10db_power(), 25.0, settings=EstimatorSettings(search_min=lo, search_max=BOX[1]))
    last = out[-1][1]
    assert last.at_edge[0] and not last.confident[0]
    assert abs(last.positions[0][1] - lo[1]) < 0.25 * 2.5
    assert sum("estimation.search_min_m / search_max_m" in r.message for r in caplog.records) == 1


def test_the_nees_metric_is_the_error_s_mahalanobis_length():
    from aerorelay.sim.metrics import estimation_metrics

    cov = np.array([[4.0, 1.0, 0.0], [1.0, 2.0, 0.5], [0.0, 0.5, 1.0]])
    est, true = np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.5, 3.5])
    log = {"t": np.array([0.0, 0.1]), "estimator_ms": np.array([1.0, 1.0]), "est_j_err_m": np.array([9.0, 1.6]),
           "est_j_std_m": np.array([5.0, 2.0]), "est_j_trusted": np.array([0.0, 1.0])}
    for i, a in enumerate("xyz"):
        log[f"est_j_{a}"], log[f"jam_j_{a}"] = np.array([0.0, est[i]]), np.array([0.0, true[i]])
    for k, (i, j) in {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}.items():
        log[f"est_j_cov_{k}"] = np.array([1.0, cov[i, j]])
    d = est - true
    m = estimation_metrics(log, 0.1)
    assert m["estimation_nees_final"] == pytest.approx(float(d @ np.linalg.inv(cov) @ d), rel=1e-12)
    assert m["estimation_trusted_final"] is True


def test_a_grid_holding_another_mode_puts_its_spread_into_the_reported_covariance():
    """Issue 77 (item 5): under Doppler fading the window's fit settled on a mirror mode 17-29 m off at a reported
    0.5-1.4 m while the grid filter (every reading so far) held its whole mass at the jammer; the window's comparison
    of the unpolished rival kept it at a likelihood ratio of 1e-6, so the estimate was trusted at NEES 250-434,000.
    Here the converged estimate's grid is made to hold one mode 10 m away (its sums there dominate): the next check
    counts that mode in full, and the reported spread covers it (the estimate is no longer confident)."""
    from .test_jammer_estimator import fly

    est, out = fly(inr_10db_power(), 25.0)
    assert out[-1][1].confident[0]
    far = int(np.argmin(np.linalg.norm(est.cells - (JAMMER + np.array([0.0, 10.0, 0.0])), axis=1)))
    est.s_ge[0, far], est.s_gg[0, far] = 1e6, 1.0  # log-likelihood 5e11 there: the grid's mass in that cell
    est._posterior = None
    est._refines = 3  # the next refinement checks a confident estimate against the grid's rival (every 4th)
    est._refine(25.0)
    e = est._summarize()
    d = est.cells[far] - e.positions[0]
    assert est._rival[0] == 1.0
    assert float(d @ np.linalg.solve(e.covariances[0], d)) < 3.0  # the rival mode within the reported spread
    assert not e.confident[0]


def test_an_estimate_is_trusted_once_confident_for_confirm_s():
    """Issue 77 (item 5): an estimate is trusted (``confident``) once its spread has been below ``confident_std_m``
    and it has been off the box's faces at every refinement for ``confirm_s`` without a break; with 0, at once."""
    from .test_jammer_estimator import fly

    refine_s = 2 * 10 * DT  # refine_every x aggregate_steps x the period: a refinement's spacing
    for confirm in (0.0, 1.0):
        _, out = fly(inr_10db_power(), 25.0, settings=SETTINGS(confirm_s=confirm))
        t = np.array([s for s, _ in out])
        ok = np.array([e.position_std[0] < 1.5 and not e.at_edge[0] for _, e in out])
        trusted = np.array([e.confident[0] for _, e in out])
        assert trusted.any() and not (trusted & ~ok).any()
        if confirm == 0.0:
            assert np.array_equal(trusted, ok)
        for k in np.flatnonzero(trusted):  # confident over the last confirm_s (less a refinement's spacing)
            assert ok[(t >= t[k] - confirm + refine_s) & (t <= t[k])].all()
        first_ok = t[np.argmax(ok)]
        assert t[np.argmax(trusted)] >= first_ok + confirm - refine_s


def test_the_widen_hint_is_said_only_when_the_grid_lies_at_that_face_too(caplog):
    """Issue 77 (item 5): the "widen the search box" hint fired with the jammer inside the box. An estimate on a face
    is still not trusted, but the hint is said only when the grid's mass lies at that face too (a jammer beyond it
    pulls the grid there; here the grid holds the jammer inside, 10 m from the face)."""
    from .test_jammer_estimator import fly

    est, out = fly(inr_10db_power(), 25.0)
    assert np.linalg.norm(out[-1][1].positions[0] - JAMMER) < 1.0
    est.theta[0, :3] = [est.lo[0], JAMMER[1], JAMMER[2]]  # the fit strayed onto the face x = -17 (the jammer at -6.95)
    with caplog.at_level("WARNING"):
        e = est._summarize()
    assert e.at_edge[0] and not e.confident[0]
    assert not any("search_min_m" in r.message for r in caplog.records)
