"""Radio blockage (sim/blockage.py): a segment crosses a box or a cylinder exactly when a line
through it does by hand, and in the plant a link through an obstacle with ``nlos_loss_db`` loses
exactly that many dB (the others none); without the field an obstacle lets radio through."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import build_scene
from aerorelay.assembly.world import blockage, obstacles
from aerorelay.models.obstacles import Box, VerticalCylinder
from aerorelay.sim.blockage import crosses

WALL = {"name": "wall", "kind": "box", "min_m": [-4.0, 2.0, 0.0], "max_m": [-3.0, 4.0, 3.0], "margin_m": 0.2}


def test_segments_against_shapes_by_hand():
    box = Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    assert crosses(box, np.array([-1.0, 0.5, 0.5]), np.array([2.0, 0.5, 0.5]))
    assert not crosses(box, np.array([-1.0, 1.5, 0.5]), np.array([2.0, 1.5, 0.5]))  # passes beside it
    assert not crosses(box, np.array([-1.0, 0.5, 0.5]), np.array([-0.1, 0.5, 0.5]))  # ends before it
    pole = VerticalCylinder((0.0, 0.0), 0.5, 0.0, 10.0)
    assert crosses(pole, np.array([-3.0, 0.3, 5.0]), np.array([3.0, 0.3, 5.0]))
    assert not crosses(pole, np.array([-3.0, 0.6, 5.0]), np.array([3.0, 0.6, 5.0]))
    assert not crosses(pole, np.array([-3.0, 0.0, 11.0]), np.array([3.0, 0.0, 11.0]))  # over its top


def test_a_blocked_link_loses_its_stated_loss():
    sc = ar.parse_scenario({"obstacles": [{**WALL, "nlos_loss_db": 20.0}]})
    scene, b = build_scene(sc), blockage(sc)
    # the relay behind the wall as seen from the base station at the origin: the relay -> bs hop is blocked
    positions = {"relay": np.array([-6.0, 5.0, 1.5]), "source": np.array([-6.0, 6.0, 3.0]), "bs": np.zeros(3)}
    gains, values = b.step(scene, 0.0, positions)
    ends = scene.link_ends()
    for k, (tx, rx, _) in enumerate(ends):
        blocked = {tx, rx} == {"relay", "bs"}
        assert gains[k] == pytest.approx(0.01 if blocked else 1.0)
        assert values[f"nlos_{tx}_{rx}"] == float(blocked)
    assert crosses(obstacles(sc, margin=False)[0], positions["relay"], positions["bs"])


def test_an_obstacle_without_a_loss_lets_radio_through():
    sc = ar.parse_scenario({"obstacles": [WALL]})
    assert not blockage(sc).active


def test_a_flight_logs_its_blocked_links():
    """The relay starts at (-6.95, 5.79, 1.72): its line to the base station crosses the wall at
    x = -3.5 m, y = 2.9 m, z = 0.87 m (by hand), inside the box; the source's line to the relay does
    not. The blocked hop's SINR at t = 0 is the unblocked run's times 10^(-20/10)."""
    wall = {**WALL, "nlos_loss_db": 20.0}
    r = ar.simulate(ar.parse_scenario({"obstacles": [wall], "sim": {"duration_s": 0.3}}))
    clear = ar.simulate(ar.parse_scenario({"obstacles": [WALL], "sim": {"duration_s": 0.3}}))
    df, df0 = r.timeseries, clear.timeseries
    assert df["nlos_relay_bs"].iloc[0] == 1.0 and df["nlos_source_relay"].iloc[0] == 0.0
    assert df["sinr.relay.bs"].iloc[0] == pytest.approx(df0["sinr.relay.bs"].iloc[0] * 10 ** (-20 / 10), rel=1e-9)
    assert df["sinr.source.relay"].iloc[0] == pytest.approx(df0["sinr.source.relay"].iloc[0], rel=1e-9)
