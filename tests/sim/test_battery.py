"""A relay's battery (issue 51, item 2, its model): the state of charge logged per relay is the usable
energy left after the rotors' shaft power (``sum_i c_tau Omega_i^3 2 pi``, written here from the rotor
model's constants) and the avionics' load drawn over every step before, from the logged rotor speeds;
hovering, it is the hover power times the time; the reserve's first time is the first step at or below
it; no battery table, no columns (every number as before: tests/sim/test_one_machinery.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aerorelay as ar

CAPACITY_WH, USABLE, RESERVE, AVIONICS_W = 0.17, 0.9, 0.2, 15.0  # 2.3 s at hover: no empty battery in 2 s


def _flown(duration_s=2.0, capacity_wh=CAPACITY_WH):
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={
        "sim.duration_s": duration_s, "platform.battery": {"capacity_wh": capacity_wh, "usable_fraction": USABLE,
                                                           "reserve_fraction": RESERVE, "avionics_w": AVIONICS_W,
                                                           "go_home": False}})  # holding: the hover's energy (flying home:
    # tests/sim/test_going_home.py)
    return sc, ar.simulate(sc)


def test_the_state_of_charge_is_the_energy_drawn_by_the_rotors_and_the_avionics():
    sc, r = _flown()
    df, T = r.timeseries, sc.control_period_s
    speeds = df[[f"relay.Omega_{i}" for i in range(1, 7)]].to_numpy()
    power = np.sum(sc.platform.c_tau * speeds**3 * 2.0 * math.pi, axis=1) + AVIONICS_W  # W, each step's start
    usable_j = CAPACITY_WH * 3600.0 * USABLE
    want = 1.0 - np.r_[0.0, np.cumsum(power * T)[:-1]] / usable_j
    np.testing.assert_allclose(df["relay.soc"].to_numpy(), want, rtol=1e-12, atol=1e-12)
    # a relay holding near its start draws about the hover power: the rotor model's hover speeds
    hover = ar.api.vehicle(sc).hover_speeds()
    hover_power = float(np.sum(sc.platform.c_tau * hover**3 * 2.0 * math.pi)) + AVIONICS_W
    t_end = float(df["t"].iloc[-1])
    assert 1.0 - df["relay.soc"].iloc[-1] == pytest.approx(hover_power * t_end / usable_j, rel=0.02)
    reached = df["relay.soc"].to_numpy() <= RESERVE
    assert reached.any()  # 0.17 Wh: the reserve within 2 s
    assert r.metrics["battery_reserve_first_s"] == pytest.approx(float(df["t"].to_numpy()[np.argmax(reached)]))
    assert r.metrics["soc_final_fraction"] == pytest.approx(float(df["relay.soc"].iloc[-1]))
    assert df["relay.battery_reserve"].dtype == bool and r.metrics["units"]["soc_final_fraction"] == "1"


def test_a_battery_that_lasts_never_reaches_its_reserve_and_a_run_without_one_logs_none():
    _, r = _flown(duration_s=0.3, capacity_wh=100.0)
    assert r.metrics["soc_final_fraction"] > 0.99 and "battery_reserve_first_s" not in r.metrics
    plain = ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.15}))
    assert not [c for c in plain.timeseries if "soc" in c] and "soc_final_fraction" not in plain.metrics


def test_a_battery_table_out_of_range_is_named():
    with pytest.raises(ar.ScenarioError, match=r"platform.battery.usable_fraction"):
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"platform.battery": {"capacity_wh": 50.0, "usable_fraction": 1.5}})


def test_a_battery_sure_to_run_empty_is_refused_before_the_flight():
    """Issue 61: 0.01 Wh relays were flown on nothing (state of charge -109 at landing, reported safe). Hovering (the
    least this model draws: 235 W here) 0.01 Wh cannot even land the relay from its start: refused naming the field;
    without go_home a battery shorter than the mission at hover is refused naming go_home."""
    hover = ar.api.vehicle(ar.load_scenario("scenarios/nominal_tilted.toml"))
    draw_w = float(hover.shaft_power(hover.hover_speeds())) + AVIONICS_W
    with pytest.raises(ar.ScenarioError, match=r"platform\.battery\.capacity_wh: 0\.01 Wh .* cannot bring relay 'relay' "
                                               r"home from its start with its reserve kept"):
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"platform.battery": {"capacity_wh": 0.01}})
    lasts_s = CAPACITY_WH * 3600.0 * USABLE / draw_w  # 2.3 s at hover
    with pytest.raises(ar.ScenarioError, match=rf"platform\.battery\.go_home: false, and {CAPACITY_WH:g} Wh .* lasts {lasts_s:.1f} s"):
        _flown(duration_s=10.0)
    _flown(duration_s=0.3)  # within it: flown


def test_a_relay_that_flew_on_an_empty_battery_makes_the_run_unsafe():
    """What hover cannot foresee (flying draws more) is caught in flight: a state of charge below 0 at a step flown is
    unsafe (exit status battery_empty), whatever else went well."""
    from aerorelay.sim.metrics import relay_metrics

    sc, r = _flown(duration_s=0.3)
    veh = ar.api.vehicle(sc)
    c = sc.controller

    def metrics(log):
        return relay_metrics(log, "relay", veh, period_s=sc.control_period_s, mu=c.mu, workspace_min=c.workspace.min,
                             workspace_max=c.workspace.max, box_tolerance_m=0.5, ground_z_m=sc.world.ground_z_m, obstacles=())

    assert not metrics(r.timeseries)["unsafe"] and not r.metrics["unsafe"]
    log = r.timeseries.copy()
    log.loc[log.index[-3:], "relay.soc"] = [-0.01, -0.02, -0.03]
    m = metrics(log)
    assert m["unsafe"] and m["exit_status"] == "battery_empty" and m["exit_statuses"] == ["battery_empty"]
    assert "flew on an empty battery" in m["unsafe_reason"] and "down to -3%" in m["unsafe_reason"]


def test_a_battery_that_empties_in_flight_ends_the_flight_there_logged_empty():
    """Issue 61: the state of charge never goes below 0 in the log; the step it empties ends the flight (the steps
    flown kept), exit status battery_empty. The battery is made small after the load's check (parts built from
    Python), as a flight drawing more than the hover would."""
    import dataclasses

    from aerorelay.assembly.parts import build
    from aerorelay.models.battery import Battery

    sc, _ = _flown(duration_s=1.0)
    parts = build(sc)
    drawn_per_step = 235.0 * sc.control_period_s  # J, about: hovering
    parts.relays[0] = dataclasses.replace(parts.relays[0], battery=Battery(20.5 * drawn_per_step, RESERVE, AVIONICS_W))
    mission = parts.closed_loop().run()
    soc = np.asarray(mission.log["relay.soc"], float)
    assert mission.exit_status == "battery_empty" and "its battery is empty" in mission.aborted
    assert soc.min() == 0.0 and soc[-1] == 0.0 and (soc[:-1] > 0.0).all()
    assert 18 <= len(soc) <= 23 < int(round(1.0 / sc.control_period_s))  # ended about 21 steps in, of 67


def test_the_run_summary_has_the_batterys_rows(tmp_path):
    """Issue 61: the console's summary of a run says each relay's battery (its state of charge at the end)."""
    from typer.testing import CliRunner

    from aerorelay.cli import app

    r = CliRunner().invoke(app, ["run", "scenarios/nominal_tilted.toml", "--out", str(tmp_path / "run"), "--duration", "0.3",
                                 "--no-bound", "--no-figures", "--set", f"platform.battery.capacity_wh={CAPACITY_WH}",
                                 "--set", "platform.battery.go_home=false"])
    assert r.exit_code == 0, r.output
    assert "soc_final_fraction" in r.output
