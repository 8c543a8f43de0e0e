"""The paper's generator over a network: one relay is the paper's generator; the surrogate's sum over
hops from the formula; K relays between two fixed nodes settle evenly spaced (the analytic optimum)."""

import numpy as np
import pytest
from scipy.optimize import minimize

from aerorelay.planning.fleet import FleetInput
from aerorelay.planning.network_generator import NetworkGenerator, network_hops
from aerorelay.planning.trajectory_generator import SurrogateParams, TrajectoryGenerator

P0 = np.zeros(3)
PJ = np.array([[-6.95, -5.79, 1.72]])
SP = SurrogateParams(mu=0.2, g_bar=1.0, tx_power=1.0, noise_power=1.0)
WIDE = dict(governor_speed=0.5, eig_floor=1e-3, workspace_min=[-90, -90, -90], workspace_max=[90, 90, 90])


def surrogate_by_hand(points, jam_power, mu=0.2):
    """(1/B) sum over consecutive points of 1/log2(1 + Gamma_bar), Gamma_bar = mu / d^2 / (1 + P_J / d_J^2) (eq. 12-15,
    G_bar = 1, unit powers), written here from the formula."""
    total = 0.0
    for a, b in zip(points[:-1], points[1:], strict=True):
        d2 = np.sum((b - a) ** 2)
        dj2 = np.sum((PJ[0] - b) ** 2)
        total += 1.0 / np.log2(1.0 + mu / d2 / (1.0 + jam_power / dj2))
    return total


def inp(positions, velocities=None, accelerations=None, jam_power=1.0):
    return FleetInput(t=0.0, dt=0.05, positions=positions, velocities=velocities or {}, accelerations=accelerations or {},
                      jammer_positions=PJ, jammer_powers=np.array([jam_power]))


def test_hops_in_route_order_a_shared_hop_twice():
    assert network_hops([["a", "r1", "r2", "bs"], ["b", "r1", "r2", "bs"]]) == [
        ("a", "r1"), ("r1", "r2"), ("r2", "bs"), ("b", "r1"), ("r1", "r2"), ("r2", "bs")]


@pytest.mark.parametrize("jam_power", [0.0, 1.0])
def test_one_relay_is_the_papers_generator(jam_power):
    p1, p2, v2, a2 = np.array([-6.95, 5.79, 1.72]), np.array([-3.04, 5.79, 1.72]), np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.1, 0.0])
    single = TrajectoryGenerator(SP, P0, **WIDE).optimum(p1, p2, v2, a2, PJ, np.array([jam_power]))
    net = NetworkGenerator(SP, [["s", "r", "bs"]], ["r"], P0, **WIDE)
    p_opt, v_d, a_d = net.optimum(inp({"r": p1, "s": p2}, {"s": v2}, {"s": a2}, jam_power))
    np.testing.assert_allclose(p_opt[0], single[0], rtol=1e-12)
    np.testing.assert_allclose(v_d[0], single[1], rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(a_d[0], single[2], rtol=1e-10, atol=1e-14)


def test_value_and_gradient_of_a_chain_from_the_formula():
    pts = {"s": np.array([8.0, 1.0, 2.0]), "r1": np.array([5.0, 0.5, 2.0]), "r2": np.array([2.0, 1.0, 1.5])}
    net = NetworkGenerator(SP, [["s", "r1", "r2", "bs"]], ["r1", "r2"], P0, **WIDE)
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
    net = NetworkGenerator(SP, [["s", *names, "bs"]], names, P0, **WIDE)
    for _ in range(40):
        p_opt = net.optimum(inp({**pos, "s": src}, jam_power=0.0))[0]
        pos = {n: p_opt[i] for i, n in enumerate(names)}
    want = [src * (k - i) / (k + 1) for i in range(k)]  # r1 nearest the source
    np.testing.assert_allclose(np.array(list(pos.values())), np.array(want), atol=1e-6)


def test_two_sources_sharing_a_relay_minimize_the_sum_over_both_routes():
    a, b = np.array([10.0, 4.0, 2.0]), np.array([10.0, -4.0, 2.0])
    routes = [["a", "r1", "r2", "bs"], ["b", "r1", "r2", "bs"]]
    net = NetworkGenerator(SP, routes, ["r1", "r2"], P0, **WIDE)
    pos = {"r1": np.array([7.0, 1.0, 2.0]), "r2": np.array([3.0, -1.0, 1.0])}
    for _ in range(40):
        p_opt = net.optimum(inp({**pos, "a": a, "b": b}))[0]
        pos = {"r1": p_opt[0], "r2": p_opt[1]}

    def total(x):
        r1, r2 = x[:3], x[3:]
        return surrogate_by_hand([a, r1, r2, P0], 1.0) + surrogate_by_hand([b, r1, r2, P0], 1.0)

    ref = minimize(total, np.r_[7.0, 1.0, 2.0, 3.0, -1.0, 1.0], method="BFGS", options={"gtol": 1e-10})
    np.testing.assert_allclose(np.r_[pos["r1"], pos["r2"]], ref.x, atol=1e-4)


def test_references_move_at_the_governor_speed_and_stay_in_the_workspace():
    net = NetworkGenerator(SP, [["s", "r1", "r2", "bs"]], ["r1", "r2"], P0, governor_speed=0.5, eig_floor=1e-3,
                           workspace_min=[-5, -5, 0], workspace_max=[5, 5, 5])
    pos = {"r1": np.array([4.0, 0.0, 2.0]), "r2": np.array([1.0, 0.0, 2.0]), "s": np.array([40.0, 0.0, 2.0])}
    refs = net.update(inp(pos))
    for n, r in refs.items():
        assert np.linalg.norm(r.p_ref - pos[n]) <= 0.5 * 0.05 + 1e-12
        assert np.all(r.p_opt <= 5) and np.all(r.p_opt >= [-5, -5, 0])
