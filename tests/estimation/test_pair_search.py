"""The joint pair search against a brute-force weighted least squares over every pair of cells."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls

from aerorelay.estimation.pair_search import best_pair


def brute_force(gains, weights, excess):
    """Best drop of ``0.5 sum w e^2`` over pairs, by nonnegative least squares per pair (scipy)."""
    sw = np.sqrt(weights)
    best, arg = -np.inf, None
    chi0 = 0.5 * np.sum(weights * excess**2)
    for a in range(len(gains)):
        for b in range(len(gains)):
            if a == b:
                continue
            powers, res = nnls(np.column_stack([gains[a], gains[b]]) * sw[:, None], excess * sw)
            if chi0 - 0.5 * res**2 > best + 1e-9 * abs(chi0):
                best, arg = chi0 - 0.5 * res**2, (a, b, *powers)
    return best, arg


def random_problem(seed: int, n_cells: int = 12, n_rows: int = 30, noise: float = 0.05):
    rng = np.random.default_rng(seed)
    gains = rng.uniform(0.01, 1.0, (n_cells, n_rows)) ** 2
    a, b = rng.choice(n_cells, 2, replace=False)
    truth = rng.uniform(1.0, 10.0, 2)
    clean = truth[0] * gains[a] + truth[1] * gains[b]
    excess = clean * (1.0 + noise * rng.standard_normal(n_rows))
    return gains, 1.0 / clean**2, excess, (a, b, truth)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), noise=st.sampled_from([0.0, 0.05, 0.5]))
def test_best_pair_is_the_brute_force_nonnegative_least_squares(seed, noise):
    gains, weights, excess, _ = random_problem(seed, noise=noise)
    fit = best_pair(gains, weights, excess)
    best, (a, b, pa, pb) = brute_force(gains, weights, excess)
    assert fit.gain == pytest.approx(best, rel=1e-6, abs=1e-9)
    assert {fit.a, fit.b} == {a, b} or fit.power_b == 0.0  # a single cell: its partner is arbitrary
    powers = {fit.a: fit.power_a, fit.b: fit.power_b}
    if fit.power_b > 0.0:
        assert powers[a] == pytest.approx(pa, rel=1e-6) and powers[b] == pytest.approx(pb, rel=1e-6)


def test_noiseless_pair_is_recovered_exactly():
    gains, weights, excess, (a, b, truth) = random_problem(3, n_cells=40, noise=0.0)
    fit = best_pair(gains, weights, excess)
    assert {fit.a, fit.b} == {a, b}
    powers = {fit.a: fit.power_a, fit.b: fit.power_b}
    assert [powers[a], powers[b]] == pytest.approx(truth, rel=1e-9)
    assert fit.gain == pytest.approx(0.5 * np.sum(weights * excess**2), rel=1e-9)  # the whole excess explained


def test_keeping_the_best_single_cells_finds_the_same_pair():
    gains, weights, excess, _ = random_problem(7, n_cells=60, noise=0.01)
    full, kept = best_pair(gains, weights, excess), best_pair(gains, weights, excess, keep=20)
    assert {kept.a, kept.b} == {full.a, full.b} and kept.gain == pytest.approx(full.gain)


def test_one_source_gives_a_single_cell():
    gains, _, _, _ = random_problem(5, noise=0.0)
    excess = 4.0 * gains[2]
    fit = best_pair(gains, 1.0 / excess**2, excess)
    assert fit.a == 2 and fit.power_a == pytest.approx(4.0) and fit.power_b == pytest.approx(0.0, abs=1e-9)


def test_mismatched_sizes_raise():
    with pytest.raises(ValueError, match="disagree"):
        best_pair(np.ones((5, 10)), np.ones(9), np.ones(10))
