"""Several base stations (``[[base_stations]]``) and routes that end at ``"any"``: the network's rate at
every step is its serving base station's, recomputed here from the logged poses with the paper's channel
written out (``tests/reference_channel.py``); with no margin and no dwell the serving one is the best at
every step; the handover rule never switches faster than its dwell time nor for less than its margin
(a property over random rates); planners and bounds score the best base station (max over candidates:
checked against every combination of concrete routes); ``nodes.bs`` is the one-station spelling."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.models.geometry import rotation_zyx
from aerorelay.models.radio import ChannelState, NodePose, network_rate
from aerorelay.sim.handover import Handover, HandoverRule
from tests.reference_channel import end_to_end_capacity, link_sinr
from tests.scenario_files import scenario_from_text

CROSSING = """
name = "handover_cross"
[[base_stations]]
name = "west"
position = [0.0, 0.0, 0.0]
[[base_stations]]
name = "east"
position = [24.0, 0.0, 0.0]
[[relays]]
name = "r1"
start = [3.0, 2.0, 2.0]
[[sources]]
name = "inspector"
[sources.mission]
waypoints = [[0.0, 4.0, 6.0, 3.0], [16.0, 20.0, 6.0, 3.0]]
[network]
handover_margin_db = 0.0
handover_dwell_s = 0.0
[controller]
planner = "capacity"
[controller.capacity]
speed_m_s = 2.0
[controller.workspace]
min = [-2.0, -2.0, 0.5]
max = [26.0, 10.0, 6.0]
[jammer]
position = [12.0, -1.5, 1.0]
power_w = 40.0
"""
STATIONS = {"west": np.array([0.0, 0.0, 0.0]), "east": np.array([24.0, 0.0, 0.0])}


def _scenario(tmp_path, text=CROSSING, name="cross.toml"):
    return scenario_from_text(tmp_path, text, name)


@pytest.fixture(scope="module")
def crossing(tmp_path_factory):
    sc = _scenario(tmp_path_factory.mktemp("handover"))
    return sc, ar.simulate(sc)


def _reference_rates(sc, ts):
    """Each base station's route rate at every logged step: eq. 5-9 from the logged poses (dipoles along body z,
    the base stations' vertical, the isotropic jammer at its position)."""
    jam = sc.jammer_configs[0]
    p_src = ts[["inspector.p_x", "inspector.p_y", "inspector.p_z"]].to_numpy()
    p_rel = ts[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy()
    eta_src = ts[["inspector.phi", "inspector.theta", "inspector.psi"]].to_numpy()
    eta_rel = ts[["r1.phi", "r1.theta", "r1.psi"]].to_numpy()
    out = {b: np.empty(len(ts)) for b in STATIONS}
    for k in range(len(ts)):
        R2, R1 = rotation_zyx(eta_src[k]), rotation_zyx(eta_rel[k])
        kw = dict(tx_power=1.0, jam_power=jam.power_w, noise_power=1.0)
        g21 = link_sinr(p_src[k], R2, p_rel[k], R1, jam.position, **kw)
        for b, p0 in STATIONS.items():
            g10 = link_sinr(p_rel[k], R1, p0, np.eye(3), jam.position, **kw)
            out[b][k] = float(end_to_end_capacity(g21, g10))
    return out


def test_with_no_margin_and_no_dwell_the_network_rate_is_the_best_base_stations_at_every_step(crossing):
    sc, r = crossing
    ts = r.timeseries
    ref = _reference_rates(sc, ts)
    for b in STATIONS:
        np.testing.assert_allclose(ts[f"capacity_via.inspector.{b}"], ref[b], rtol=1e-9)
    best = np.maximum(ref["west"], ref["east"])
    np.testing.assert_allclose(ts["capacity"], best, rtol=1e-9)
    serving = ts["inspector.base_station"].to_numpy()
    np.testing.assert_allclose(ts["capacity"], np.where(serving == "west", ref["west"], ref["east"]), rtol=1e-9)
    # the crossing is flown: both serve, and the metrics count what the log shows
    m = r.metrics
    assert set(serving) == {"west", "east"}
    assert m["handovers"] == int(np.sum(serving[1:] != serving[:-1])) >= 1
    assert sum(m["routes"]["inspector"]["served_fraction"].values()) == pytest.approx(1.0)
    assert not m["unsafe"], m["unsafe_reason"]


def test_the_dwell_and_margin_hold_in_flight(tmp_path, crossing):
    """A margin and a dwell: the serving base station is kept until the other is better by the margin, and a
    handover comes at the first step it is (recomputed rates), never within the dwell of the last one."""
    margin, dwell = 2.0, 3.0
    text = CROSSING.replace("handover_margin_db = 0.0", f"handover_margin_db = {margin}").replace(
        "handover_dwell_s = 0.0", f"handover_dwell_s = {dwell}")
    sc = _scenario(tmp_path, text)
    ts = ar.simulate(sc).timeseries
    ref = _reference_rates(sc, ts)
    serving = ts["inspector.base_station"].to_numpy()
    t = ts["t"].to_numpy()
    switches = np.flatnonzero(serving[1:] != serving[:-1]) + 1
    assert len(switches) >= 1
    assert np.all(np.diff(np.r_[0.0, t[switches]]) >= dwell - 1e-9)
    other = {"west": "east", "east": "west"}
    # before each switch the step's serving base station was the one of the step before
    for k in switches:
        assert 10 * math.log10(ref[serving[k]][k] / ref[serving[k - 1]][k]) > margin
    kept = np.setdiff1d(np.arange(1, len(t)), switches)
    last = np.searchsorted(switches, kept, side="right")  # the last switch at or before each step kept
    since = t[kept] - np.where(last > 0, t[switches[np.maximum(last - 1, 0)]], 0.0)
    # a step that kept its base station: the other was not better by the margin, or the dwell had not passed
    later_gain = np.array([10 * math.log10(ref[other[serving[k - 1]]][k] / ref[serving[k - 1]][k]) for k in kept])
    assert np.all((later_gain <= margin + 1e-9) | (since < dwell + 1e-9))
    np.testing.assert_allclose(ts["capacity"], np.where(serving == "west", ref["west"], ref["east"]), rtol=1e-9)


def _state(rates):
    return ChannelState(hops=(), sinr=(), interference=(), capacity=np.asarray(max(rates)), route_capacity=(),
                        candidates=(tuple(np.asarray(r) for r in rates),))


@settings(max_examples=60, deadline=None)
@given(rates=st.lists(st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 10.0)), min_size=2, max_size=60),
       margin=st.sampled_from([0.0, 1.0, 3.0]), dwell=st.sampled_from([0.0, 0.1, 0.35]))
