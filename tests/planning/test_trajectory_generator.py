"""The paper's trajectory generator, written once for K relays (``planning.trajectory_generator``): for one relay and
one source the paper's eq. 14-19, checked against the surrogate written here from eq. 12-15 (its minimizer by scipy,
its derivatives by finite differences, eq. 18 as the implicit function's derivative); for chains the analytic optimum
(K relays between two fixed nodes settle evenly spaced) and two sources' sum over both routes."""

import numpy as np
import pytest
from scipy.optimize import minimize

from aerorelay.planning.fleet import FleetInput
from aerorelay.planning.trajectory_generator import SurrogateParams, TrajectoryGenerator, network_hops, regularized

P0 = np.zeros(3)
P1 = np.array([-6.95, 5.79, 1.72])
P2 = np.array([-3.04, 5.79, 1.72])
PJ = np.array([-6.95, -5.79, 1.72])
SP = SurrogateParams(mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0)
BOX = dict(workspace_min=[-7, -6, 0.5], workspace_max=[7, 6, 19])
WIDE = dict(workspace_min=[-90, -90, -90], workspace_max=[90, 90, 90])
ZERO = np.zeros(3)


def surrogate_by_hand(points, jam_power, mu=0.2, bandwidth=1.0):
    """(1/B) sum over consecutive points of 1/log2(1 + Gamma_bar), Gamma_bar = mu / d^2 / (1 + P_J / d_J^2) (eq. 12-15,
    G_bar = 1, unit powers), written here from the formula."""
    total = 0.0
    for a, b in zip(points[:-1], points[1:], strict=True):
        d2 = np.sum((b - a) ** 2)
        dj2 = np.sum((PJ - b) ** 2)
        total += 1.0 / np.log2(1.0 + mu / d2 / (1.0 + jam_power / dj2))
    return total / bandwidth


def f_one(p1, p2, jam_power):
    """The paper's one relay: the source's hop to the relay, the relay's to the base station."""
    return surrogate_by_hand([p2, p1, P0], jam_power)


def one(sp=SP, **kw) -> TrajectoryGenerator:
    """The paper's generator: relay ``r`` between source ``s`` and the base station at the origin."""
    return TrajectoryGenerator(sp, [["s", "r", "bs"]], ["r"], P0, **{"governor_speed": 0.5, "eig_floor": 1e-3, **BOX, **kw})


def inp(positions, velocities=None, accelerations=None, jam_power=1.0, dt=0.05, pj=PJ):
    return FleetInput(t=0.0, dt=dt, positions=positions, velocities=velocities or {}, accelerations=accelerations or {},
                      jammer_positions=np.reshape(pj, (-1, 3)), jammer_powers=np.atleast_1d(np.asarray(jam_power, float)))


def opt(tg, p1, p2, v2=ZERO, jam_power=1.0):
    """Eq. 17-19 of the one relay: (p_opt, v_d, a_d, taylor error, regularized)."""
    p_opt, v_d, a_d, err, reg = tg.optimum(inp({"r": p1, "s": p2}, {"s": v2}, {"s": ZERO}, jam_power))
    return p_opt[0], v_d[0], a_d[0], err, reg


def test_hops_in_route_order_a_shared_hop_twice():
    assert network_hops([["a", "r1", "r2", "bs"], ["b", "r1", "r2", "bs"]]) == [
        ("a", "r1"), ("r1", "r2"), ("r2", "bs"), ("b", "r1"), ("r1", "r2"), ("r2", "bs")]


@pytest.mark.parametrize("jam_power", [0.0, 1.0])
@pytest.mark.parametrize("p2", [P2, np.array([-1.5, 4.29, 9.0]), np.array([0.0, 4.29, 16.5])])
def test_newton_references_converge_to_scipy_minimizer(p2, jam_power):
    tg = one(**{"workspace_min": [-50, -50, -50], "workspace_max": [50, 50, 50]})
    ref = minimize(lambda x: f_one(x, p2, jam_power), P1, method="BFGS", options={"gtol": 1e-10})
    p = P1.copy()
    for _ in range(30):
        p = opt(tg, p, p2, jam_power=jam_power)[0]
    np.testing.assert_allclose(p, ref.x, atol=1e-4)


