import numpy as np
import pytest
from scipy.optimize import minimize

from aerorelay.models.channel import inverse_capacity
from aerorelay.planning.trajectory_generator import SurrogateParams, TrajectoryGenerator, regularized

P0 = np.zeros(3)
P1 = np.array([-6.95, 5.79, 1.72])
P2 = np.array([-3.04, 5.79, 1.72])
PJ = np.array([-6.95, -5.79, 1.72])
SP = SurrogateParams(mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0)


def make(**kw):
    args = dict(governor_speed=0.5, eig_floor=1e-3, workspace_min=[-7, -6, 0.5], workspace_max=[7, 6, 19])
    args.update(kw)
    return TrajectoryGenerator(SP, P0, **args)


def f_surrogate(p1, p2, jam_power):
    return inverse_capacity(p1, p2, P0, [PJ], [jam_power], mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0)


@pytest.mark.parametrize("jam_power", [0.0, 1.0])
@pytest.mark.parametrize("p2", [P2, np.array([-1.5, 4.29, 9.0]), np.array([0.0, 4.29, 16.5])])
def test_newton_references_converge_to_scipy_minimizer(p2, jam_power):
    tg = make(workspace_min=[-50, -50, -50], workspace_max=[50, 50, 50])
    ref = minimize(lambda x: f_surrogate(x, p2, jam_power), P1, method="BFGS", options={"gtol": 1e-10})
    p = P1.copy()
    for _ in range(30):
        p = tg.optimum(p, p2, np.zeros(3), np.zeros(3), PJ, jam_power)[0]
    np.testing.assert_allclose(p, ref.x, atol=1e-4)


def test_gradient_and_hessian_match_finite_differences():
    tg = make()
    f, g1, g2, H11, H12, _ = tg.expansion(P1, P2, PJ, 1.0)
    assert f == pytest.approx(f_surrogate(P1, P2, 1.0))
    h = 1e-5
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        assert g1[i] == pytest.approx((f_surrogate(P1 + e, P2, 1) - f_surrogate(P1 - e, P2, 1)) / (2 * h), rel=1e-6)
        _, g1p, *_ = tg.expansion(P1, P2 + e, PJ, 1.0)
        _, g1m, *_ = tg.expansion(P1, P2 - e, PJ, 1.0)
        np.testing.assert_allclose(H12[:, i], (g1p - g1m) / (2 * h), rtol=1e-5, atol=1e-6)


def test_velocity_reference_is_implicit_function_derivative():
    # v_d = -H11^-1 H12 p2_dot is d p*/dt of the minimizer when MRAV-2 moves (eq. 18)
    tg = make(workspace_min=[-50, -50, -50], workspace_max=[50, 50, 50])
    v2 = np.array([0.1, -0.2, 0.3])

    def argmin(p2):
        p = P1.copy()
        for _ in range(30):
            p = tg.optimum(p, p2, np.zeros(3), np.zeros(3), PJ, 1.0)[0]
        return p

    p_star = argmin(P2)
    _, v_d, _, _, _ = tg.optimum(p_star, P2, v2, np.zeros(3), PJ, 1.0)
    dt = 1e-3
    fd = (argmin(P2 + v2 * dt) - argmin(P2 - v2 * dt)) / (2 * dt)
    np.testing.assert_allclose(v_d, fd, rtol=1e-3, atol=1e-5)


def test_governor_bounds_reference_speed_and_taylor_error_is_logged():
    tg = make()
    dt = 0.015
    prev = P1.copy()
    errs = []
    for k in range(200):
        r = tg.update(dt, P1, P2 + np.array([0, 0, 0.01 * k]), np.zeros(3), np.zeros(3), PJ, 1.0)
        assert np.linalg.norm(r.p_ref - prev) <= 0.5 * dt + 1e-12
        assert np.linalg.norm(r.v_ref) <= 0.5 + 1e-12
        prev = r.p_ref
        errs.append(r.taylor_rel_err)
    assert errs[0] == 0.0 and 0 < max(errs[1:]) < 1e-3


def test_indefinite_hessian_is_regularized():
    tg = make()
    H = np.diag([1.0, -2.0, 0.5])
    Hr, reg = regularized(H, tg.eig_floor)
    assert reg and np.linalg.eigvalsh(Hr).min() > 0
    Hs, reg2 = regularized(np.eye(3), tg.eig_floor)
    assert not reg2 and np.array_equal(Hs, np.eye(3))


def test_taylor_error_ignores_a_change_of_jammer_knowledge():
    tg = make()
    dt = 0.015
    tg.update(dt, P1, P2, np.zeros(3), np.zeros(3), PJ, 0.0)  # before localization
    r = tg.update(dt, P1 + 0.005, P2 + 0.005, np.zeros(3), np.zeros(3), PJ, 1.0)  # localized now
    assert r.taylor_rel_err < 1e-6
    # independent check: the second-order model of the previous step at the new point, same jammer (P_J = 0)
    f0, g1, g2, H11, H12, H22 = tg.expansion(P1, P2, PJ, 0.0)
    d = np.full(6, 0.005)
    H = np.block([[H11, H12], [H12.T, H22]])
    f_new = f_surrogate(P1 + 0.005, P2 + 0.005, 0.0)
    expected = abs(f_new - (f0 + np.concatenate([g1, g2]) @ d + 0.5 * d @ H @ d)) / f_new
    assert r.taylor_rel_err == pytest.approx(expected, rel=1e-6, abs=1e-15)


def test_a_degenerate_surrogate_holds_the_last_reference_instead_of_raising():
    """mu = 0 makes the surrogate's inverse capacity infinite (rejected for scenarios); the generator
    itself, given it anyway, holds its reference rather than feeding NaNs to the NMPC."""
    gen = TrajectoryGenerator(SurrogateParams(0.0, 1.0, 1.0, 1.0), P0, governor_speed=0.5, eig_floor=1e-3,
                              workspace_min=[-7, -6, 0.5], workspace_max=[7, 6, 19])
    ref = gen.update(0.015, P1, P2, np.zeros(3), np.zeros(3), PJ[None], np.ones(1))
    np.testing.assert_array_equal(ref.p_ref, P1)
    assert np.all(ref.v_ref == 0) and np.all(np.isfinite(ref.a_ref))


def test_jammer_count_mismatch_raises_instead_of_shifting_the_packed_input():
    tg = make()  # one jammer
    with pytest.raises(ValueError, match="1 jammer"):
        tg.expansion(P1, P2, np.array([PJ, PJ]), np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match="1 jammer"):
        tg.expansion(P1, P2, PJ, np.array([1.0, 1.0]))


def test_expansion_does_not_alias_its_buffer():
    # the packed output buffer is overwritten by the next call: returned arrays must be copies
    tg = make()
    _, g1, _, H11, *_ = tg.expansion(P1, P2, PJ, 1.0)
    g_first, H_first = g1.copy(), H11.copy()
    tg.expansion(P1 + 1.0, P2, PJ, 1.0)
    np.testing.assert_array_equal(g1, g_first)
    np.testing.assert_array_equal(H11, H_first)
