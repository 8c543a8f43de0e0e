"""The network's rate (docs/concepts/networks.md), tested from its formula: every hop of every route
in its own time slot, every source at the same rate,
``R = B / sum_s sum_{k in route s} 1 / log2(1 + Gamma_{s,k})``; per route
``C_s = B / sum_{k in route s} 1 / log2(1 + Gamma_{s,k})``."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aerorelay.models.antenna import IsotropicPattern
from aerorelay.models.jammer import Jammer
from aerorelay.models.radio import Antenna, LinkBudget, Node, NodePose, RadioScene, network_rate, route_capacity

SINR = st.floats(1e-3, 1e4)


def test_a_hand_computed_network():
    # route 1: Gamma (3, 7) -> log2(1 + Gamma) (2, 3); route 2: Gamma (1, 15) -> (1, 4)
    routes = [[3.0, 7.0], [1.0, 15.0]]
    assert network_rate(routes, bandwidth=2.0) == pytest.approx(2.0 / (1 / 2 + 1 / 3 + 1 / 1 + 1 / 4))
    assert route_capacity(routes[0], 2.0) == pytest.approx(2.0 / (1 / 2 + 1 / 3))
    assert route_capacity(routes[1], 2.0) == pytest.approx(2.0 / (1 / 1 + 1 / 4))


@given(SINR, SINR, st.floats(0.1, 10.0))
def test_one_route_of_two_hops_is_eq_9(g1, g2, bandwidth):
    a, b = math.log2(1 + g1), math.log2(1 + g2)
    assert float(network_rate([[g1, g2]], bandwidth)) == pytest.approx(bandwidth * a * b / (a + b), rel=1e-12)


@given(st.lists(st.lists(SINR, min_size=1, max_size=4), min_size=1, max_size=3), st.floats(0.1, 10.0))
def test_the_rate_from_the_formula_and_symbolically(routes, bandwidth):
    want = bandwidth / sum(1.0 / math.log2(1.0 + g) for r in routes for g in r)
    assert float(network_rate(routes, bandwidth)) == pytest.approx(want, rel=1e-9)
    syms = [[ca.SX.sym(f"g{i}{k}") for k in range(len(r))] for i, r in enumerate(routes)]
    f = ca.Function("R", [ca.vertcat(*[s for r in syms for s in r])], [network_rate(syms, bandwidth)])
    assert float(f([g for r in routes for g in r])) == pytest.approx(want, rel=1e-9)


def test_a_dead_hop_stops_the_network():
    assert float(network_rate([[3.0, 0.0], [1.0, 15.0]])) == 0.0
    np.testing.assert_array_equal(network_rate([[np.array([3.0, 3.0]), np.array([0.0, 7.0])]]),
                                  [0.0, 1.0 / (1 / 2 + 1 / 3)])


def _iso(name, role, position=None):
    return Node(name, role, Antenna(IsotropicPattern(1.0)), None if position is None else np.array(position, float))


def test_a_scene_with_two_sources_sharing_a_relay_from_the_link_equations():
    """Isotropic unit gains in free space: Gamma = P_U / d^2 / (N + sum_j P_J / d_j^2) (eq. 5-7), written
    here from the equations; the relay r1 -> bs hop is in both routes (each source's data crosses it)."""
    nodes = (_iso("bs", "base_station", [0, 0, 0]), _iso("a", "source"), _iso("b", "source"), _iso("r1", "relay"))
    jam = Jammer(position=np.array([5.0, -5.0, 1.0]), power=4.0)
    scene = RadioScene(nodes, (jam,), LinkBudget(2.0, 0.5, 3.0), route=("a", "r1", "bs"),
                       routes=(("a", "r1", "bs"), ("b", "r1", "bs")))
    p = {"a": np.array([20.0, 0.0, 5.0]), "b": np.array([0.0, 18.0, 6.0]), "r1": np.array([8.0, 6.0, 4.0]),
         "bs": np.zeros(3)}
    poses = {n: NodePose(v, np.array([0.0, 0.0, 1.0])) for n, v in p.items() if n != "bs"}
    state = scene.evaluate(0.0, poses)

    def gamma(tx, rx):
        d2 = float(np.sum((p[rx] - p[tx]) ** 2))
        i = 4.0 / float(np.sum((p[rx] - jam.position) ** 2))
        return 2.0 / d2 / (0.5 + i)

    se = {h: math.log2(1 + gamma(*h)) for h in (("a", "r1"), ("r1", "bs"), ("b", "r1"))}
    assert state.hops == (("a", "r1"), ("r1", "bs"), ("b", "r1"))
    assert float(state.capacity) == pytest.approx(3.0 / (1 / se["a", "r1"] + 2 / se["r1", "bs"] + 1 / se["b", "r1"]))
    assert [float(c) for c in state.route_capacity] == pytest.approx(
        [3.0 / (1 / se["a", "r1"] + 1 / se["r1", "bs"]), 3.0 / (1 / se["b", "r1"] + 1 / se["r1", "bs"])])


def test_a_chain_of_two_relays_from_the_link_equations():
    nodes = (_iso("bs", "base_station", [0, 0, 0]), _iso("s", "source"), _iso("r1", "relay"), _iso("r2", "relay"))
    scene = RadioScene(nodes, (), LinkBudget(), route=("s", "r1", "r2", "bs"))
    p = {"s": np.array([30.0, 0.0, 5.0]), "r1": np.array([20.0, 1.0, 5.0]), "r2": np.array([10.0, -1.0, 5.0])}
    state = scene.evaluate(0.0, {n: NodePose(v, np.array([0.0, 0.0, 1.0])) for n, v in p.items()})
    p["bs"] = np.zeros(3)
    se = [math.log2(1 + 1.0 / float(np.sum((p[rx] - p[tx]) ** 2))) for tx, rx in (("s", "r1"), ("r1", "r2"), ("r2", "bs"))]
    assert float(state.capacity) == pytest.approx(1.0 / sum(1 / s for s in se))
    assert len(state.route_capacity) == 1 and float(state.route_capacity[0]) == pytest.approx(float(state.capacity))