def test_gradient_and_hessian_match_finite_differences():
    tg = one()
    f, g, H = tg.expansion({"r": P1, "s": P2}, PJ, [1.0])
    assert f == pytest.approx(f_one(P1, P2, 1.0), rel=1e-12)
    h = 1e-5
    for i in range(3):
        e = np.eye(3)[i] * h
        assert g[i] == pytest.approx((f_one(P1 + e, P2, 1) - f_one(P1 - e, P2, 1)) / (2 * h), rel=1e-6)
        assert g[3 + i] == pytest.approx((f_one(P1, P2 + e, 1) - f_one(P1, P2 - e, 1)) / (2 * h), rel=1e-6)
        gp = tg.expansion({"r": P1, "s": P2 + e}, PJ, [1.0])[1]
        gm = tg.expansion({"r": P1, "s": P2 - e}, PJ, [1.0])[1]
        np.testing.assert_allclose(H[:3, 3 + i], (gp[:3] - gm[:3]) / (2 * h), rtol=1e-5, atol=1e-6)


def test_velocity_reference_is_implicit_function_derivative():
    # v_d = -H11^-1 H12 p2_dot is d p*/dt of the minimizer when MRAV-2 moves (eq. 18)
    tg = one(**WIDE)
    v2 = np.array([0.1, -0.2, 0.3])

    def argmin(p2):
        p = P1.copy()
        for _ in range(30):
            p = opt(tg, p, p2)[0]
        return p

    p_star = argmin(P2)
    v_d = opt(tg, p_star, P2, v2)[1]
    dt = 1e-3
    fd = (argmin(P2 + v2 * dt) - argmin(P2 - v2 * dt)) / (2 * dt)
    np.testing.assert_allclose(v_d, fd, rtol=1e-3, atol=1e-5)


def test_governor_bounds_reference_speed_and_taylor_error_is_logged():
    tg = one()
    dt = 0.015
    prev = P1.copy()
    errs = []
    for k in range(200):
        r = tg.update(inp({"r": P1, "s": P2 + np.array([0, 0, 0.01 * k])}, dt=dt))["r"]
        assert np.linalg.norm(r.p_ref - prev) <= 0.5 * dt + 1e-12
        assert np.linalg.norm(r.v_ref) <= 0.5 + 1e-12
        prev = r.p_ref
        errs.append(r.taylor_rel_err)
    assert errs[0] == 0.0 and 0 < max(errs[1:]) < 1e-3


def test_indefinite_hessian_is_regularized_relative_to_its_largest_eigenvalue():
    H = np.diag([1.0, -2.0, 0.5])
    Hr, reg = regularized(H, 1e-3)
    assert reg
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(Hr)), [2e-3, 0.5, 1.0], rtol=1e-12)  # the floor: 1e-3 * |-2|
    Hs, reg2 = regularized(np.eye(3), 1e-3)
    assert not reg2 and np.array_equal(Hs, np.eye(3))
    tiny = regularized(1e-9 * np.diag([1.0, 0.5, 2e-4]), 1e-3)[0]  # scale-free: 1e-9 H floors as H does
    np.testing.assert_allclose(np.linalg.eigvalsh(tiny), 1e-9 * np.array([1e-3, 0.5, 1.0]), rtol=1e-9)
    # the paper's rule: at least eig_floor * max(1, |lambda|max), so 1e-3 itself below 1
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(regularized(H, 1e-3, relative=False)[0])), [2e-3, 0.5, 1.0])
    paper = regularized(1e-9 * np.diag([1.0, 0.5, 2e-4]), 1e-3, relative=False)[0]
    np.testing.assert_allclose(paper, 1e-3 * np.eye(3), rtol=1e-5)  # every eigenvalue (1e-9 .. 2e-13) raised to 1e-3


