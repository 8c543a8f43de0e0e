"""The flyable path: exactly at the speed limit, from the relay's start, holdable axes, its
capacity the scene's (recomputed with the numpy channel), never worse than its first guess."""

import numpy as np
import pytest

from aerorelay.assembly import load_scenario
from aerorelay.assembly.parts import bound_problem
from aerorelay.models.axes import axis_cone, tilted_axes
from aerorelay.planning.bound import CapacityLandscape, compute_bound
from aerorelay.planning.feasible_path import (
    _flyable_or_guess,
    best_feasible_path,
    leaning_capacity,
    path_accelerations,
    speed_limited,
    thrust_directions,
)

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
    assert np.linalg.norm(moves[1]) <= 0.5 * a * dt**2 * (1 + 1e-6)  # from rest: at most a dt^2 / 2 in the first step
    assert np.all(fp.position >= pb.workspace_min) and np.all(fp.position <= pb.workspace_max)
    assert np.degrees(np.arccos(fp.axis[:, 2])).max() <= np.degrees(limit) + 1e-6  # holdable in hover
    # and within the tilt limit of the thrust direction the path's acceleration needs (from the moves, by hand)
    acc = np.vstack([2 * moves[1], np.diff(moves[1:], axis=0)]) / dt**2  # from rest, then second differences
    acc = np.vstack([acc, acc[-1:]])[: len(b.t)]
    thrust = acc + pb.vehicle.gravity * np.array([0.0, 0.0, 1.0])
    lean_deg = np.degrees(np.arccos(np.clip(np.sum(fp.axis * thrust, axis=1) / np.linalg.norm(thrust, axis=1), -1, 1)))
    assert lean_deg.max() <= np.degrees(limit) + 1e-5
    again = np.array([land.capacity(t, fp.position[k][None], fp.axis[k][None])[0, 0] for k, t in enumerate(b.t)])
    np.testing.assert_allclose(fp.capacity, again, rtol=2e-3)  # the symbolic dipole's regularization
    # at least as good as its first guess (the grid path pulled back to the speed limit, best axis of a fine cone)
    guess = speed_limited(grid_path, pb.relay_start, v * dt, SHORT.bound.max_accel_m_s2 * dt**2)
    axes = axis_cone(limit, np.radians(2.0))
    dirs = np.asarray(thrust_directions(len(b.t), dt, pb.vehicle.gravity)(guess.T))
    g = np.array([np.where(axes @ dirs[:, k] >= np.cos(limit), land.capacity(t, guess[k][None], axes)[0], 0.0).max()
                  for k, t in enumerate(b.t)])
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
    np.testing.assert_allclose(out[1], [0.2, 0.0, 0.0])  # from rest: dv / 2 (a dt^2 / 2 at constant a)


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


def test_a_path_accelerating_beyond_the_limit_is_never_reported():
    """From rest, 0.6 m in the first 0.5 s needs 4.8 m/s^2 (2 d / dt^2) where 4 are allowed; 0.5 m
    is exactly at the limit; later, a second difference of 1.1 m over dt^2 = 0.25 s^2 is 4.4 m/s^2."""
    dt, T = 0.5, 3
    accels = path_accelerations(T, dt)
    box = (-np.ones(3) * 5, np.ones(3) * 5)
    p0 = np.zeros((T, 3))

    def flown(pos):
        ratio = lambda q: np.linalg.norm(np.asarray(accels(q.T))[:, :T - 1], axis=0) / 4.0  # noqa: E731
        return _flyable_or_guess(pos, None, p0, None, *box, 2.0, 0.0, "Solve_Succeeded", ratio)[0]

    ok = np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    np.testing.assert_array_equal(flown(ok), ok)
    np.testing.assert_array_equal(flown(np.array([[0.0, 0, 0], [0.6, 0, 0], [1.2, 0, 0]])), p0)
    np.testing.assert_array_equal(flown(np.array([[0.0, 0, 0], [0.5, 0, 0], [2.1, 0, 0]])), p0)


