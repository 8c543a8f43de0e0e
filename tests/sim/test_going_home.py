"""A relay whose battery's energy left is what getting home needs plus the reserve flies home and lands, and
leaves the network (``[platform.battery] go_home``): it turns at the step the formula says, written out here
(``E_home = (d / v_home + h / v_land + t_extra) (P_hover + P_avionics)``, ``t_extra`` the speeding up, braking and
2 s of settling, the hover's shaft power from the rotor model ``sum c_tau Omega^3 2 pi``), lands with at least its
reserve left, the other relay carries the route alone,
and nothing is unsafe. One relay (a fleet of one) going home leaves the source talking to the base station."""

import math

import numpy as np
import pytest

import aerorelay as ar

AVIONICS_W = 15.0


def _with_battery(path, relay_index, capacity_wh, go_home=True, **settings):
    sc = ar.load_scenario(path, set=settings)
    battery = {"capacity_wh": capacity_wh, "usable_fraction": 0.9, "reserve_fraction": 0.2, "avionics_w": AVIONICS_W,
               "return_speed_m_s": 2.0, "land_speed_m_s": 0.5, "go_home": go_home}
    if sc.relays is None:
        return sc.with_updates({"platform.battery": battery})
    relays = [r.model_dump() for r in sc.relays]
    relays[relay_index]["platform"] = sc.platform_of(relay_index).model_dump() | {"battery": battery}
    return sc.with_updates({"relays": relays})


@pytest.fixture(scope="module")
def chain_home():
    sc = _with_battery("scenarios/chain_two_relays.toml", 0, 3.0, **{"sim.duration_s": 40.0})
    return sc, ar.simulate(sc)


def test_the_relay_turns_home_at_the_step_the_energy_formula_says(chain_home):
    sc, r = chain_home
    ts, m = r.timeseries, r.metrics
    plat = sc.platform_of(0)
    hover = ar.api.vehicle(sc).hover_speeds()
    p_hover = float(np.sum(plat.c_tau * hover**3 * 2.0 * math.pi))
    usable = 3.0 * 3600.0 * 0.9
    start = np.array(sc.relay_list[0].start)
    floor = sc.controller.workspace.min[2]
    t = ts["t"].to_numpy()
    p = ts[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy()
    left = ts["r1.soc"].to_numpy() * usable  # at each step's start
    power = np.sum(plat.c_tau * ts[[f"r1.Omega_{i}" for i in range(1, 7)]].to_numpy() ** 3 * 2.0 * math.pi, axis=1) + AVIONICS_W
    after = left - power * sc.control_period_s  # what is left once the step is flown: when the relay decides
    cap = sc.controller.capacity  # the reference shaper's accelerations
    brake = min(cap.brake_accel_m_s2, cap.max_accel_m_s2)
    extra = 2.0 / (2 * cap.max_accel_m_s2) + 2.0 / (2 * brake) + 0.5 / (2 * brake) + 2.0
    need = (np.linalg.norm(p[:, :2] - start[:2], axis=1) / 2.0 + (p[:, 2] - floor) / 0.5 + extra) * (p_hover + AVIONICS_W)
    go = after <= need + 0.2 * usable
    k = int(np.argmax(go))
    assert go.any() and m["relays"]["r1"]["went_home_at_s"] == pytest.approx(t[k + 1])  # the next step flies home
    assert not go[:k].any()
    assert m["relays"]["r1"]["soc_landed_fraction"] >= 0.2  # the estimate (hover power) never undercounts here
    assert m["relays"]["r1"]["landed_at_s"] > m["relays"]["r1"]["went_home_at_s"]


def test_the_other_relay_carries_the_route_and_nothing_is_unsafe(chain_home):
    sc, r = chain_home
    ts, m = r.timeseries, r.metrics
    home = ts["r1.going_home"].to_numpy()
    assert not m["unsafe"], m["unsafe_reason"]
    assert m["separation_min_m"] >= sc.separation_m
    turned = np.argmax(home)
    assert ts["sinr.inspector.r2"].iloc[turned + 1:].notna().all() and ts["sinr.inspector.r1"].iloc[turned + 1:].isna().all()
    assert (ts["capacity"].iloc[turned:] > 0).all()
    down = ts["r1.p_x"].isna().to_numpy()
    assert down[-1] and not down[:turned].any()  # down and out of the flight by the end


def test_one_relay_going_home_leaves_the_source_with_the_base_station():
    sc = _with_battery("scenarios/nominal_tilted.toml", 0, 0.8, **{"sim.duration_s": 12.0, "channel.units": "physical",
                                                                    "jammer.power_dbm": 0.0})
    r = ar.simulate(sc)
    ts = r.timeseries
    assert r.metrics["relays"]["relay"]["went_home_at_s"] < 12.0 and not r.metrics["unsafe"], r.metrics["unsafe_reason"]
    later = ts["relay.going_home"].to_numpy()
    assert ts.loc[later, "sinr.source.bs"].notna().all() and (ts.loc[later, "capacity"] > 0).all()


def test_without_go_home_the_relay_flies_on_past_its_reserve():
    r = ar.simulate(_with_battery("scenarios/chain_two_relays.toml", 0, 1.0, go_home=False, **{"sim.duration_s": 3.0}))
    assert "r1.going_home" not in r.timeseries and r.timeseries["r1.p_x"].notna().all()
