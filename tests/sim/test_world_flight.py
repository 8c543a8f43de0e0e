"""Flying in the world: a pole in the capacity-seeking relay's way is kept out of (no step inside,
its references moved out of the margin, the supervisor never needed), and in a steady 8 m/s wind
the external-force observer makes the NMPC track better than without it, its estimate meeting the
drag the plant applied."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.models.obstacles import VerticalCylinder

POLE = {"name": "pole", "kind": "cylinder", "centre_m": [-5.0, 4.2], "radius_m": 0.4, "z_min_m": 0.0, "z_max_m": 20.0,
        "margin_m": 0.5}


@pytest.fixture(scope="module")
def nominal():
    return ar.load_scenario("scenarios/nominal_tilted.toml")


def test_a_pole_in_the_way_is_kept_out_of(nominal):
    # without the pole the relay passes 0.73 m from its axis at t = 2 s (inside radius + margin = 0.9 m)
    sc = nominal.with_updates({"controller.planner": "capacity", "sim.duration_s": 8.0, "obstacles": [POLE]})
    r = ar.simulate(sc)
    m = r.metrics
    assert not m["unsafe"] and m["safety_violations"] == 0
    assert m["reference_kept_out_steps"] > 0  # the pole was in the way
    p = r.timeseries[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    bare = VerticalCylinder((-5.0, 4.2), 0.4, 0.0, 20.0)
    assert np.min(bare.signed_distance(p)) == pytest.approx(m["obstacle_clearance_min_m"])
    assert m["obstacle_clearance_min_m"] > 0.25  # outside the pole, most of the margin kept (soft constraint)


def _windy(nominal, observer: bool):
    sc = nominal.with_updates({"controller.planner": "capacity", "sim.duration_s": 8.0,
                               "wind": {"mean_m_s": [8.0, 0.0, 0.0], "observer": observer}})
    return ar.simulate(sc)


def test_the_observer_tracks_better_in_a_steady_wind(nominal):
    on, off = _windy(nominal, True), _windy(nominal, False)
    assert on.metrics["position_error_mean_m"] < 0.8 * off.metrics["position_error_mean_m"]
    assert on.metrics["wind_speed_mean_m_s"] == pytest.approx(8.0)  # computed from the logged wind series (steady: 8 m/s)
    df = on.timeseries
    late = df[df.t > 4.0]
    est = late[["relay.a_ext_x", "relay.a_ext_y", "relay.a_ext_z"]].to_numpy()
    drag = late[["relay.a_drag_x", "relay.a_drag_y", "relay.a_drag_z"]].to_numpy()
    assert np.mean(np.linalg.norm(est - drag, axis=1)) < 0.1 * np.mean(np.linalg.norm(drag, axis=1))
    assert "relay.a_ext_x" not in off.timeseries and "relay.a_drag_x" in off.timeseries