def test_the_handover_rule_switches_only_when_allowed_and_always_when_it_should(two_stations, rates, margin, dwell):
    """The rule as stated: the first step takes the best; then a switch only when the other beats the serving
    one by more than the margin (a dead serving one: any live one) and the dwell has passed; and whenever both
    hold, a switch."""
    scene = two_stations
    rule = Handover(HandoverRule(margin, dwell))
    dt = 0.05
    serving, since = None, 0.0
    for k, (a, b) in enumerate(rates):
        t = k * dt
        ends = rule.decide(t, scene, _state((a, b)))
        if ends is not None:
            scene = scene.serving_routes(ends)
        now = scene.all_routes[0][-1]
        if serving is None:
            assert now == ("west" if a >= b else "east")
            serving, since = now, t
            continue
        c = {"west": a, "east": b}
        other = "east" if serving == "west" else "west"
        better = c[other] > 0 and (c[serving] <= 0 or 10 * (math.log10(c[other]) - math.log10(c[serving])) > margin)
        may = t - since >= dwell - 1e-9
        assert (now != serving) == (better and may)
        if now != serving:
            serving, since = now, t


@pytest.fixture(scope="module")
def two_stations(tmp_path_factory):
    return ar.build_scene(_scenario(tmp_path_factory.mktemp("two")))


