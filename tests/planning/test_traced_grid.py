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
    with pytest.raises(ScenarioError, match=r"controller\.capacity\.scoring: 'traced' scores a fixed route; a route to 'any'"):
        updated(ar.parse_scenario(two), {**PHYSICAL, "controller.planner": "capacity", "controller.capacity.scoring": "traced",
                                         "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty"})


@needs_rt
def test_a_relay_scoring_on_the_traced_channel_flies():
    sc = ar.load_scenario("scenarios/street_canyon.toml", set={"sim.duration_s": 1.0, "controller.planner": "capacity",
                                                               "controller.capacity.scoring": "traced",
                                                               "controller.capacity.route_grid_m": 3.0,  # 200 cells
                                                               "controller.workspace.min": [-42.0, -6.0, 4.0],
                                                               "controller.workspace.max": [-20.0, 8.0, 16.0]})
    r = ar.simulate(sc)
    assert not r.metrics["unsafe"] and r.metrics["c_min"] > 0


FLEET = {"channel.units": "physical", "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty",
         "controller.planner": "capacity", "controller.capacity.scoring": "traced"}


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
    with pytest.raises(ScenarioError, match=r"controller\.planner = 'equidistant' scores none"):
        updated(ar.load_scenario("scenarios/chain_two_relays.toml"), {**FLEET, "controller.planner": "equidistant"})


EMPTY = {**PHYSICAL, "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty",
         "channel.propagation.max_depth": 0, "channel.propagation.rays_per_source": 10_000}


@needs_rt
def test_the_bound_on_the_traced_map_of_an_empty_scene_is_the_free_space_grids_best_cell():
    # the traced bound (every cell traced at every instant, not refined between cells) equals, in free space, the best
    # cell and axis of the analytic landscape (Friis at the cells: float32 tracing aside) and its path DP's values,
    # and stays at or below the analytic bound refined off the grid
    from dataclasses import replace

    from aerorelay.assembly.parts import bound_problem
    from aerorelay.models.axes import axis_cone
    from aerorelay.planning.bound import CapacityLandscape, compute_bound, position_grid
    sc = ar.parse_scenario({}).with_updates({**EMPTY, "bound.grid_m": 3.0, "bound.dt_s": 5.0, "sim.duration_s": 20.0})
    pb = bound_problem(sc)
    assert pb.tracer is not None
    traced = compute_bound(pb)
    analytic = CapacityLandscape(pb.scene, pb.source, pb.vehicle.gravity)
    _, cells = position_grid(pb.workspace_min, pb.workspace_max, 3.0)
    axes = axis_cone(pb.vehicle.hover_tilt_limit, np.radians(5.0))
    best = np.array([analytic.capacity(t, cells, axes).max() for t in traced.t])
    np.testing.assert_allclose(traced.static, best, rtol=3e-4)
    refined = compute_bound(replace(pb, tracer=None))
    assert np.all(traced.static <= refined.static * (1 + 3e-4))
    assert np.all(traced.path_mean <= traced.static * (1 + 1e-9))
    assert traced.resolution["flyable_status"]["mean"] == "not refined (traced channel)"


@needs_rt
def test_the_traced_route_of_an_empty_scene_is_the_free_space_route():
    # scoring 'traced' plans the pre-flight route on the traced map: in free space the analytic route (same DP, values to
    # float32), in a few traces: the base station's to the cells once, the source's once per instant
    from aerorelay.assembly import world
    from aerorelay.assembly.parts import build_planner, build_source
    from aerorelay.assembly.vehicle import build_vehicle
    from aerorelay.models.raytrace import RayTracer
    over = {**EMPTY, "controller.planner": "capacity", "controller.capacity.route_grid_m": 3.0,
            "controller.capacity.route_dt_s": 4.0, "sim.duration_s": 20.0}
    routes = {}
    for scoring in ("joint", "traced"):
        sc = ar.parse_scenario({}).with_updates(over | {"controller.capacity.scoring": scoring})
        before = world.map_tracer(sc).calls  # the process's one tracer of these settings
        planner = build_planner(sc, build_vehicle(sc.platform), build_scene(sc), build_source(sc))
        routes[scoring] = planner.route_p
        if scoring == "traced":
            assert isinstance(planner.grid, TracedRelayGrid)
            tracer = planner.grid.network.tracer
            assert isinstance(tracer, RayTracer) and tracer is world.map_tracer(sc)
            assert tracer.calls - before <= len(planner.route_t) + 1
    np.testing.assert_allclose(routes["traced"], routes["joint"], atol=1e-9)


@needs_rt
def test_a_traced_route_too_long_to_trace_is_refused_naming_its_grid():
    with pytest.raises(ScenarioError, match=r"controller\.capacity\.route_grid_m: the pre-flight route on the traced map"):
        ar.parse_scenario({}).with_updates({**EMPTY, "channel.propagation.rays_per_source": 10_000_000, "controller.planner":
                                            "capacity", "controller.capacity.scoring": "traced",
                                            "controller.capacity.route_grid_m": 0.5})


