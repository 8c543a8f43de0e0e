"""The step API of a network (issue 50, item 2): ``ar.controller`` on a fleet steps every relay from outside
(states by name in, commands by name out, the relays' plans exchanged inside); stepped over aerorelay's
plant it reproduces ``ar.simulate`` of the same fleet bit for bit, as the one relay's does."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import world
from aerorelay.assembly.parts import build
from aerorelay.control.network import Controller
from aerorelay.models.geometry import rotation_zyx
from aerorelay.sim.closed_loop import step_count


def _fly_stepped(sc):
    """``ar.controller(sc)`` stepped over the plant ``ar.simulate`` flies (in ``[wind]``, the same wind series)."""
    ctrl = ar.controller(sc)
    assert isinstance(ctrl, Controller) and ctrl.relays == [r.name for r in sc.relay_list]
    parts = build(sc)  # the plant and the sources' paths ar.simulate flies
    x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
    plants = {r.name: r.plant for r in parts.relays}
    air = world.air(sc, {r.name: (r.vehicle, sc.platform_of(i)) for i, r in enumerate(parts.relays)})
    states, inputs = [], []
    for k in range(step_count(sc.duration_s, sc.control_period_s)):
        t = k * sc.control_period_s
        sources = {name: ar.SourceState(s.p, s.v, s.a) for name, path in parts.sources.items() for s in [path.state(t)]}
        if air is not None:
            air.begin()
        cmds = ctrl.step(t, x, sources)
        assert set(cmds) == set(x) and all(c.mode in ("nmpc", "fallback") for c in cmds.values())
        states.append({n: xs.copy() for n, xs in x.items()})
        inputs.append({n: c.omega_dot_hz_s for n, c in cmds.items()})
        x = {n: air.advance(n, x[n], cmds[n].omega_dot_hz_s, np.zeros(6)) if air is not None else
             np.asarray(plants[n](x[n], cmds[n].omega_dot_hz_s, np.zeros(6))).ravel() for n in x}
    return states, inputs


GUSTS = {"wind": {"mean_m_s": [6.0, 0.0, 0.0], "gusts": True}}


@pytest.mark.parametrize("preset, updates", [("chain_two_relays", {}), ("two_sources", {}), ("chain_two_relays", GUSTS)],
                         ids=["chain", "two-sources", "chain-in-gusts"])
def test_stepping_a_fleet_reproduces_simulate_bit_for_bit(preset, updates):
    """In gusty wind each relay's external-force observer is the controller's own, as ar.simulate gives every relay."""
    sc = ar.load_scenario(f"scenarios/{preset}.toml", set={"sim.duration_s": 0.6}).with_updates(updates)
    if updates:
        assert all(ar.controller(sc).relay(r.name).stepper.observer is not None for r in sc.relay_list)
    log = ar.simulate(sc).timeseries
    states, inputs = _fly_stepped(sc)
    for r in sc.relay_list:
        n = r.name
        cols = [f"{n}.{q}" for q in ("p_x", "p_y", "p_z", "phi", "theta", "psi", "v_x", "v_y", "v_z")]
        assert np.array_equal(log[cols].to_numpy(), np.array([s[n][:9] for s in states])), n
        assert np.array_equal(log[[f"{n}.u_{i}" for i in range(1, 7)]].to_numpy(), np.array([u[n] for u in inputs])), n


def test_a_fleets_step_needs_every_relay_and_source_and_says_which():
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 0.3})
    ctrl = ar.controller(sc)
    parts = build(sc)
    x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
    s = parts.sources["inspector"].state(0.0)
    with pytest.raises(ValueError, match=r"no trusted state for \['r2'\]"):
        ctrl.step(0.0, {"r1": x["r1"]}, {"inspector": ar.SourceState(s.p, s.v, s.a)})
    with pytest.raises(ValueError, match=r"relay_states\['r1'\] must be"):
        ctrl.step(0.0, {**x, "r1": x["r1"][:5]}, {"inspector": ar.SourceState(s.p, s.v, s.a)})
    with pytest.raises(ValueError, match=r"a network needs one airframe per relay"):
        ar.fly_lockstep(sc, ar.plant_airframe(sc))


def test_a_relay_whose_state_stops_holds_then_lands_while_the_others_fly_on():
    """r2's state missing from 0.3 s: it holds where it last was (a position setpoint, no rotor command), lands
    once missing for land_after_s (3 s), the network planning with its last state; r1 keeps its NMPC; r2's state
    back, its NMPC again. A missing source holds every relay and says why."""
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 10.0})
    ctrl, parts = ar.controller(sc), build(sc)
    x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
    plants = {r.name: r.plant for r in parts.relays}
    T = sc.control_period_s
    modes = []
    last_r2 = None
    for k in range(int(3.9 / T)):
        t = k * T
        s = parts.sources["inspector"].state(t)
        states = dict(x) if not (20 <= k < 20 + int(3.3 / T)) else {"r1": x["r1"]}  # r2 silent for 3.3 s
        if "r2" in states:
            last_r2 = x["r2"].copy()
        cmds = ctrl.step(t, states, {"inspector": ar.SourceState(s.p, s.v, s.a)})
        modes.append((cmds["r1"].mode, cmds["r2"].mode))
        if cmds["r2"].mode in ("hold", "land"):
            assert cmds["r2"].rotor_speeds_hz is None
            assert np.allclose(cmds["r2"].position_m[:2], last_r2[:2])  # where it last was (landing: straight down)
        x = {n: np.asarray(plants[n](x[n], cmds[n].omega_dot_hz_s, np.zeros(6))).ravel() if cmds[n].omega_dot_hz_s is not None
             else x[n] for n in x}
    r1, r2 = zip(*modes, strict=True)
    assert set(r1) <= {"nmpc", "fallback"}
    assert r2[19] == "nmpc" and r2[20] == "hold" and r2[20 + int(3.0 / T) + 2] == "land" and r2[-1] == "nmpc"
    cmds = ctrl.step(len(modes) * T, x, {"inspector": None})
    assert all(c.mode == "hold" and "no source" in (c.rejected or "") for c in cmds.values())


def test_a_fleets_step_estimates_its_jammer_from_every_relays_readings():
    """The chain with its jammer estimated: each step is handed what r1's and r2's receivers measured over the
    last period (the true interference plus the noise where they were, computed here from the scene), folded
    into one estimate the planner flies on; after 4 s it is within 2 m of the jammer."""
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={
        "sim.duration_s": 10.0, "jammer.localization": "estimated",
        "estimation.search_min_m": [-10.0, -40.0, 0.0], "estimation.search_max_m": [70.0, 20.0, 15.0]})  # the jammer inside
    ctrl, parts = ar.controller(sc), build(sc)
    scene, noise = parts.scene, parts.scene.budget.noise_power
    x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
    T, readings = sc.control_period_s, None
    for k in range(int(4.0 / T)):
        t = k * T
        s = parts.sources["inspector"].state(t)
        cmds = ctrl.step(t, x, {"inspector": ar.SourceState(s.p, s.v, s.a)}, readings=readings)
        poses = {n: scene.pose(n, xs[0:3], rotation_zyx(xs[3:6])) for n, xs in x.items()}
        poses["inspector"] = scene.pose("inspector", s.p, rotation_zyx(s.attitude()))
        state = scene.evaluate(t, poses)
        readings = {rx: float(state.interference[h]) + noise for h, (_, rx) in enumerate(state.hops) if rx in ("r1", "r2")}
        x = {r.name: np.asarray(r.plant(x[r.name], cmds[r.name].omega_dot_hz_s, np.zeros(6))).ravel() for r in parts.relays}
    positions, _, _ = ctrl.jammers(4.0)
    truth = scene.jammers[0].position_at(4.0)
    assert np.linalg.norm(positions[0] - truth) < 2.0
