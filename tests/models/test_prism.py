"""``kind = "prism"`` obstacles (issue 63, item 2, its first part): a convex footprint of any orientation extruded to a
height. An axis-aligned rectangle is the box (signed distance, nearest point, separating plane: tested on random
shapes and points); a turned footprint's distance equals the box formula in the footprint's own frame (computed
here, not by the prism); footprints that are not convex, repeat a corner or cross themselves are refused by name; a
relay flying past a turned wall keeps out of it with the paper's planner and the capacity planner."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.models.obstacles import Box, Prism, separating_planes

coord = st.floats(-20.0, 20.0, allow_nan=False)
size = st.floats(0.2, 10.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(x=coord, y=coord, z=st.floats(-2.0, 5.0), w=size, d=size, h=size, margin=st.floats(0.0, 2.0),
       seed=st.integers(0, 2**31 - 1))
def test_an_axis_aligned_prism_is_the_box(x, y, z, w, d, h, margin, seed):
    box = Box((x, y, z), (x + w, y + d, z + h), margin)
    prism = Prism(((x, y), (x + w, y), (x + w, y + d), (x, y + d)), z, z + h, margin)
    p = np.random.default_rng(seed).uniform([x - 5, y - 5, z - 5], [x + w + 5, y + d + 5, z + h + 5], (200, 3))
    np.testing.assert_allclose(prism.signed_distance(p), box.signed_distance(p), atol=1e-9)
    np.testing.assert_allclose(prism.closest_point(p), box.closest_point(p), atol=1e-9)
    (nb, cb), (npr, cp) = separating_planes(box, p), separating_planes(prism, p)
    far = np.abs(box.signed_distance(p)) > 1e-6  # on the surface the normal of a corner is a choice
    np.testing.assert_allclose(npr[far], nb[far], atol=1e-9)
    np.testing.assert_allclose(cp[far], cb[far], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(angle=st.floats(0.0, 2 * math.pi), w=size, d=size, seed=st.integers(0, 2**31 - 1))
def test_a_turned_footprint_is_the_box_in_its_own_frame(angle, w, d, seed):
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s], [s, c]])
    corners = [tuple(R @ np.array(v)) for v in ((0.0, 0.0), (w, 0.0), (w, d), (0.0, d))]
    prism = Prism(tuple(corners), 0.0, 3.0, 0.25)
    p = np.random.default_rng(seed).uniform(-12, 12, (300, 3))
    local = np.column_stack([p[:, :2] @ R, p[:, 2]])  # the points in the footprint's own frame (R^T p)
    np.testing.assert_allclose(prism.signed_distance(p), Box((0.0, 0.0, 0.0), (w, d, 3.0), 0.25).signed_distance(local),
                               atol=1e-9)


@pytest.mark.parametrize(("footprint", "needle"), [
    ([[0, 0], [2, 0], [2, 2], [1, 2], [1, 1], [0, 1]], "not convex"),  # an L
    ([[0, 0], [2, 0], [2, 0], [0, 2]], "repeats a corner"),
    ([[0, 0], [2, 2], [2, 0], [0, 2]], "not convex"),  # a bow tie
    ([[0, 0], [2, 0], [4, 0], [0, 2]], "not convex"),  # three corners in a line
    ([[0, 0], [2, 0, 1], [0, 2]], "every corner is [x, y]"),
])
def test_footprints_that_are_not_a_convex_polygon_are_named(footprint, needle):
    obstacle = {"name": "wall", "kind": "prism", "footprint_m": footprint, "z_min_m": 0.0, "z_max_m": 3.0}
    with pytest.raises(ScenarioError) as exc:
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"obstacles": [obstacle]})
    assert "obstacles" in str(exc.value) and needle in str(exc.value), str(exc.value)


def test_a_five_pointed_star_is_refused():
    star = tuple((math.cos(2 * math.pi * 2 * k / 5), math.sin(2 * math.pi * 2 * k / 5)) for k in range(5))
    with pytest.raises(ValueError, match="crosses itself"):
        Prism(star, 0.0, 1.0)


WALL_ANGLE = math.radians(50.0)  # across the relay's way (its bounding box: 1.52 x 1.72 m, not 2.0 x 0.3)


def _wall() -> list[list[float]]:
    c, s = math.cos(WALL_ANGLE), math.sin(WALL_ANGLE)
    centre = np.array([-5.2, 4.65])
    half = [np.array([c, s]) * 1.0, np.array([-s, c]) * 0.15]
    return [list(map(float, centre + sa * half[0] + sb * half[1])) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))]


@pytest.mark.parametrize("planner", ["trajectory_generator", "capacity"])
def test_a_relay_flies_past_a_turned_wall_without_entering_it(planner):
    """Without the wall both planners fly 0.15 m inside it (measured); with it the relay keeps out."""
    wall = {"name": "wall", "kind": "prism", "footprint_m": _wall(), "z_min_m": 0.0, "z_max_m": 3.0, "margin_m": 0.4}
    sc = ar.load_scenario("scenarios/nominal_tilted.toml",
                          set={"controller.planner": planner, "sim.duration_s": 8.0, "obstacles": [wall]})
    r = ar.simulate(sc)
    m = r.metrics
    assert not m["unsafe"] and m["safety_violations"] == 0
    p = r.timeseries[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    bare = Prism(tuple(tuple(c) for c in _wall()), 0.0, 3.0)
    assert np.min(bare.signed_distance(p)) == pytest.approx(m["obstacle_clearance_min_m"])
    assert m["obstacle_clearance_min_m"] > 0.1  # outside the wall, most of the margin kept (soft constraint)