@needs_rt
def test_a_fleets_network_bound_on_the_traced_map_of_an_empty_scene_is_the_brute_force_best_configuration(tmp_path, monkeypatch):
    # two relays in a chain under a jammer, in an empty scene: the traced network bound's static value equals the best
    # pair of open cube centres by brute force from Friis, each relay's dipole at its best axis of the cone toward each
    # hop and its least jammer interference over the cone (float32 tracing aside); the configuration it flies with one
    # axis per relay and the upper path bound stay at or below it
    monkeypatch.setenv("AERORELAY_CACHE", str(tmp_path))
    from aerorelay.assembly.parts import network_bound_problem
    from aerorelay.assembly.world import trace_settings
    from aerorelay.models.axes import axis_cone
    from aerorelay.models.propagation import wavelength_m
    from aerorelay.planning.network_bound import NetworkBoundSolver
    from aerorelay.planning.traced_network_bound import compute_traced_network_bound
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={
        "channel.propagation.model": "ray_traced", "channel.propagation.scene": "empty", "channel.propagation.max_depth": 0,
        "channel.propagation.rays_per_source": 10_000, "bound.grid_m": 8.0, "bound.dt_s": 20.0,
        "sim.duration_s": 20.0})
    pb = network_bound_problem(sc)
    bound = compute_traced_network_bound(pb, RayTracer(trace_settings(sc)), coherent=False)
    solver = NetworkBoundSolver(pb)
    cells, b, lam = solver.cells, pb.scene.budget, wavelength_m(sc.channel.carrier_hz)
    axes = axis_cone(pb.tilt_limits["r1"], np.radians(5.0))
    dip = pb.scene.node("r1").antenna.pattern

    def friis(p, q):
        return (lam / (4 * np.pi * np.linalg.norm(np.asarray(q, float) - p, axis=-1))) ** 2

    def best(u):  # the relay's dipole at its best cone axis toward unit directions u (..., 3)
        return dip.gain_from_cos(u @ axes.T).max(axis=-1)

    for k, t in enumerate(bound.t):
        poses = solver.fixed_poses(float(t))
        src, bs = poses["inspector"], poses["bs"]
        jam = pb.scene.emitters(float(t), poses)[0]

        def unit(v):
            return v / np.linalg.norm(v, axis=-1, keepdims=True)

        u_j = unit(cells - jam.position)
        i_relay = jam.power * friis(jam.position, cells) * jam.pattern.gain_from_cos(u_j @ jam.axis) * \
            dip.gain_from_cos(-u_j @ axes.T).min(axis=-1)
        u_bj = unit(bs.position - jam.position)
        i_bs = jam.power * float(friis(jam.position, bs.position) * jam.pattern.gain_from_cos(u_bj @ jam.axis)
                                 * pb.scene.node("bs").antenna.pattern.gain_from_cos(-u_bj @ bs.axis))

        def term(signal, interference):
            return 1.0 / np.log2(1.0 + signal * b.tx_power / (interference + b.noise_power))

        u_s = unit(cells - src.position)  # inspector -> r1
        t_s1 = term(friis(src.position, cells) * pb.scene.node("inspector").antenna.pattern.gain_from_cos(u_s @ src.axis)
                    * best(-u_s), i_relay)
        u_b = unit(bs.position - cells)  # r2 -> bs
        t_2b = term(friis(cells, bs.position) * best(u_b) * pb.scene.node("bs").antenna.pattern.gain_from_cos(-u_b @ bs.axis), i_bs)
        d = cells[None, :, :] - cells[:, None, :]  # r1 (rows) -> r2
        dist = np.linalg.norm(d, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = d / dist[..., None]
            t_12 = term((lam / (4 * np.pi * dist)) ** 2 * best(u) * best(-u), i_relay[None, :])
        total = t_s1[:, None] + t_12 + t_2b[None, :]
        total[dist < pb.separation_m] = np.inf
        brute = b.bandwidth / np.min(total)
        np.testing.assert_allclose(bound.static[k], brute, rtol=3e-4)
    assert np.all(bound.achieved <= bound.static * (1 + 3e-4)) and np.all(bound.path_mean <= bound.static * (1 + 1e-9))
    assert bound.resolution["flyable_status"].startswith("not refined (traced channel)") and len(bound.flyable) == len(bound.t)


@needs_rt
def test_a_fleets_network_bound_on_a_fine_traced_map_is_refused_naming_its_grid():
    from aerorelay.assembly.parts import check_bound_size
    sc = ar.load_scenario("scenarios/street_canyon_chain.toml", set={"bound.grid_m": 2.0})
    with pytest.raises(ScenarioError, match=r"bound\.grid_m: the bound would take"):
        check_bound_size(sc)


@needs_rt
def test_a_traced_bound_of_routes_to_any_base_station_is_refused_before_any_work():
    from aerorelay.assembly.parts import check_bound_size
    two = {"base_stations": [{"name": "a", "position": [0.0, 0.0, 0.0]}, {"name": "b", "position": [9.0, 0.0, 0.0]}]}
    sc = updated(ar.parse_scenario(two), {**PHYSICAL, "channel.propagation.model": "ray_traced",
                                          "channel.propagation.scene": "empty", "bound.grid_m": 3.0,
                                          "controller.planner": "capacity"})
    assert sc.has_handover
    with pytest.raises(ScenarioError, match=r"bound: routes that may end at several base stations"):
        check_bound_size(sc)
