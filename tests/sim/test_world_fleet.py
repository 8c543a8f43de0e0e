"""A fleet in the world: every relay meets the wind through its own drag and observer, keeps out of
an obstacle's margin, and a hop through a radio-blocking obstacle is logged blocked; the fleet's
log carries each relay's columns."""

from __future__ import annotations

import numpy as np

import aerorelay as ar

# a building between r2 (20, -1, 6) and the base station at the origin: the r2 -> bs hop crosses it
BUILDING = {"name": "building", "kind": "box", "min_m": [8.0, -3.0, 0.0], "max_m": [10.0, 3.0, 12.0], "margin_m": 1.0,
            "nlos_loss_db": 15.0}


def test_a_chain_flies_in_wind_among_obstacles():
    sc = ar.load_scenario("scenarios/chain_two_relays.toml").with_updates({
        "sim.duration_s": 1.5, "wind": {"mean_m_s": [0.0, 6.0, 0.0], "gusts": True}, "obstacles": [BUILDING]})
    r = ar.simulate(sc)
    df, m = r.timeseries, r.metrics
    for name in ("r1", "r2"):
        assert {f"{name}.a_drag_y", f"{name}.a_ext_y"} <= set(df)
        assert df[f"{name}.a_drag_y"].iloc[-1] > 0  # pushed along the wind
        assert m["relays"][name]["obstacle_clearance_min_m"] > 0 and "wind_speed_mean_m_s" in m["relays"][name]
    assert df["nlos_r2_bs"].iloc[0] == 1.0 and df["nlos_inspector_r1"].iloc[0] == 0.0
    assert not m["unsafe"] and np.isfinite(df["capacity"]).all()
