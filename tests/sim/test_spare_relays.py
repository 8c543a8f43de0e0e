"""A spare relay (``[[relays]] standby = true``) waits at its start, launches when a relay of the network will
have to fly home before the spare could reach it (the launch step checked against the energy formula written
out here: ``E_left - (P_hover + P_avionics) T_transit <= E_home + reserve``, ``T_transit = (|p_spare - p_relay| -
d_beside) / max(v_return - v_away, v_return / 4) + t_extra``, ``v_away`` the relay's speed away from the spare),
flies beside that relay and takes its place on the route the step the relay turns home;
the network stays connected through the swap and nothing is unsafe (separation, workspace, ground)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError
from tests.scenario_files import scenario_from_text

AVIONICS_W = 15.0
SPARE = """
name = "spare_takes_over"
seed = 0
[channel]
units = "physical"
[controller.workspace]
min = [-2.0, -12.0, 0.5]
max = [94.0, 12.0, 20.0]
[jammer]
position = [45.0, -20.0, 2.0]
power_w = 0.08
[platform.battery]
capacity_wh = 3.0
avionics_w = 15.0
[[relays]]
name = "r1"
start = [8.0, 2.0, 6.0]
[[relays]]
name = "spare"
start = [2.0, -4.0, 1.0]
standby = true
[[sources]]
name = "inspector"
[sources.mission]
waypoints = [[0.0, 6.0, 3.0, 10.0], [20.0, 50.0, 3.0, 12.0], [30.0, 50.0, -3.0, 12.0]]
[network]
min_separation_m = 2.0
planner = "equidistant"
"""


def _load(tmp_path, text, name="spare.toml"):
    return scenario_from_text(tmp_path, text, name)


@pytest.fixture(scope="module")
def takeover(tmp_path_factory):
    sc = _load(tmp_path_factory.mktemp("spare"), SPARE)
    return sc, ar.simulate(sc)


def _extra_s(sc, speed, land):
    cap = sc.controller.capacity
    brake = min(cap.brake_accel_m_s2, cap.max_accel_m_s2)
    return speed / (2 * cap.max_accel_m_s2) + speed / (2 * brake) + land / (2 * brake) + 2.0


def test_the_spare_launches_at_the_step_the_energy_formula_says(takeover):
    sc, r = takeover
    ts, m = r.timeseries, r.metrics
    plat = sc.platform
    bat = plat.battery
    hover = ar.api.vehicle(sc).hover_speeds()
    p_hover = float(np.sum(plat.c_tau * hover**3 * 2.0 * math.pi))
    usable = bat.capacity_wh * 3600.0 * bat.usable_fraction
    t = ts["t"].to_numpy()
    p = ts[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy()
    power = np.sum(plat.c_tau * ts[[f"r1.Omega_{i}" for i in range(1, 7)]].to_numpy() ** 3 * 2.0 * math.pi, axis=1) + AVIONICS_W
    after = ts["r1.soc"].to_numpy() * usable - power * sc.control_period_s  # left once the step is flown
    start, spare = np.array(sc.relay_list[0].start), np.array(sc.relay_list[1].start)
    floor = sc.controller.workspace.min[2]
    v, w = bat.return_speed_m_s, bat.land_speed_m_s
    home = (np.linalg.norm(p[:, :2] - start[:2], axis=1) / v + (p[:, 2] - floor) / w + _extra_s(sc, v, w)) * (p_hover + AVIONICS_W)
    d = p - spare
    away = np.maximum(0.0, np.sum(ts[["r1.v_x", "r1.v_y", "r1.v_z"]].to_numpy() * d, axis=1) / np.linalg.norm(d, axis=1))
    transit = np.maximum(np.linalg.norm(d, axis=1) - 3.0, 0.0) / np.maximum(v - away, 0.25 * v) + _extra_s(sc, v, w)
    launch = after - transit * (p_hover + AVIONICS_W) <= home + bat.reserve_fraction * usable
    k = int(np.argmax(launch))
    spare_m = m["relays"]["spare"]
    assert launch.any() and spare_m["launched_at_s"] == pytest.approx(t[k + 1])  # the next step flies
    assert not launch[:k].any()
    assert ts["spare.waiting"].to_numpy()[: k + 1].all() and not ts["spare.waiting"].to_numpy()[k + 1:].any()


def test_the_spare_takes_the_place_the_step_the_relay_turns_home_and_the_network_stays_up(takeover):
    sc, r = takeover
    ts, m = r.timeseries, r.metrics
    spare_m, r1 = m["relays"]["spare"], m["relays"]["r1"]
    assert spare_m["took_over_at_s"] == pytest.approx(r1["went_home_at_s"]) and spare_m["took_over_from"] == "r1"
    assert spare_m["launched_at_s"] < spare_m["took_over_at_s"]
    t = ts["t"].to_numpy()
    k = int(np.searchsorted(t, spare_m["took_over_at_s"] - 1e-9))
    # it had arrived beside r1 (the separation and 1 m, give or take its lag behind a moving goal)
    gap = np.linalg.norm(ts[["spare.p_x", "spare.p_y", "spare.p_z"]].to_numpy()[k] - ts[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy()[k])
    assert 2.0 <= gap <= 2.0 + 1.0 + 2.0
    # the route runs through the spare from then on, through r1 before
    via_spare = np.isfinite(ts["sinr.inspector.spare"].to_numpy())
    until = spare_m.get("went_home_at_s", math.inf)  # (it carries the route until its own battery sends it home)
    np.testing.assert_array_equal(via_spare, (t >= spare_m["took_over_at_s"] - 1e-9) & (t < until - 1e-9))
    assert until > spare_m["took_over_at_s"] + 3.0
    assert np.isfinite(ts["sinr.inspector.r1"].to_numpy()[:k]).all() and np.isnan(ts["sinr.inspector.r1"].to_numpy()[k:]).all()
    assert (ts["capacity"].to_numpy() > 0).all()  # connected through the swap
    assert spare_m["c_min_after_takeover"] > 0 and spare_m["c_mean_after_takeover"] > 0
    assert not m["unsafe"], m["unsafe_reason"]
    assert m["separation_min_m"] >= 2.0
    for relay in ("r1", "spare"):
        assert m["relays"][relay]["box_violation_max_m"] == 0.0 and m["relays"][relay]["min_altitude_m"] > 0.0


@pytest.mark.parametrize("text, field", [
    (SPARE.replace("[network]\n", '[network]\nroutes = [["inspector", "r1", "spare", "bs"]]\n'), r"relays\[1\]\.standby"),
    (SPARE.replace('planner = "equidistant"\n', ""), r"relays\[1\]\.standby: with a spare, one relay and one source are a network"),
    (SPARE.replace("capacity_wh = 3.0", "capacity_wh = 3.0\ngo_home = false"), r"relays\[1\]\.standby: no relay"),
    (SPARE.replace('start = [2.0, -4.0, 1.0]\nstandby = true', 'start = [2.0, -4.0, 1.0]\nstandby = true\nlost_at_s = 5.0'),
     r"relays\[1\]\.lost_at_s"),
    (SPARE.replace("power_w = 0.08", 'power_w = 0.08\npattern = "cosine"\npoint_at = "spare"'), r"jammer\.point_at: 'spare' is a spare"),
])
def test_bad_spares_are_named_errors(tmp_path, text, field):
    with pytest.raises(ScenarioError, match=field):
        _load(tmp_path, text, "bad.toml")


def test_a_fleet_with_a_spare_is_not_flown_from_outside(tmp_path):
    """The step API (and so MAVLink and ROS 2) flies the relays it is handed: a spare would never launch there."""
    sc = _load(tmp_path, SPARE)
    with pytest.raises(ScenarioError, match=r"relays\[1\]\.standby: spare relays take over in ar\.simulate"):
        ar.controller(sc)


def test_a_spare_on_its_way_takes_the_place_of_a_relay_lost_before_it_turns_home(tmp_path, takeover):
    """r1 lost (``lost_at_s``) after the spare launched for it and before its battery sends it home: the spare takes
    its place then, and the route runs through it from that step."""
    _, flown = takeover
    launched = flown.metrics["relays"]["spare"]["launched_at_s"]
    lost_at = round(launched + 2.0, 2)
    sc = _load(tmp_path, SPARE.replace('start = [8.0, 2.0, 6.0]', f'start = [8.0, 2.0, 6.0]\nlost_at_s = {lost_at}'))
    r = ar.simulate(sc)
    spare = r.metrics["relays"]["spare"]
    assert spare["launched_at_s"] == pytest.approx(launched)
    assert spare["took_over_at_s"] == pytest.approx(lost_at, abs=sc.control_period_s) and spare["took_over_from"] == "r1"
    t = r.timeseries["t"].to_numpy()
    assert np.isfinite(r.timeseries["sinr.inspector.spare"].to_numpy()[t >= spare["took_over_at_s"] - 1e-9][:100]).all()
    assert (r.timeseries["capacity"].to_numpy() > 0).all() and not r.metrics["unsafe"], r.metrics["unsafe_reason"]


def test_the_relay_shifts_preset_stays_connected_and_safe_through_its_swap_and_handover():
    """``scenarios/relay_shifts.toml`` over its first 45 s: the spare takes r1's place, the route is handed over to
    the substation, the rate stays above zero throughout and nothing is unsafe (launches and landings included)."""
    from pathlib import Path

    sc = ar.load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / "relay_shifts.toml", set={"sim.duration_s": 45.0})
    r = ar.simulate(sc)
    m, ts = r.metrics, r.timeseries
    assert m["relays"]["spare"]["took_over_from"] == "r1"
    assert m["handovers"] >= 1 and ts["inspector.base_station"].iloc[-1] == "substation"
    assert (ts["capacity"].to_numpy() > 0).all()
    assert not m["unsafe"], m["unsafe_reason"]
    assert m["separation_min_m"] >= sc.network.min_separation_m