def test_a_scene_scores_the_best_base_station_of_each_route_as_the_best_of_every_combination(tmp_path):
    """Two sources, each route to "any" of two base stations: "best" is the best of the four concrete networks
    (every combination of ends, each a plain scene), "serving" is the concrete network of the serving ends."""
    text = CROSSING.replace('[[sources]]\nname = "inspector"', '[[sources]]\nname = "inspector"').replace(
        "[network]", '[[sources]]\nname = "second"\n[sources.mission]\nwaypoints = [[0.0, 20.0, 2.0, 4.0], '
        '[16.0, 6.0, 2.0, 4.0]]\n[[relays]]\nname = "r2"\nstart = [20.0, 2.0, 2.0]\n[network]\n'
        'routes = [["inspector", "r1", "any"], ["second", "r2", "any"]]\nplanner = "capacity"')
    sc = _scenario(tmp_path, text, "two.toml")
    scene = ar.build_scene(sc)
    assert scene.handover == (("west", "east"), ("west", "east"))
    rng = np.random.default_rng(4)
    for _ in range(20):
        poses = {n: NodePose(rng.uniform([-2, -2, 0.5], [26, 10, 6]), rotation_zyx(rng.uniform(-0.3, 0.3, 3))[:, 2])
                 for n in ("inspector", "second", "r1", "r2")}
        best = float(scene.evaluate(0.0, poses).capacity)
        plain = replace(scene, handover=())
        rates = {ends: float(plain.serving(ends).evaluate(0.0, poses).capacity)
                 for ends in itertools.product(("west", "east"), repeat=2)}
        assert best == pytest.approx(max(rates.values()), rel=1e-12)
        for ends, rate in rates.items():
            served = scene.serving(ends).evaluate(0.0, poses, ends="serving")
            assert float(served.capacity) == pytest.approx(rate, rel=1e-12)
            per_route = [[s for (tx, rx), s in zip(served.hops, served.sinr, strict=True) if (tx, rx) in
                          list(zip(route[:-1], route[1:], strict=True))] for route in scene.serving(ends).all_routes]
            assert float(network_rate(per_route)) == pytest.approx(rate, rel=1e-12)


def test_the_compiled_grid_scores_the_best_base_station(two_stations):
    """The capacity planner's compiled grid (CasADi, max over the candidates as fmax) equals the numpy scene's."""
    from aerorelay.planning.relay_grid import CompiledRelayGrid

    scene = two_stations.world_view()
    P = np.array([[2.0, 1.0, 2.0], [12.0, 1.0, 3.0], [22.0, 2.0, 2.0]])
    B = np.array([[0.0, 0.0, 1.0], [0.3, 0.0, 0.954], [0.0, -0.3, 0.954]])
    B = B / np.linalg.norm(B, axis=1, keepdims=True)
    src = NodePose(np.array([15.0, 6.0, 3.0]), np.array([0.0, 0.0, 1.0]))
    pj, PJ = np.array([[12.0, -1.5, 1.0]]), np.array([40.0])
    grid = CompiledRelayGrid(scene, len(P), len(B), source="inspector", relay="r1")
    expected = scene.relay_grid(0.0, P, B, {"inspector": src}, jammer_positions=pj, jammer_powers=PJ, relay="r1")
    np.testing.assert_allclose(grid(P, B, src, pj, PJ), expected, rtol=1e-4)


def test_nodes_bs_is_the_one_station_spelling(tmp_path):
    one = _scenario(tmp_path, "[nodes]\nbs = [1.0, 2.0, 0.0]\n", "a.toml")
    named = _scenario(tmp_path, '[[base_stations]]\nname = "bs"\nposition = [1.0, 2.0, 0.0]\n', "b.toml")
    assert ar.build_scene(one).describe() == ar.build_scene(named).describe()
    assert one.route_list == named.route_list == [["source", "relay", "bs"]]
    assert not one.has_handover and named.has_two_hops


@pytest.mark.parametrize("text, field", [
    ('[nodes]\nbs = [1.0, 0.0, 0.0]\n[[base_stations]]\nname = "a"\nposition = [0.0, 0.0, 0.0]\n', "nodes.bs"),
    ('[[base_stations]]\nname = "any"\nposition = [0.0, 0.0, 0.0]\n', "base_stations.0.name"),
    ('[[base_stations]]\nname = "a"\nposition = [0.0, 0.0, 0.0]\n[[base_stations]]\nname = "b"\nposition = [0.0, 0.0, 0.05]\n',
     "base_stations[1].position"),
    ('[[base_stations]]\nname = "a"\nposition = [0.0, 0.0, 0.0]\n[[base_stations]]\nname = "b"\nposition = [9.0, 0.0, 0.0]\n'
     '[network]\nroutes = [["source", "relay", "c"]]\n', "network.routes[0]"),
    ('[[base_stations]]\nname = "a"\nposition = [0.0, 0.0, 0.0]\n[[base_stations]]\nname = "b"\nposition = [9.0, 0.0, 0.0]\n',
     "controller.planner"),
    ('[[base_stations]]\nname = "a"\nposition = [0.0, 0.0, -1.0]\n', "base_stations[0].position"),
])
def test_bad_base_stations_are_named_errors(tmp_path, text, field):
    with pytest.raises(ScenarioError, match=field.replace("[", r"\[").replace("]", r"\]")):
        _scenario(tmp_path, text, "bad.toml")
