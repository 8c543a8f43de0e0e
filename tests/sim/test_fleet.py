"""A fleet flown together (sim/fleet.py): the logged rates recomputed from the logged poses with the
paper's link equations written here (eq. 5-7 with half-wave dipoles, App. A), the equidistant
planner's places by hand, separation in the metrics."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import parse_scenario
from aerorelay.planning.fleet import equidistant_targets
from aerorelay.sim.log_schema import separation_min
from aerorelay.sim.metrics import compute_metrics

WS = {"min": [-5.0, -10.0, 0.5], "max": [45.0, 12.0, 20.0]}
CHAIN = {"sim": {"duration_s": 2.0},
         "controller": {"workspace": WS},
         "jammer": {"position": [15.0, -8.0, 2.0], "power_w": 4.0},
         "relays": [{"name": "r1", "start": [20.0, 1.0, 5.0]}, {"name": "r2", "start": [10.0, -1.0, 5.0]}],
         "sources": [{"name": "inspector", "mission": {"waypoints": [[0.0, 30.0, 0.0, 5.0], [20.0, 40.0, 0.0, 8.0]]}}],
         "network": {"routes": [["inspector", "r1", "r2", "bs"]], "min_separation_m": 2.0}}


def two_sources() -> dict:
    d = copy.deepcopy(CHAIN)
    d["sources"].append({"name": "second", "mission": {"waypoints": [[0.0, 30.0, 8.0, 6.0], [20.0, 35.0, 10.0, 6.0]]}})
    d["network"]["routes"].append(["second", "r1", "r2", "bs"])
    return d


def _axis(phi, theta, psi):
    """Body z in the world, ZYX Euler angles: the third column of Rz(psi) Ry(theta) Rx(phi)."""
    return np.array([math.cos(psi) * math.sin(theta) * math.cos(phi) + math.sin(psi) * math.sin(phi),
                     math.sin(psi) * math.sin(theta) * math.cos(phi) - math.cos(psi) * math.sin(phi),
                     math.cos(theta) * math.cos(phi)])


def _dipole(c):
    """Half-wave dipole, peak 1: cos^2(pi/2 cos th) / sin^2 th."""
    return math.cos(0.5 * math.pi * c) ** 2 / (1.0 - c * c)


def _gain(p_tx, b_tx, p_rx, b_rx, tx_dipole=True):
    d = p_rx - p_tx
    n = float(np.linalg.norm(d))
    g_tx = _dipole(float(d @ b_tx) / n) if tx_dipole else 1.0
    return g_tx * _dipole(float(-d @ b_rx) / n) / n**2


def _recompute(row, routes, jammer_power):
    """Per hop Gamma = P_U G G / d^2 / (sigma^2 + P_J G_J / d_J^2) (P_U = sigma^2 = 1, B = 1), per route
    C_s = 1 / sum_k 1/log2(1 + Gamma), network R = 1 / sum_s sum_k 1/log2(1 + Gamma)."""
    def pose(n):
        if n == "bs":
            return np.zeros(3), np.array([0.0, 0.0, 1.0])
        return (np.array([row[f"{n}.p_x"], row[f"{n}.p_y"], row[f"{n}.p_z"]]),
                _axis(row[f"{n}.phi"], row[f"{n}.theta"], row[f"{n}.psi"]))
    pj = np.array([row["jam_jammer_x"], row["jam_jammer_y"], row["jam_jammer_z"]])
    gamma, inv_total, per_route = {}, 0.0, []
    for route in routes:
        inv = 0.0
        for tx, rx in zip(route[:-1], route[1:], strict=False):
            (pt, bt), (pr, br) = pose(tx), pose(rx)
            interference = jammer_power * _gain(pj, None, pr, br, tx_dipole=False)
            gamma[tx, rx] = _gain(pt, bt, pr, br) / (1.0 + interference)
            inv += 1.0 / math.log2(1.0 + gamma[tx, rx])
        per_route.append(1.0 / inv)
        inv_total += inv
    return gamma, per_route, 1.0 / inv_total


@pytest.mark.parametrize("data", [CHAIN, two_sources()], ids=["chain", "two_sources"])
def test_logged_rates_equal_the_link_equations_on_the_logged_poses(data):
    sc = parse_scenario(data)
    r = ar.simulate(sc)
    df, m = r.timeseries, r.metrics
    assert not m["unsafe"], m["unsafe_reason"]
    for k in (0, len(df) // 2, len(df) - 1):
        row = df.iloc[k]
        gamma, routes, rate = _recompute(row, sc.route_list, 4.0)
        for (tx, rx), g in gamma.items():
            assert row[f"sinr.{tx}.{rx}"] == pytest.approx(g, rel=1e-9)
        for route, c in zip(sc.route_list, routes, strict=True):
            assert row[f"capacity.{route[0]}"] == pytest.approx(c, rel=1e-9)
        assert row["capacity"] == pytest.approx(rate, rel=1e-9)
    assert m["c_min"] == pytest.approx(df["capacity"].min()) and m["separation_min_m"] == pytest.approx(df["separation_min"].min())
    assert set(m["relays"]) == {"r1", "r2"} and set(m["routes"]) == {r[0] for r in sc.route_list} and "fleet_solve_ms" in m


def test_equidistant_places_by_hand():
    pos = {"s": np.array([30.0, 0.0, 6.0]), "bs": np.zeros(3), "t": np.array([0.0, 30.0, 6.0])}
    got = equidistant_targets([["s", "r1", "r2", "bs"]], pos)
    np.testing.assert_allclose(got["r2"], [10.0, 0.0, 2.0])  # first from the base station: 1/3 of the way
    np.testing.assert_allclose(got["r1"], [20.0, 0.0, 4.0])
    shared = equidistant_targets([["s", "r1", "bs"], ["t", "r1", "bs"]], pos)
    np.testing.assert_allclose(shared["r1"], [7.5, 7.5, 3.0])  # the mean of its places (15,0,3) and (0,15,3)


def test_separation_min_and_its_verdict():
    assert separation_min(np.array([[0.0, 0, 0], [3.0, 4.0, 0], [0, 0, 12.0]])) == pytest.approx(5.0)
    sc = parse_scenario(CHAIN)
    r = ar.simulate(sc)
    relays = {"r1": ar.api.vehicle(sc), "r2": ar.api.vehicle(sc)}
    common = dict(relays=relays, sources=["inspector"], period_s=sc.control_period_s, outage_threshold=1e-3, mu=0.0, wall_s=1.0,
                  sim_s=1.0, workspace_min=WS["min"], workspace_max=WS["max"])
    sep = float(r.timeseries["separation_min"].min())
    assert not compute_metrics(r.mission.log, min_separation_m=sep - 0.1, **common)["unsafe"]
    m = compute_metrics(r.mission.log, min_separation_m=sep + 0.1, **common)
    assert m["unsafe"] and "closer than network.min_separation_m" in m["unsafe_reason"]
    assert m["exit_status"] == "too_close" and m["exit_statuses"] == ["too_close"]


def _converging(separation_m: float | None):
    """Two sources 4 m apart, each relayed by its own relay: the equidistant places of r1 and r2 are
    2 m apart, the relays start 8 m apart."""
    return parse_scenario({
        "sim": {"duration_s": 10.0}, "controller": {"workspace": {"min": [-2, -10, 0.5], "max": [30, 10, 15]}},
        "jammer": {"position": [10.0, -9.0, 1.0]},
        "relays": [{"name": "r1", "start": [8.0, -4.0, 3.0]}, {"name": "r2", "start": [8.0, 4.0, 3.0]}],
        "sources": [{"name": "a", "mission": {"waypoints": [[0, 20, -2, 6], [10, 20, -2, 6]]}},
                    {"name": "b", "mission": {"waypoints": [[0, 20, 2, 6], [10, 20, 2, 6]]}}],
        "network": {"routes": [["a", "r1", "bs"], ["b", "r2", "bs"]]} | ({} if separation_m is None else {"min_separation_m": separation_m})})


def test_each_relays_nmpc_keeps_the_separation():
    def gap(sc):
        df = ar.simulate(sc).timeseries
        return np.linalg.norm(df[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy() - df[["r2.p_x", "r2.p_y", "r2.p_z"]].to_numpy(),
                              axis=1)
    free, kept = gap(_converging(None)), gap(_converging(3.0))
    # the places are 2 m apart: the default separation (the vehicles' size, 1.05 m) lets them meet there
    assert free[-1] < 2.1 and free.min() < 2.1 and free.min() > 1.05 - 0.05
    assert kept.min() > 3.0 - 0.05 and kept[-1] > 3.0 - 0.05  # the soft constraint holds (its slack < 5 cm)


def _iso_scene(route):
    from aerorelay.models.antenna import IsotropicPattern
    from aerorelay.models.radio import Antenna, LinkBudget, Node, RadioScene

    iso = Antenna(IsotropicPattern(1.0))
    nodes = (Node("bs", "base_station", iso, np.zeros(3)), Node("s", "source", iso),
             *(Node(n, "relay", iso) for n in route[1:-1]))
    return RadioScene(nodes, (), LinkBudget(1.0, 1.0, 1.0), tuple(route))  # SNR 1 / d^2: 0.01 at 10 m


@pytest.mark.parametrize("joint", [True, False], ids=["joint", "one_at_a_time"])
@pytest.mark.parametrize("route,want", [(["s", "r1", "bs"], {"r1": [10.0, 0.0, 5.0]}),
                                        (["s", "r1", "r2", "bs"], {"r1": [40 / 3, 0.0, 5.0], "r2": [20 / 3, 0.0, 5.0]})])
def test_the_fleets_capacity_planner_finds_the_even_spacing_in_free_space(route, want, joint):
    """Isotropic nodes, no jammer, low SNR (1 / d^2): the chain's best places are evenly spaced on the
    segment (1/log2(1 + 1/d^2) is convex in the hop's length d there, so equal hops minimize the sum
    of the hops' terms; at high SNR it is not: one relay on top of an end wins); the planner's
    goals on their 0.5 m grid stop within a grid cell's diagonal of them, with the relays' moves taken
    jointly and one relay at a time (the planner before 2026-12-04), without a route."""
    from aerorelay.models.axes import axis_cone
    from aerorelay.planning.fleet import FleetInput
    from aerorelay.planning.fleet_capacity import FleetCapacityPlanner, FleetCapacitySettings
    from aerorelay.planning.shaper import ShaperSettings

    scene = _iso_scene(route)
    starts = {n: np.array([3.0 + 4 * i, 4.0, 5.0]) for i, n in enumerate(route[1:-1])}
    planner = FleetCapacityPlanner(scene, starts, {n: axis_cone(0.85 * 0.3, np.radians(5.0)) for n in starts},
                                   {n: ShaperSettings(tilt_limit=0.3) for n in starts},
                                   FleetCapacitySettings(step_m=0.5, replan_every=1, workspace_min=(-50, -50, 5.0),
                                                         workspace_max=(50, 50, 5.0), joint=joint))
    inp = FleetInput(t=0.0, dt=0.06, positions={"s": np.array([20.0, 0.0, 5.0])}, velocities={"s": np.zeros(3)},
                     axes={"s": np.array([0.0, 0.0, 1.0])}, jammer_positions=np.zeros((0, 3)), jammer_powers=np.zeros(0))
    for _ in range(200):
        planner.update(inp)
    for name, p in want.items():
        assert np.linalg.norm(planner.goals[name] - p) <= np.sqrt(3) * 0.5, (name, planner.goals[name])  # a grid cell's diagonal


def test_the_fleets_capacity_planner_beats_the_equidistant_chain_under_the_jammer():
    """Measured on these 10 s (2026-12-04): 84.79 against 83.36 Mbit/s, +1.72% (the +11.5% of
    docs/results/networks.md is the whole 47 s mission); the test keeps more than half of that gain."""
    means = {}
    for planner in ("equidistant", "capacity"):
        sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"controller.planner": planner, "sim.duration_s": 10.0})
        m = ar.simulate(sc).metrics
        assert not m["unsafe"], m["unsafe_reason"]
        means[planner] = m["c_mean"]
    assert means["capacity"] > 1.01 * means["equidistant"], means


def test_the_papers_fleet_looks_at_each_relays_route_neighbours():
    """network.planner = "paper": every relay flies the comms-aware NMPC whose alignment terms look upstream at
    the previous node of its route and downstream at the next (the next relay's latest plan or the base
    station); the generator moves the references; the flight is safe."""
    from aerorelay.assembly.parts import build

    sc = parse_scenario({**CHAIN, "network": {**CHAIN["network"], "planner": "paper"}})
    parts = build(sc)
    seen: dict[str, list] = {}
    for r in parts.relays:
        assert r.controller.spec.constrained and r.controller.spec.p0_parameter
        original = r.controller.parameters

        def spy(*a, _orig=original, _name=r.name, **kw):
            seen.setdefault(_name, []).append((kw["p2_path"].copy(), kw["p0_path"].copy()))
            return _orig(*a, **kw)
        r.controller.parameters = spy
    loop = parts.closed_loop()
    res = loop.run()
    assert res.qp_failures == 0 and res.aborted is None
    bs = np.zeros(3)
    up_r1, down_r1 = seen["r1"][-1]
    up_r2, down_r2 = seen["r2"][-1]
    src = parts.sources["inspector"].state(res.log["t"][-1])
    np.testing.assert_allclose(up_r1[:, 0], src.p)  # r1 looks at the inspector ...
    np.testing.assert_allclose(down_r2, np.repeat(bs[:, None], down_r2.shape[1], axis=1))  # r2 at the base station
    last = {n: np.array([res.log[f"{n}.p_{a}"][-1] for a in "xyz"]) for n in ("r1", "r2")}
    assert np.linalg.norm(down_r1[:, 0] - last["r2"]) < 0.05  # ... r1 at r2's plan (one step old) ...
    assert np.linalg.norm(up_r2[:, 0] - last["r1"]) < 0.05  # ... and r2 at r1's
    assert np.linalg.norm(down_r1[:, -1] - down_r1[:, 0]) > 0  # a plan over the horizon, not a point held
    ref_moved = np.hypot(res.log["r1.pd_x"][-1] - res.log["r1.pd_x"][0], res.log["r1.pd_y"][-1] - res.log["r1.pd_y"][0])
    assert ref_moved > 0.05


@pytest.mark.parametrize("senses", [False, True])
def test_a_fleet_plans_with_the_jammer_state_it_senses(senses):
    """Review T6: the fleet loop planned with the nominal power whatever controller.senses_jammer_state
    said. An on_off jammer (5 s ON, 5 s OFF, localized at tau_E = 2 s): at t = 7 s it is OFF, so a fleet
    that senses its state plans with 0 W, one that does not with its nominal power."""
    from aerorelay.assembly.parts import build

    sc = parse_scenario(copy.deepcopy(CHAIN) | {"sim": {"duration_s": 7.1}}).with_updates(
        {"jammer.schedule": "on_off", "controller.senses_jammer_state": senses})
    parts = build(sc)
    inputs = recorded_inputs(parts)
    parts.closed_loop().run()
    seen = {round(inp.t, 6): np.array(inp.jammer_powers, float) for inp in inputs}
    at = {t: p for t, p in seen.items() if 6.9 <= t <= 7.05}
    assert at
    for p in at.values():
        np.testing.assert_allclose(p, [0.0] if senses else [sc.jammer.power_w])
    assert all(np.allclose(p, [sc.jammer.power_w]) for t, p in seen.items() if 3.0 <= t <= 4.9)  # ON, localized


def recorded_inputs(parts) -> list:
    """Every FleetInput the fleet's planner is handed from now on (the planner wrapped in place)."""
    seen: list = []

    class Recorder:
        def __init__(self, inner):
            self.inner = inner

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def update(self, inp):
            seen.append(inp)
            return self.inner.update(inp)
    parts.planner = Recorder(parts.planner)
    return seen
