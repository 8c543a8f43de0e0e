"""The one relay's capacity planner never sets a goal on its source: candidates closer than
``network.min_separation_m`` to the source (now and as predicted) are moved out to it. In the street canyon
the relay started 5 m behind the inspector, which flies away along its path: without the clearance it flew
to 0.69 m of it (reported unsafe); with it, the flight keeps the separation."""

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.planning.capacity_planner import away_from


def test_points_inside_the_clearance_move_out_along_the_line_from_the_centre():
    c = np.array([1.0, 2.0, 3.0])
    pts = np.array([[1.5, 2.0, 3.0], [1.0, 2.0, 3.0], [4.0, 2.0, 3.0], [1.0, 2.6, 3.8]])
    out = away_from(pts, c, 2.0)
    np.testing.assert_allclose(out[0], [3.0, 2.0, 3.0])
    np.testing.assert_allclose(out[1], [1.0, 2.0, 5.0])  # on the centre: straight up
    np.testing.assert_array_equal(out[2], pts[2])  # outside: unchanged
    assert np.linalg.norm(out[3] - c) == pytest.approx(2.0) and np.allclose(np.cross(out[3] - c, pts[3] - c), 0.0)


def test_the_capacity_relay_keeps_its_distance_from_the_inspector_in_the_street():
    sc = ar.load_scenario("scenarios/street_canyon.toml", set={"controller.planner": "capacity", "sim.duration_s": 6.0,
                                                               "channel.propagation.model": "free_space"})
    m = ar.simulate(sc).metrics
    assert m["separation_min_m"] >= sc.separation_m and not m["unsafe"]
