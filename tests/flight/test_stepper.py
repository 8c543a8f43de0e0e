"""The step API (``ar.controller``): stepped over aerorelay's plant it reproduces ``ar.simulate`` bit
for bit (the paper's controller, the capacity-seeking one, and in gusty wind with its observer);
stale input holds within one period, then lands, and a fresh state resumes the NMPC; the command's
setpoints are the model's state one period ahead."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly import world
from aerorelay.assembly.parts import build
from aerorelay.assembly.vehicle import thrust_along_body_z
from aerorelay.sim.closed_loop import plant_step_function, step_count

DURATION = 0.6


def _fly_stepped(sc):
    """``ar.controller(sc)`` stepped over the plant ``ar.simulate`` flies (the same wind series when windy)."""
    ctrl = ar.controller(sc).one_relay()
    parts = build(sc)
    veh = parts.relay("relay").vehicle
    plant = plant_step_function(veh, sc.sim.plant_rate_hz, sc.control_period_s)
    air = world.air(sc, {"relay": (veh, sc.platform)})
    x = veh.hover_state(sc.nodes.relay)
    xs, us = [], []
    for k in range(step_count(sc.duration_s, sc.control_period_s)):
        t = k * sc.control_period_s
        s = parts.sources["source"].state(t)
        if air is not None:
            air.begin()
        cmd = ctrl.step(t, x, ar.SourceState(s.p, s.v, s.a))
        xs.append(x.copy())
        us.append(cmd.omega_dot_hz_s)
        x = air.advance("relay", x, cmd.omega_dot_hz_s, np.zeros(6)) if air else np.asarray(plant(x, cmd.omega_dot_hz_s, np.zeros(6))).ravel()
    return np.array(xs), np.array(us)


@pytest.mark.parametrize("updates", [
    {},
    {"controller.planner": "capacity"},
    {"controller.planner": "capacity", "wind": {"mean_m_s": [6.0, 0.0, 0.0], "gusts": True}},
], ids=["paper", "capacity", "capacity-in-gusts"])
def test_stepping_reproduces_simulate_bit_for_bit(updates):
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates({"sim.duration_s": DURATION, **updates})
    log = ar.simulate(sc).timeseries
    xs, us = _fly_stepped(sc)
    cols = ["relay.p_x", "relay.p_y", "relay.p_z", "relay.phi", "relay.theta", "relay.psi", "relay.v_x", "relay.v_y", "relay.v_z"]
    assert np.array_equal(log[cols].to_numpy(), xs[:, :9])
    assert np.array_equal(log[[f"relay.u_{i}" for i in range(1, 7)]].to_numpy(), us)


@pytest.fixture(scope="module")
def stepped():
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates({"sim.duration_s": 5.0})
    ctrl = ar.controller(sc).one_relay()
    parts = build(sc)
    return sc, ctrl, parts


def test_stale_input_holds_within_one_period_then_lands_then_resumes(stepped):
    sc, ctrl, parts = stepped
    T = sc.control_period_s
    veh = parts.relay("relay").vehicle
    x = veh.hover_state(sc.nodes.relay)
    s = parts.sources["source"].state(0.0)
    src = ar.SourceState(s.p, s.v, s.a)
    first = ctrl.step(0.0, x, src)
    assert first.mode == "nmpc" and first.rotor_speeds_hz is not None
    hold_after = ctrl.stale.hold_after_s
    # the last state was measured at t = 0; one period after it became too old, the command holds
    t = hold_after + T
    held = ctrl.step(t, None, src)
    assert held.mode == "hold" and held.rotor_speeds_hz is None
    assert np.array_equal(held.position_m, x[0:3]) and np.array_equal(held.velocity_m_s, np.zeros(3))
    # a state with an old stamp is stale too
    assert ctrl.step(t, x, src, state_stamp=0.0).mode == "hold"
    # longer still: land straight down at the landing speed, never below the ground
    t_land = ctrl.stale.land_after_s + T
    a = ctrl.step(t_land, None, src)
    b = ctrl.step(t_land + 1.0, None, src)
    assert a.mode == b.mode == "land"
    assert b.position_m[2] == pytest.approx(a.position_m[2] - ctrl.stale.land_speed_m_s, abs=1e-12)
    assert np.array_equal(b.position_m[:2], x[0:2]) and b.velocity_m_s[2] == -ctrl.stale.land_speed_m_s
    late = ctrl.step(t_land + 100.0, None, src)
    assert late.position_m[2] == sc.world.ground_z_m and np.array_equal(late.velocity_m_s, np.zeros(3))
    # a fresh state resumes the NMPC
    assert ctrl.step(t_land + 100.0 + T, x, ar.SourceState(s.p, s.v, s.a)).mode == "nmpc"


def test_the_command_is_the_model_one_period_ahead(stepped):
    sc, _, parts = stepped
    ctrl = ar.controller(sc).one_relay()
    veh = parts.relay("relay").vehicle
    x = veh.hover_state(sc.nodes.relay)
    s = parts.sources["source"].state(0.0)
    cmd = ctrl.step(0.0, x, ar.SourceState(s.p, s.v, s.a))
    x1 = np.asarray(veh.rk4_step(x, cmd.omega_dot_hz_s, sc.control_period_s))
    assert np.array_equal(cmd.position_m, x1[0:3]) and np.array_equal(cmd.velocity_m_s, x1[6:9])
    assert np.allclose(cmd.rotor_speeds_hz, x[12:] + cmd.omega_dot_hz_s * sc.control_period_s)
    assert abs(np.linalg.norm(cmd.attitude_wxyz) - 1) < 1e-12
    assert cmd.thrust_normalized == pytest.approx(1.0, abs=0.05)  # from hover, one period later
    assert cmd.deadline_met == (cmd.compute_ms <= sc.control_period_s * 1e3)


def test_a_networks_controller_honours_autopilot_stale_and_observer():
    """``ar.controller`` on a fleet is the same controller as on one relay (``control.network.Controller``; one relay
    and one source through the ``OneRelay`` adapter): ``autopilot``, ``stale`` and ``observer`` reach every relay
    (each was dropped for a network before), and jammers are estimated from readings when the scenario says so."""
    from aerorelay.control.network import Controller, OneRelay

    chain = ar.load_scenario("scenarios/chain_two_relays.toml", set={"wind.mean_m_s": [3.0, 0.0, 0.0]})
    stale = ar.StaleSettings(hold_after_s=0.2, land_after_s=9.0)
    ctrl = ar.controller(chain, autopilot=True, stale=stale)
    assert isinstance(ctrl, Controller) and ctrl.stale == stale
    for i, r in enumerate(chain.relay_list):
        part = ctrl.relay(r.name).stepper
        assert part.stale == stale and part.observer is not None  # [wind] gives every relay its observer
        assert np.allclose(part.vehicle.axes, [0.0, 0.0, 1.0])  # an autopilot's thrust along body z
        assert not np.allclose(ar.controller(chain).relay(r.name).vehicle.axes, [0.0, 0.0, 1.0]) or \
            chain.platform_of(i).tilt_deg == 0
    assert all(ar.controller(chain, observer=False).relay(n).stepper.observer is None for n in ctrl.relays)
    made = ar.controller(ar.load_scenario("scenarios/nominal_tilted.toml"), stale=stale)
    assert isinstance(made, Controller) and made.stale == stale  # the same type for one relay
    one = made.one_relay()
    assert isinstance(one, OneRelay) and one.network is made
    with pytest.raises(ValueError, match="one relay and one source"):
        ctrl.one_relay()
    estimating = ar.controller(ar.load_scenario("scenarios/chain_two_relays.toml", set={"jammer.localization": "estimated"}))
    assert isinstance(estimating, Controller) and estimating.estimated is not None


def test_a_networks_relay_with_bad_telemetry_is_held_by_name_and_the_others_fly():
    """One relay's 1 km telemetry jump or NaN state is not trusted: that relay holds where it last was and its command
    says why, the other relay's NMPC flies on (before, the network took the jump as its state and commanded 1 km out
    of the workspace, and a NaN raised for the whole fleet); a NaN source holds every relay, naming it."""
    sc = ar.load_scenario("scenarios/chain_two_relays.toml", set={"sim.duration_s": 1.0})
    ctrl, parts = ar.controller(sc), build(sc)
    x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
    T = sc.control_period_s
    s = parts.sources["inspector"].state(0.0)
    src = {"inspector": ar.SourceState(s.p, s.v, s.a)}
    ctrl.step(0.0, x, src)
    jumped = {**x, "r2": x["r2"] + np.r_[1000.0, np.zeros(x["r2"].size - 1)]}
    cmds = ctrl.step(T, jumped, src)
    assert cmds["r2"].mode == "hold" and "jumped" in cmds["r2"].rejected
    assert np.array_equal(cmds["r2"].position_m, x["r2"][0:3])
    assert cmds["r1"].mode in ("nmpc", "fallback") and cmds["r1"].rejected is None
    nan = {**x, "r2": np.full_like(x["r2"], np.nan)}
    cmds = ctrl.step(2 * T, nan, src)
    assert cmds["r2"].mode == "hold" and "not finite" in cmds["r2"].rejected and cmds["r1"].mode in ("nmpc", "fallback")
    bad_source = {"inspector": ar.SourceState(np.full(3, np.nan), s.v, s.a)}
    cmds = ctrl.step(3 * T, x, bad_source)
    assert all(c.mode == "hold" and "source inspector: source not finite" in c.rejected for c in cmds.values())


ESTIMATING = {"sim.duration_s": 5.0, "jammer.localization": "estimated", "jammer.inr_db_at_relay_start": 10.0,
              "estimation.use_bs": True, "estimation.confident_std_m": 7.0}  # confident within the 5 s: the planner uses it


def test_stepping_with_the_logged_readings_reproduces_an_estimating_simulate_bit_for_bit():
    """The readings ar.simulate's receivers took at each step, handed to the next step, give the same
    estimate, plan and flight: the step API estimates the jammers as the simulation does."""
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates(ESTIMATING)
    log = ar.simulate(sc).mission.log
    assert np.nanmin(log["est_jammer_std_m"]) < sc.estimation.confident_std_m  # the planner did get the jammer
    ctrl, parts = ar.controller(sc).one_relay(), build(sc)
    plant = plant_step_function(parts.relay("relay").vehicle, sc.sim.plant_rate_hz, sc.control_period_s)
    x = parts.relay("relay").vehicle.hover_state(sc.nodes.relay)
    for k in range(len(log["t"])):
        t = k * sc.control_period_s
        assert np.array_equal(x[0:3], [log["relay.p_x"][k], log["relay.p_y"][k], log["relay.p_z"][k]]), f"step {k}"
        s = parts.sources["source"].state(t)
        readings = {r: log[f"meas_{r}_w"][k - 1] for r in ("relay", "bs")} if k else None
        cmd = ctrl.step(t, x, ar.SourceState(s.p, s.v, s.a), readings=readings)
        x = np.asarray(plant(x, cmd.omega_dot_hz_s, np.zeros(6))).ravel()


def test_readings_are_checked_by_receiver():
    with pytest.raises(ValueError, match="not estimated"):
        ar.controller(ar.load_scenario("scenarios/nominal_tilted.toml")).one_relay().step(0.0, None, None, readings={"relay": 1.0})
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates({"jammer.localization": "estimated"})
    ctrl = ar.controller(sc).one_relay()
    x, s = ctrl.vehicle.hover_state(sc.nodes.relay), build(sc).sources["source"].state(0.0)
    with pytest.raises(ValueError, match=r"readings from \['bs'\]"):
        ctrl.step(0.0, x, ar.SourceState(s.p, s.v, s.a), readings={"bs": 1e-9})


def test_the_first_input_keeps_every_motor_within_its_bounds(stepped):
    # the plan predicts a hover; what is measured is a motor 0.05 Hz above its lower bound and a gust's
    # velocity, rate and tilt: the sensitivity feedback (the predicted solution's active set) took such a
    # motor to 11.55 Hz, under its 16 Hz bound (two of these twelve draws, before the first input was clipped)
    sc, _, parts = stepped
    veh = parts.relay("relay").vehicle
    ts = sc.controller.ts_s
    s = parts.sources["source"].state(0.0)
    rng = np.random.default_rng(0)
    for trial in range(12):
        ctrl = ar.controller(sc).one_relay()
        x = veh.hover_state(sc.nodes.relay)
        ctrl.step(0.0, x, ar.SourceState(s.p, s.v, s.a))
        x[12 + trial % 6] = veh.omega_min + 0.05
        x[6:9] += rng.normal(0, 1.5, 3)
        x[9:12] += rng.normal(0, 1.0, 3)
        x[3:5] += rng.normal(0, 0.1, 2)
        cmd = ctrl.step(ts, x, ar.SourceState(s.p, s.v, s.a))
        nxt = x[12:] + cmd.omega_dot_hz_s * ts
        assert np.all(nxt >= veh.omega_min - 1e-9) and np.all(nxt <= veh.omega_max + 1e-9), (trial, nxt)
        assert np.all(cmd.omega_dot_hz_s >= veh.omega_dot_min) and np.all(cmd.omega_dot_hz_s <= veh.omega_dot_max)


def test_for_an_autopilot_the_nmpc_models_thrust_along_body_z():
    """An autopilot keeps its thrust along body z: the NMPC that gives it setpoints plans with the rotors
    untilted (a tilted hexarotor through the cascade: 0.60 m and unsafe with its tilted model, 0.17 m and
    safe with this one: docs/decisions.md)."""
    tilted = ar.load_scenario("scenarios/nominal_tilted.toml")
    axes = ar.controller(tilted, autopilot=True).relay("relay").vehicle.axes
    assert np.allclose(axes, [0.0, 0.0, 1.0]) and not np.allclose(ar.controller(tilted).relay("relay").vehicle.axes, [0.0, 0.0, 1.0])
    quad = ar.load_scenario("scenarios/quad_x.toml")
    assert thrust_along_body_z(quad).platform == quad.platform  # already along body z
    outward = [r.model_dump() | {"axis": [0.5 * r.position[0], 0.5 * r.position[1], 1.0]} for r in quad.platform.rotors]
    tilted_custom = quad.with_updates({"platform.rotors": outward})  # every rotor tilted outward alike: it hovers
    untilted = thrust_along_body_z(tilted_custom).platform.rotors
    assert [r.axis for r in untilted] == [[0.0, 0.0, 1.0]] * 4
    assert [r.position for r in untilted] == [r.position for r in quad.platform.rotors]
