"""The capacity planner's candidates scored on the ray-traced channel (``planning/traced_grid.py``): in an empty
scene every candidate pose's capacity is the compiled free-space grid's (float32 tracing aside), the jammer
and the relay-to-base-station hop (traced from the base station) included; a traced scoring without a
traced channel is a named error. Needs the ``rt`` extra."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.load import updated
from aerorelay.assembly.parts import build_scene
from aerorelay.config import ScenarioError
from aerorelay.models.radio import NodePose
from aerorelay.models.raytrace import RayTracer, TraceSettings
from aerorelay.planning.relay_grid import CompiledRelayGrid
from aerorelay.planning.traced_grid import TracedRelayGrid
from tests.rt_marks import needs_rt

PHYSICAL = {"channel.units": "physical", "jammer.inr_db_at_relay_start": 10.0}


@needs_rt
def test_in_an_empty_scene_the_traced_grid_is_the_free_space_grid():
    sc = ar.parse_scenario({}).with_updates(PHYSICAL)
    scene = build_scene(sc)
    rng = np.random.default_rng(3)
    P = rng.uniform([-6, -5, 1], [6, 5, 8], (7, 3))
    B = rng.normal(size=(5, 3)) * [0.3, 0.3, 1.0]
    B /= np.linalg.norm(B, axis=1, keepdims=True)
    src = NodePose(np.array([-3.0, 5.8, 1.7]), np.array([0.1, 0.0, 0.995]) / np.linalg.norm([0.1, 0.0, 0.995]))
    pj, PJ = np.array([[-6.95, -5.79, 1.72]]), np.array([scene.jammers[0].power])
    traced = TracedRelayGrid(scene, RayTracer(TraceSettings("empty", 2.4e9, max_depth=0), cached=False), source="source")
    want = CompiledRelayGrid(scene, len(P), len(B), source="source")(P, B, src, pj, PJ)
    np.testing.assert_allclose(traced(P, B, src, pj, PJ), want, rtol=2e-4)
    assert traced.traces == 1  # every link of every candidate in one trace


def test_traced_scoring_needs_a_traced_channel():
    with pytest.raises(ScenarioError, match=r"controller\.capacity\.scoring: 'traced'.*ray_traced"):
        updated(ar.parse_scenario({}), {**PHYSICAL, "controller.planner": "capacity", "controller.capacity.scoring": "traced"})


@needs_rt
def test_traced_scoring_of_a_route_to_any_base_station_is_a_named_error():
    two = {"base_stations": [{"name": "a", "position": [0.0, 0.0, 0.0]}, {"name": "b", "position": [9.0, 0.0, 0.0]}]}
    with pytest.raises(ScenarioError, match=r"controller\.capacity\.scoring: 'traced' scores the route to one base station"):
        updated(ar.parse_scenario(two), {**PHYSICAL, "controller.planner": "capacity", "controller.capacity.scoring": "traced",
                                         "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty"})


@needs_rt
def test_a_relay_scoring_on_the_traced_channel_flies():
    sc = ar.load_scenario("scenarios/street_canyon.toml", set={"sim.duration_s": 1.0, "controller.planner": "capacity",
                                                               "controller.capacity.scoring": "traced"})
    r = ar.simulate(sc)
    assert not r.metrics["unsafe"] and r.metrics["c_min"] > 0


FLEET = {"channel.units": "physical", "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty",
         "network.planner": "capacity", "controller.capacity.scoring": "traced"}


@needs_rt
def test_a_fleets_candidates_and_joint_moves_on_the_traced_channel_of_an_empty_scene_are_free_spaces():
    # a chain inspector -> r1 -> r2 -> bs under a jammer: each relay's grid with the other relay given (traced from the
    # fixed ends where one end moves) and the joint moves' configurations equal the compiled free-space ones
    from aerorelay.planning.relay_grid import CompiledConfigurations
    from aerorelay.planning.traced_grid import TracedConfigurations
    sc = ar.load_scenario("scenarios/chain_two_relays.toml")
    scene = build_scene(sc)
    tracer = RayTracer(TraceSettings("empty", sc.channel.carrier_hz, max_depth=0), cached=False)
    rng = np.random.default_rng(5)
    src = NodePose(np.array([58.0, 0.0, 8.0]), np.array([0.0, 0.0, 1.0]))
    pj, PJ = np.array([[30.0, -25.0, 2.0]]), np.array([scene.jammers[0].power])
    B = rng.normal(size=(4, 3)) * [0.3, 0.3, 1.0]
    B /= np.linalg.norm(B, axis=1, keepdims=True)
    for relay, other, at in (("r1", "r2", [20.0, -1.0, 6.0]), ("r2", "r1", [40.0, 1.0, 8.0])):
        P = rng.uniform([5, -10, 2], [55, 10, 20], (6, 3))
        others = (NodePose(np.array(at), B[0]),)
        traced = TracedRelayGrid(scene, tracer, source="inspector", relay=relay, moving=(other,))
        want = CompiledRelayGrid(scene, len(P), len(B), source="inspector", relay=relay, moving=(other,))(P, B, src, pj, PJ, others)
        np.testing.assert_allclose(traced(P, B, src, pj, PJ, others), want, rtol=2e-4)
    P = rng.uniform([5, -10, 2], [55, 10, 20], (3, 2, 3))
    A = B[rng.integers(0, len(B), (3, 2))]
    traced = TracedConfigurations(scene, tracer, ("r1", "r2"), ("inspector",))
    want = CompiledConfigurations(scene, ("r1", "r2"), ("inspector",), 3)(P, A, (src,), pj, PJ)
    np.testing.assert_allclose(traced(P, A, (src,), pj, PJ), want, rtol=2e-4)
    assert traced.network.traces == 1  # every link of every configuration in one trace


@needs_rt
def test_a_fleet_scoring_on_the_traced_channel_flies_and_scores_traced():
    from aerorelay.assembly.parts import build
    from aerorelay.planning.traced_grid import TracedConfigurations
    # traced scoring: the preset's; two decisions (0.25 s apart) on reflections of depth 1 (the suite's time)
    sc = ar.load_scenario("scenarios/street_canyon_chain.toml", set={"sim.duration_s": 0.3, "channel.propagation.max_depth": 1})
    planner = build(sc).planner
    assert all(isinstance(g, TracedRelayGrid) for g in planner.grids.values())
    assert isinstance(planner.configurations, TracedConfigurations)
    r = ar.simulate(sc)
    assert not r.metrics["unsafe"] and r.metrics["c_min"] > 0


def test_traced_scoring_in_a_network_needs_its_capacity_planner():
    with pytest.raises(ScenarioError, match=r"network\.planner = 'equidistant' scores none"):
        updated(ar.load_scenario("scenarios/chain_two_relays.toml"), {**FLEET, "network.planner": "equidistant"})