def test_an_axis_the_path_cannot_hold_while_accelerating_is_never_reported():
    # braking at 4 m/s^2 toward -x (thrust 22 deg toward -x) with the antenna 17 deg toward +x: 39 deg apart
    dt, limit = 0.5, np.radians(18.0)
    pos = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.0, 0, 0]])
    ang = np.array([[0.0, 0.0], [np.radians(17.0), 0.0], [0.0, 0.0]])
    dirs = np.asarray(thrust_directions(3, dt, 9.81)(pos.T))
    axes = tilted_axes(ang[:, 0], ang[:, 1])
    cos = np.sum(axes * dirs.T, axis=1)
    assert cos[1] < np.cos(limit)
    p0, a0 = np.zeros((3, 3)), np.zeros((3, 2))
    box = (-np.ones(3) * 5, np.ones(3) * 5)
    got, _ = _flyable_or_guess(pos, ang, p0, a0, *box, 1.0, limit, "Solve_Succeeded", None, lambda q, a: cos)
    np.testing.assert_array_equal(got, p0)
    got, _ = _flyable_or_guess(pos, ang, p0, a0, *box, 1.0, limit, "Solve_Succeeded", None, lambda q, a: np.ones(3))
    np.testing.assert_array_equal(got, pos)  # the same path with holdable axes is kept


def test_bad_inputs_are_refused(problem):
    pb, b, land = problem
    with pytest.raises(ValueError, match="kind"):
        best_feasible_path(land, b.t, b.path_mean_position, pb.relay_start, pb.workspace_min, pb.workspace_max, 1.0, 0.1, "best")
    with pytest.raises(ValueError, match="guess"):
        best_feasible_path(land, b.t, b.path_mean_position[:-1], pb.relay_start, pb.workspace_min, pb.workspace_max, 1.0, 0.1)


def test_thrust_directions_of_a_path_from_rest_by_hand():
    # 0.5 s samples: moves 0.5, 1.0, 0.5 m along x -> 4 m/s^2 over the first interval (from rest:
    # 2 * 0.5 / 0.25), then 2 and -2 m/s^2 (second differences), the last sample repeating
    P = np.array([[0.0, 0.5, 1.5, 2.0], [0.0] * 4, [0.0] * 4])
    got = np.asarray(thrust_directions(4, 0.5, 9.81)(P))
    for k, ax in enumerate([4.0, 2.0, -2.0, -2.0]):
        np.testing.assert_allclose(got[:, k], np.array([ax, 0.0, 9.81]) / np.hypot(ax, 9.81), atol=1e-12)


def test_leaning_capacity_scores_only_the_axes_the_path_can_lean_to(problem):
    """The large-scale fallback's capacity: at rest every axis of the hover cone counts; where the
    path accelerates (0.5 m in the first 0.5 s from rest: 4 m/s^2, thrust 22 deg off vertical) only
    the axes within the tilt limit of that thrust direction, worked out here by hand; where no
    axis is (1 m: 8 m/s^2, 39 deg), the nearest one."""
    pb, b, land = problem
    limit = pb.vehicle.hover_tilt_limit
    axes = axis_cone(limit, np.radians(5.0))
    times = np.array([2.0, 2.5, 3.0])
    rest = np.tile([-4.0, 3.0, 3.0], (3, 1))
    caps = np.array([land.capacity(float(t), rest[k][None], axes)[0] for k, t in enumerate(times)])
    np.testing.assert_allclose(leaning_capacity(land, times, rest, axes, limit), caps.max(axis=1))
    for first_move, some_held in ((0.5, True), (1.0, False)):
        moving = rest + np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]]) * first_move
        caps = np.array([land.capacity(float(t), moving[k][None], axes)[0] for k, t in enumerate(times)])
        a0 = np.array([2.0 * first_move / 0.25, 0.0, 9.81])  # from rest: 2 (p_1 - p_0) / dt^2, plus gravity
        cos = axes @ (a0 / np.linalg.norm(a0))
        held = cos >= np.cos(limit)
        assert (0 < held.sum() < len(axes)) if some_held else held.sum() == 0
        expected = caps[0][held].max() if some_held else caps[0][np.argmax(cos)]
        got = leaning_capacity(land, times, moving, axes, limit)
        assert got[0] == pytest.approx(expected, rel=1e-12)
        np.testing.assert_allclose(leaning_capacity(land, times, moving, axes, 0.0), caps.max(axis=1))  # coplanar: no lean
