"""Capacity bounds: upper bound per instant, dynamic programming against brute force, hover tilt."""

import itertools

import numpy as np
import pytest

from aerorelay.assembly import load_scenario, parse_scenario
from aerorelay.assembly.parts import bound_problem, build_scene, build_source
from aerorelay.assembly.vehicle import build_vehicle
from aerorelay.models.axes import axis_cone
from aerorelay.models.radio import NodePose
from aerorelay.planning.bound import CapacityLandscape, _dp, _footprint, compute_bound

SHORT = load_scenario("scenarios/nominal_tilted.toml").with_updates({"sim.duration_s": 2.0})


@pytest.fixture(scope="module")
def bound():
    return compute_bound(bound_problem(SHORT))


def test_random_feasible_poses_never_beat_the_static_bound(bound):
    """5000 random relay poses (position in the box, axis inside the hover-feasible cone) per
    instant: none exceeds the static bound by more than its stated 1% resolution."""
    rng = np.random.default_rng(7)
    scene = CapacityLandscape(build_scene(SHORT), build_source(SHORT), SHORT.platform.gravity_m_s2)
    ws = SHORT.controller.workspace
    limit = build_vehicle(SHORT.platform).hover_tilt_limit
    for k, t in enumerate(bound.t):
        P = rng.uniform(ws.min, ws.max, size=(5000, 3))
        tilt = limit * np.sqrt(rng.uniform(size=5000))
        az = rng.uniform(0, 2 * np.pi, size=5000)
        B = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        C = np.array([scene.capacity(t, P[i : i + 1], B[i : i + 1])[0, 0] for i in range(0, 5000, 10)])
        C_grid = scene.capacity(t, P, B[:1])  # all positions with one axis too
        assert max(C.max(), C_grid.max()) <= bound.static[k] * 1.01
        # and the bound itself is a real pose's capacity
        again = scene.capacity(t, bound.static_position[k][None], bound.static_axis[k][None])[0, 0]
        assert again == pytest.approx(bound.static[k], rel=1e-9)
        assert np.degrees(np.arccos(bound.static_axis[k][2])) <= np.degrees(limit) + 1e-6


def test_paths_start_at_the_relay_and_respect_the_speed_limit(bound):
    r = bound.resolution
    for pos in (bound.path_mean_position, bound.path_maxmin_position):
        assert np.linalg.norm(pos[0] - np.array(SHORT.nodes.relay)) <= np.sqrt(3) * r["grid_m"] / 2 + 1e-9
        steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
        assert steps.max() <= r["path_step_radius_m"] + 1e-9
        assert steps.max() / r["dt_s"] <= r["max_path_speed_m_s"] + 1e-9
    # the stated grid allowance (defaults 1 m/s, 0.5 m grid, 0.5 s): a diagonal cell, sqrt(2) x 0.5 m per 0.5 s
    assert (r["max_speed_m_s"], r["grid_m"], r["dt_s"]) == (1.0, 0.5, 0.5)
    assert r["max_path_speed_m_s"] == pytest.approx(np.sqrt(2.0))
    assert bound.path_mean.mean() >= bound.path_maxmin.mean() - 1e-12
    assert bound.path_maxmin.min() >= bound.path_mean.min() - 1e-12
    assert np.all(bound.static >= bound.path_mean - 1e-12)


@pytest.mark.parametrize("kind", ["mean", "maxmin"])
def test_dynamic_programming_matches_brute_force(kind):
    rng = np.random.default_rng(3 if kind == "mean" else 4)
    values = rng.uniform(size=(4, 3, 3, 2))
    fp = _footprint(1.0)  # face neighbours and staying put
    start = (1, 1, 0)
    path = _dp(values, start, fp, kind)
    score = (lambda p: sum(values[(k, *c)] for k, c in enumerate(p))) if kind == "mean" else \
        (lambda p: min(values[(k, *c)] for k, c in enumerate(p)))
    cells = list(itertools.product(range(3), range(3), range(2)))
    best = -np.inf
    for rest in itertools.product(cells, repeat=3):
        p = [start, *rest]
        if all(np.abs(np.subtract(a, b)).sum() <= 1 for a, b in zip(p, p[1:], strict=False)):
            best = max(best, score(p))
    assert score(path) == pytest.approx(best)


def test_hover_tilt_limit_is_zero_for_a_coplanar_platform_and_widens_with_the_rotor_tilt():
    limits = [build_vehicle(parse_scenario({"platform": {"tilt_deg": a}}).platform).hover_tilt_limit for a in (0.0, 20.0, 30.0)]
    assert limits[0] == 0.0 and 0.0 < limits[1] < limits[2] < np.radians(30.0)
    assert np.degrees(limits[1]) == pytest.approx(17.9, abs=0.3)
    assert axis_cone(0.0, np.radians(5)).shape == (1, 3)


def test_the_bound_searches_the_runs_own_shadowing_realization():
    """With log-normal shadowing the bound differs per seed (each run's field), its static optimum is the
    scene's capacity there with that seed's realized link gains (recomputed independently), and the plant
    flying through a pose sees the same realized gains as the bound at that pose."""
    sc = SHORT.with_updates({"channel.propagation.model": "log_distance", "channel.propagation.exponent": 2.5,
                             "channel.propagation.reference_loss_db": 0.0, "channel.propagation.shadowing_std_db": 6.0,
                             "channel.propagation.decorrelation_m": 5.0, "bound.grid_m": 1.0})
    b0 = compute_bound(bound_problem(sc))
    b1 = compute_bound(bound_problem(sc.with_updates({"seed": 1})))
    assert not np.allclose(b0.static, b1.static)
    pb = bound_problem(sc)
    scene, real = pb.scene, pb.realization
    k = 2
    t, p, axis = b0.t[k], b0.static_position[k], b0.static_axis[k]
    src = CapacityLandscape(scene, pb.source, sc.platform.gravity_m_s2).source_pose(t)
    where = {"relay": p, "source": src.position, "bs": np.zeros(3)}
    gains = [float(real.link(i, scene.jammers[j].position_at(t) if j is not None else where[tx], where[rx]).gain)
             for i, (tx, rx, j) in enumerate(scene.link_ends())]
    c = scene.evaluate(t, {"relay": NodePose(p, axis), "source": src}, fading=np.array(gains)).capacity
    assert float(c) == pytest.approx(b0.static[k], rel=1e-9)
    # without the realization the same pose has another capacity (the shadowing is there)
    assert float(scene.evaluate(t, {"relay": NodePose(p, axis), "source": src}).capacity) != pytest.approx(b0.static[k], rel=1e-3)