def test_the_newton_step_does_not_depend_on_the_cost_unit():
    """f in s/bit over a 20 MHz band is f / 2e7: its Newton step, floored or not, is the same (the paper's absolute floor
    of eig_floor froze a relay in physical units, where every eigenvalue is far below 1)."""
    floored = []
    for p1 in (P1, np.array([-6.9, -5.0, 1.7])):  # the second beside the jammer, where H11 is indefinite: the floor acts
        a = opt(one(**WIDE), p1, P2)
        floored.append(a[4])
        b = opt(one(SurrogateParams(mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0, bandwidth=2e7), **WIDE), p1, P2)
        np.testing.assert_allclose(b[0], a[0], rtol=1e-9)
        np.testing.assert_allclose(b[1], a[1], rtol=1e-9, atol=1e-15)
        assert a[4] == b[4]
    assert floored == [False, True]
    # the paper's floor in s/bit: every eigenvalue raised to 1e-3, the Newton step 4 mm for 6.2 m (7e-4 of it: frozen)
    paper = opt(one(SurrogateParams(mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0, bandwidth=2e7), relative_floor=False,
                    **WIDE), P1, P2)
    relative = opt(one(**WIDE), P1, P2)
    assert np.linalg.norm(paper[0] - P1) < 1e-2 * np.linalg.norm(relative[0] - P1)


def test_the_floors_rule_is_the_papers_for_its_problem_relative_for_a_network_and_honoured_when_set():
    import aerorelay as ar
    from aerorelay.assembly.parts import build

    assert build(ar.load_scenario("scenarios/rma_av.toml")).planner.relative_floor is False
    assert build(ar.load_scenario("scenarios/rma_av.toml", set={"controller.hessian_floor": "relative"})).planner.relative_floor
    chain = ar.load_scenario("scenarios/chain_two_relays.toml", set={"controller.planner": "paper", "network.route": False})
    assert build(chain).planner.relative_floor is True
    assert build(chain.with_updates({"controller.hessian_floor": "paper"})).planner.relative_floor is False


def test_taylor_error_ignores_a_change_of_jammer_knowledge():
    tg = one()
    dt = 0.015
    tg.update(inp({"r": P1, "s": P2}, jam_power=0.0, dt=dt))  # before localization
    r = tg.update(inp({"r": P1 + 0.005, "s": P2 + 0.005}, jam_power=1.0, dt=dt))["r"]  # localized now
    assert r.taylor_rel_err < 1e-6
    # independent check: the second-order model of the previous step at the new point, same jammer (P_J = 0)
    f0, g, H = tg.expansion({"r": P1, "s": P2}, PJ, [0.0])
    d = np.full(6, 0.005)
    f_new = f_one(P1 + 0.005, P2 + 0.005, 0.0)
    expected = abs(f_new - (f0 + g @ d + 0.5 * d @ H @ d)) / f_new
    assert r.taylor_rel_err == pytest.approx(expected, rel=1e-6, abs=1e-15)


def test_a_degenerate_surrogate_holds_the_last_reference_instead_of_raising():
    """mu = 0 makes the surrogate's inverse capacity infinite (rejected for scenarios); the generator
    itself, given it anyway, holds its reference rather than feeding NaNs to the NMPC."""
    gen = one(SurrogateParams(0.0, 1.0, 1.0, 1.0))
    ref = gen.update(inp({"r": P1, "s": P2}, dt=0.015))["r"]
    np.testing.assert_array_equal(ref.p_ref, P1)
    assert np.all(ref.v_ref == 0) and np.all(np.isfinite(ref.a_ref))


def test_jammer_count_mismatch_raises_instead_of_shifting_the_packed_input():
    tg = one()  # one jammer
    with pytest.raises(ValueError, match="1 jammer"):
        tg.expansion({"r": P1, "s": P2}, np.array([PJ, PJ]), np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match="1 jammer"):
        tg.expansion({"r": P1, "s": P2}, PJ, np.array([1.0, 1.0]))


def test_expansion_does_not_alias_its_buffer():
    # the packed output buffer is overwritten by the next call: returned arrays must be copies
    tg = one()
    _, g, H = tg.expansion({"r": P1, "s": P2}, PJ, [1.0])
    g_first, H_first = g.copy(), H.copy()
    tg.expansion({"r": P1 + 1.0, "s": P2}, PJ, [1.0])
    np.testing.assert_array_equal(g, g_first)
    np.testing.assert_array_equal(H, H_first)


