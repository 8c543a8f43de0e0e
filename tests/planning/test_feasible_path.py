"""The flyable path: exactly at the speed limit, from the relay's start, holdable axes, its
capacity the scene's (recomputed with the numpy channel), never worse than its first guess."""

import numpy as np
import pytest

from aerorelay.models.axes import axis_cone
from aerorelay.planning.bound import CapacityLandscape, compute_bound
from aerorelay.planning.feasible_path import _flyable_or_guess, best_feasible_path, speed_limited
from aerorelay.scenario import load_scenario
from aerorelay.scenario.build import bound_problem

SHORT = load_scenario("scenarios/nominal_tilted.toml").with_updates({"sim.duration_s": 6.0})


@pytest.fixture(scope="module")
def problem():
    pb = bound_problem(SHORT)
    return pb, compute_bound(pb), CapacityLandscape(pb.scene, pb.source, pb.vehicle.gravity)


def test_speed_limited_chases_a_path_at_most_one_step_per_sample():
    path = np.array([[0.0, 0, 0], [3.0, 0, 0], [3.0, 4.0, 0], [3.0, 4.0, 0]])
    out = speed_limited(path, np.zeros(3), 1.0)
    u = np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)  # from (1, 0, 0) the target (3, 4, 0) lies along (1, 2)
    np.testing.assert_allclose(out, [[0, 0, 0], [1, 0, 0], [1, 0, 0] + u, [1, 0, 0] + 2 * u], atol=1e-12)


@pytest.mark.parametrize("kind", ["mean", "maxmin"])
def test_flyable_path_is_flyable_and_its_capacity_is_the_scenes(problem, kind):
    pb, b, land = problem
    v, limit = SHORT.bound.max_speed_m_s, pb.vehicle.hover_tilt_limit
    grid_path = b.path_mean_position if kind == "mean" else b.path_maxmin_position
    fp = best_feasible_path(land, b.t, grid_path, pb.relay_start, pb.workspace_min, pb.workspace_max, v, limit, kind,
                            max_accel=SHORT.bound.max_accel_m_s2)
    assert fp.status == "Solve_Succeeded"
    dt = b.t[1] - b.t[0]
    np.testing.assert_allclose(fp.position[0], pb.relay_start)  # its own start, not the nearest cell
    moves = np.diff(np.vstack([fp.position[:1], fp.position]), axis=0)  # from rest
    assert np.linalg.norm(moves, axis=1).max() <= v * dt * (1 + 1e-6)  # Euclidean, no allowance
    a = SHORT.bound.max_accel_m_s2
    assert np.linalg.norm(np.diff(moves, axis=0), axis=1).max() <= a * dt**2 * (1 + 1e-6)  # and accelerating at <= a
    assert np.all(fp.position >= pb.workspace_min) and np.all(fp.position <= pb.workspace_max)
    assert np.degrees(np.arccos(fp.axis[:, 2])).max() <= np.degrees(limit) + 1e-6
    again = np.array([land.capacity(t, fp.position[k][None], fp.axis[k][None])[0, 0] for k, t in enumerate(b.t)])
    np.testing.assert_allclose(fp.capacity, again, rtol=2e-3)  # the symbolic dipole's regularization
    # at least as good as its first guess (the grid path pulled back to the speed limit, best axis of a fine cone)
    guess = speed_limited(grid_path, pb.relay_start, v * dt, SHORT.bound.max_accel_m_s2 * dt**2)
    axes = axis_cone(limit, np.radians(2.0))
    g = np.array([land.capacity(t, guess[k][None], axes)[0].max() for k, t in enumerate(b.t)])
    if kind == "mean":
        assert fp.capacity.mean() >= g.mean() * (1 - 2e-3)
    else:
        assert fp.capacity.min() >= g.min() * (1 - 2e-3)


def test_speed_and_acceleration_limited_chase_changes_its_move_by_at_most_dv():
    path = np.array([[0.0, 0, 0], [3.0, 0, 0], [3.0, 4.0, 0], [3.0, 4.0, 0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    out = speed_limited(path, np.zeros(3), 1.0, 0.4)
    moves = np.diff(np.vstack([out[:1], out]), axis=0)
    assert np.linalg.norm(moves, axis=1).max() <= 1.0 + 1e-12
    assert np.linalg.norm(np.diff(moves, axis=0), axis=1).max() <= 0.4 + 1e-12
    np.testing.assert_allclose(out[1], [0.4, 0.0, 0.0])  # from rest: one change of dv


def test_the_bound_carries_the_flyable_paths_below_its_grid_paths(problem):
    _, b, _ = problem
    s = b.summary()
    assert s["resolution"]["flyable_status"] == {"mean": "Solve_Succeeded", "maxmin": "Solve_Succeeded"}
    # the grid path may fly 1.41 m/s: over a take-off it reaches more than a path at exactly 1 m/s
    assert s["flyable_mean"]["mean"] < s["path_mean"]["mean"]
    assert s["flyable_mean"]["mean"] > 0.8 * s["path_mean"]["mean"]


def test_a_path_outside_the_limits_is_never_reported():
    p0 = np.zeros((3, 3))
    bad = np.array([[0.0, 0, 0], [2.0, 0, 0], [2.0, 0, 0]])  # a 2 m step where 1 m is allowed
    pos, ang = _flyable_or_guess(bad, None, p0, None, -np.ones(3) * 5, np.ones(3) * 5, 1.0, 0.0, "Maximum_Iterations_Exceeded")
    np.testing.assert_array_equal(pos, p0)
    pos, _ = _flyable_or_guess(np.full((3, 3), np.nan), None, p0, None, -np.ones(3) * 5, np.ones(3) * 5, 1.0, 0.0, "x")
    np.testing.assert_array_equal(pos, p0)


def test_bad_inputs_are_refused(problem):
    pb, b, land = problem
    with pytest.raises(ValueError, match="kind"):
        best_feasible_path(land, b.t, b.path_mean_position, pb.relay_start, pb.workspace_min, pb.workspace_max, 1.0, 0.1, "best")
    with pytest.raises(ValueError, match="guess"):
        best_feasible_path(land, b.t, b.path_mean_position[:-1], pb.relay_start, pb.workspace_min, pb.workspace_max, 1.0, 0.1)
