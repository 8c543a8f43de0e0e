"""Building the NMPC's state from what an autopilot reports (issue 50, item 5): ``ar.AutopilotLoop``
with ``ar.Measured`` (position, rotation, velocity, body rates; no rotor speeds) steps the controller
as the MAVLink bridge and the ROS node do, and a state that can be stepped but not flown as meant is
named in a warning (once each): zero body rates while the attitude turns, rotor speeds all zero, a
position below the ground (NED passed as ENU)."""

from __future__ import annotations

import logging

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build_source
from aerorelay.models.state import ETA, OMEGA, ROTORS

NOMINAL = "scenarios/nominal_tilted.toml"


@pytest.fixture(scope="module")
def sc():
    return ar.load_scenario(NOMINAL)


def _source(sc, t):
    s = build_source(sc).state(t)
    return ar.SourceState(np.asarray(s.p), np.asarray(s.v), np.asarray(s.a), stamp=t)


def test_the_autopilot_loop_steps_from_what_an_autopilot_reports(sc):
    loop = ar.AutopilotLoop(ar.controller(sc, autopilot=True))
    p, T = np.array(sc.nodes.relay), loop.period
    assert loop.tick(0.0, {"relay": None}, {"source": _source(sc, 0.0)}) is None and loop.waiting == "relay: no relay state"
    cmds = [loop.tick(k * T, {"relay": ar.Measured(p, np.eye(3), np.zeros(3), np.zeros(3), k * T)},
                      {"source": _source(sc, k * T)})["relay"] for k in range(5)]
    assert all(c.mode == "nmpc" for c in cmds)
    np.testing.assert_allclose(loop.commanded["relay"].speeds, cmds[-1].rotor_speeds_hz)  # the speeds last commanded


def test_a_state_that_cannot_be_flown_is_named_once(sc, caplog):
    ctrl = ar.controller(sc).one_relay()
    x = ctrl.vehicle.hover_state(sc.nodes.relay)
    caplog.set_level(logging.WARNING, logger="aerorelay.control.relay_step")
    T = ctrl.period
    for k in range(8):  # the attitude turning at 0.05 rad/s, the body rates read zero (a simulator without them)
        x = x.copy()
        x[ETA] = [0.0, 0.0, 0.05 * k * T]
        x[OMEGA] = 0.0
        ctrl.step(k * T, x, _source(sc, k * T))
    assert sum("body rates read zero" in r.message for r in caplog.records) == 1
    y = x.copy()
    y[ROTORS] = 0.0
    ctrl.step(8 * T, y, _source(sc, 8 * T))
    assert any("rotor speeds are all zero" in r.message for r in caplog.records)
    z = x.copy()
    z[2] = -1.72  # the nominal start in NED
    ctrl2 = ar.controller(sc).one_relay()
    ctrl2.step(0.0, z, _source(sc, 0.0))
    assert any("NED position passed as ENU" in r.message for r in caplog.records)


def test_a_consistent_state_says_nothing(sc, caplog):
    ctrl = ar.controller(sc).one_relay()
    caplog.set_level(logging.WARNING, logger="aerorelay.control.relay_step")
    x = ctrl.vehicle.hover_state(sc.nodes.relay)
    x[3:6] = [0.05, 0.0, 0.0]
    x[9:12] = [0.0, 0.0, 0.0]
    for k in range(8):
        ctrl.step(k * ctrl.period, x, _source(sc, k * ctrl.period))
    assert not caplog.records