def test_value_and_gradient_of_a_chain_from_the_formula():
    pts = {"s": np.array([8.0, 1.0, 2.0]), "r1": np.array([5.0, 0.5, 2.0]), "r2": np.array([2.0, 1.0, 1.5])}
    net = TrajectoryGenerator(SP, [["s", "r1", "r2", "bs"]], ["r1", "r2"], P0, governor_speed=0.5, eig_floor=1e-3, **WIDE)
    f, g, _ = net.expansion(pts, PJ, [1.0])
    chain = lambda r1, r2: surrogate_by_hand([pts["s"], r1, r2, P0], 1.0)  # noqa: E731
    assert f == pytest.approx(chain(pts["r1"], pts["r2"]), rel=1e-12)
    h = 1e-5
    for i in range(3):
        e = np.eye(3)[i] * h
        assert g[i] == pytest.approx((chain(pts["r1"] + e, pts["r2"]) - chain(pts["r1"] - e, pts["r2"])) / (2 * h), rel=1e-6)
        assert g[3 + i] == pytest.approx((chain(pts["r1"], pts["r2"] + e) - chain(pts["r1"], pts["r2"] - e)) / (2 * h), rel=1e-6)


@pytest.mark.parametrize("k", [2, 3])
def test_relays_between_two_fixed_nodes_settle_evenly_spaced(k):
    # no jammer, equal links: the minimizer of sum 1/log2(1 + mu/d_i^2) over a chain with fixed ends is the even split
    src = np.array([40.0, 0.0, 0.0])
    names = [f"r{i}" for i in range(1, k + 1)]
    pos = {n: src * (0.9 - 0.2 * i) + np.array([0.0, 3.0 * (-1) ** i, 1.0]) for i, n in enumerate(names)}  # off the line
    net = TrajectoryGenerator(SP, [["s", *names, "bs"]], names, P0, governor_speed=0.5, eig_floor=1e-3, **WIDE)
    for _ in range(40):
        p_opt = net.optimum(inp({**pos, "s": src}, jam_power=0.0))[0]
        pos = {n: p_opt[i] for i, n in enumerate(names)}
    want = [src * (k - i) / (k + 1) for i in range(k)]  # r1 nearest the source
    np.testing.assert_allclose(np.array(list(pos.values())), np.array(want), atol=1e-6)


def test_two_sources_sharing_a_relay_minimize_the_sum_over_both_routes():
    a, b = np.array([10.0, 4.0, 2.0]), np.array([10.0, -4.0, 2.0])
    routes = [["a", "r1", "r2", "bs"], ["b", "r1", "r2", "bs"]]
    net = TrajectoryGenerator(SP, routes, ["r1", "r2"], P0, governor_speed=0.5, eig_floor=1e-3, **WIDE)
    pos = {"r1": np.array([7.0, 1.0, 2.0]), "r2": np.array([3.0, -1.0, 1.0])}
    for _ in range(40):
        p_opt = net.optimum(inp({**pos, "a": a, "b": b}))[0]
        pos = {"r1": p_opt[0], "r2": p_opt[1]}

    def total(x):
        r1, r2 = x[:3], x[3:]
        return surrogate_by_hand([a, r1, r2, P0], 1.0) + surrogate_by_hand([b, r1, r2, P0], 1.0)

    ref = minimize(total, np.r_[7.0, 1.0, 2.0, 3.0, -1.0, 1.0], method="BFGS", options={"gtol": 1e-10})
    np.testing.assert_allclose(np.r_[pos["r1"], pos["r2"]], ref.x, atol=1e-4)


def test_references_move_at_each_relays_governor_speed_and_stay_in_its_workspace():
    net = TrajectoryGenerator(SP, [["s", "r1", "r2", "bs"]], ["r1", "r2"], P0, governor_speed={"r1": 0.5, "r2": 0.2},
                              eig_floor=1e-3, workspace_min=[-5, -5, 0], workspace_max=[5, 5, 5],
                              boxes={"r2": (np.array([-5, -5, 0]), np.array([3, 5, 5]))})
    pos = {"r1": np.array([4.0, 0.0, 2.0]), "r2": np.array([1.0, 0.0, 2.0]), "s": np.array([40.0, 0.0, 2.0])}
    refs = net.update(inp(pos))
    for n, r in refs.items():
        assert np.linalg.norm(r.p_ref - pos[n]) <= {"r1": 0.5, "r2": 0.2}[n] * 0.05 + 1e-12
        assert np.all(r.p_opt <= (5 if n == "r1" else [3, 5, 5])) and np.all(r.p_opt >= [-5, -5, 0])
