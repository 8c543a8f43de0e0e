"""Issue 79, item 2: schedules beyond time division (``network.schedule``), tested from formulas written here:
one relay under spatial reuse is time division exactly; a three-hop chain's spatial reuse (its first and last hops in
one slot, each the other's interference) and full duplex (every hop at once, the relays' self-interference) in
closed form; the network bound under either schedule above every configuration's rate; what cannot honour a schedule
is refused by name."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build_scene
from aerorelay.config import ScenarioError
from aerorelay.models.antenna import IsotropicPattern
from aerorelay.models.radio import NodePose
from aerorelay.planning.network_bound import NetworkBoundSolver, compute_network_bound
from tests.planning.test_network_bound import BS, problem, scene, still

ROOT = Path(__file__).resolve().parents[2]
UP = np.array([0.0, 0.0, 1.0])


def test_one_relay_under_spatial_reuse_is_time_division_exactly():
    sc = build_scene(ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml"))
    rng = np.random.default_rng(1)
    for _ in range(50):
        poses = {"source": NodePose(rng.uniform(-10, 10, 3) + [0, 0, 12], UP),
                 "relay": NodePose(rng.uniform(-10, 10, 3) + [0, 0, 12], rng.normal(size=3) / 3 + UP)}
        t = float(rng.uniform(0, 40))
        assert replace(sc, schedule="spatial_reuse").evaluate(t, poses).capacity == sc.evaluate(t, poses).capacity


def _chain():
    """An isotropic three-hop chain on the x axis (B = P = N = 1, gain 1/d^2): s at 9 m, r1 at 6, r2 at 3, bs at 0."""
    sc = scene(["r1", "r2"], IsotropicPattern(1.0), [["s", "r1", "r2", "bs"]])
    at = {"s": np.array([9.0, 0.0, 2.0]), "r1": np.array([6.0, 0.3, 2.0]), "r2": np.array([3.0, -0.2, 2.0]), "bs": BS}
    poses = {n: NodePose(p, UP) for n, p in at.items() if n != "bs"}
    return sc, at, poses


def _g(at, a: str, b: str) -> float:
    return 1.0 / float(np.sum((at[a] - at[b]) ** 2))


def test_spatial_reuse_of_a_three_hop_chain_is_the_closed_form():
    sc, at, poses = _chain()
    se = [math.log2(1.0 + _g(at, a, b)) for a, b in (("s", "r1"), ("r1", "r2"), ("r2", "bs"))]
    tdma = 1.0 / sum(1.0 / x for x in se)
    # hops 1 and 3 (s -> r1, r2 -> bs) share a slot, each hearing the other's transmitter; hop 2 alone
    sinr1 = _g(at, "s", "r1") / (1.0 + _g(at, "r2", "r1"))
    sinr3 = _g(at, "r2", "bs") / (1.0 + _g(at, "s", "bs"))
    reuse = 1.0 / (1.0 / min(math.log2(1.0 + sinr1), math.log2(1.0 + sinr3)) + 1.0 / se[1])
    st = replace(sc, schedule="spatial_reuse").evaluate(0.0, poses)
    assert float(st.capacity) == pytest.approx(max(reuse, tdma), rel=1e-12)
    assert reuse > tdma and int(st.slots[0]) == 2  # here reuse wins: two slots
    assert float(sc.evaluate(0.0, poses).capacity) == pytest.approx(tdma, rel=1e-12)


@pytest.mark.parametrize("suppression_db", [110.0, 0.0, 30.0])
def test_full_duplex_of_a_three_hop_chain_is_the_closed_form(suppression_db):
    sc, at, poses = _chain()
    si = 10.0 ** (-suppression_db / 10.0)
    # every hop at once: r1 hears r2 and its own transmission (si), r2 hears s and its own, bs hears s and r1
    sinr = [_g(at, "s", "r1") / (1.0 + si + _g(at, "r2", "r1")),
            _g(at, "r1", "r2") / (1.0 + si + _g(at, "s", "r2")),
            _g(at, "r2", "bs") / (1.0 + _g(at, "s", "bs") + _g(at, "r1", "bs"))]
    fd = min(math.log2(1.0 + g) for g in sinr)
    tdma = 1.0 / sum(1.0 / math.log2(1.0 + _g(at, a, b)) for a, b in (("s", "r1"), ("r1", "r2"), ("r2", "bs")))
    st = replace(sc, schedule="full_duplex", self_interference_db=suppression_db).evaluate(0.0, poses)
    assert float(st.capacity) == pytest.approx(max(fd, tdma), rel=1e-12)
    assert int(st.slots[0]) == (1 if fd > tdma else 3)


@pytest.mark.parametrize("schedule", ["spatial_reuse", "full_duplex"])
def test_no_configuration_beats_the_network_bound_under_the_schedule(schedule):
    sc = replace(scene(["r1", "r2"], IsotropicPattern(1.0), [["s", "r1", "r2", "bs"]], jammer=[5.0, 3.0, 2.0]),
                 schedule=schedule)
    src = np.array([15.0, 0.3, 2.5])
    pb = problem(sc, {"s": still(src)}, ["r1", "r2"], [-1, -3, 0], [17, 3, 4], 2.0)
    b = compute_network_bound(pb)
    assert b.resolution["schedule"] == schedule and b.resolution["schedule_factor"] == 3.0
    solver = NetworkBoundSolver(pb)
    poses = solver.fixed_poses(0.0)
    rng = np.random.default_rng(5)
    rates = [solver.rate(0.0, rng.uniform([-1, -3, 0], [17, 3, 4], (2, 3)), np.tile(UP, (2, 1)), poses) for _ in range(400)]
    assert max(rates) <= b.static[0]


def test_what_cannot_honour_a_schedule_is_refused_by_name():
    with pytest.raises(ScenarioError, match=r"network.schedule: 'full_duplex' .*trajectory generator"):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"network.schedule": "full_duplex"})
    with pytest.raises(ScenarioError, match=r"network.schedule: 'spatial_reuse' .*trajectory generator"):
        ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml",
                         set={"network.schedule": "spatial_reuse", "controller.planner": "trajectory_generator"})
    with pytest.raises(ScenarioError, match=r"network.schedule: 'full_duplex' .*ray-traced"):
        ar.load_scenario(ROOT / "scenarios" / "street_canyon_traced.toml", set={"network.schedule": "full_duplex",
                                                                                "controller.planner": "capacity"})
    with pytest.raises(ScenarioError, match=r"network.self_interference_db"):
        ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml", set={"network.self_interference_db": 90.0})
    # the paper's one relay under spatial reuse: time division itself, accepted
    assert ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                            set={"network.schedule": "spatial_reuse"}).network.schedule == "spatial_reuse"
