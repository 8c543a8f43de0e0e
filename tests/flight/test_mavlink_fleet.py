"""A relay network through MAVLink (``flight.mavlink_bridge.OffboardBridge``, one vehicle per relay): the two-relay chain flown in lockstep
over two in-repo vehicles (each its own UDP link and system id) with our plant's airframe keeps the rate
``ar.simulate`` flies on the same chain; one vehicle's telemetry lost for 1 s holds it and it takes OFFBOARD
back; lost for 4 s it holds, lands and leaves the network, the other relay re-plans alone, and the run names
the relay and when."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar

CHAIN = "scenarios/chain_two_relays.toml"


@pytest.fixture(scope="module")
def chain():
    sc = ar.load_scenario(CHAIN, set={"sim.duration_s": 6.0})
    flown, log = ar.fly_lockstep(sc, ar.plant_airframes(sc))
    return sc, flown, log, ar.simulate(sc)


def test_the_chain_through_two_mavlink_vehicles_keeps_the_simulated_rate(chain):
    sc, flown, log, sim = chain
    a, b = flown.timeseries["capacity"].to_numpy(), sim.timeseries["capacity"].to_numpy()
    assert len(a) >= len(b) - 3  # the first periods wait for every vehicle's telemetry
    assert a.mean() == pytest.approx(b.mean(), rel=0.02) and a.min() == pytest.approx(b.min(), rel=0.02)
    assert not flown.metrics["unsafe"] and "lost_in_flight" not in flown.metrics
    assert set(log["relay"]) == {"r1", "r2"} and set(log.loc[log["mode"] != "stream", "mode"]) <= {"nmpc", "fallback", "wait"}
    for r in ("r1", "r2"):  # each relay flew its own vehicle near where the plant flies it
        p = flown.timeseries[[f"{r}.p_x", f"{r}.p_y", f"{r}.p_z"]].to_numpy()
        q = sim.timeseries[[f"{r}.p_x", f"{r}.p_y", f"{r}.p_z"]].to_numpy()[: len(p)]
        assert np.max(np.linalg.norm(p[: len(q)] - q, axis=1)) < 2.0


def _events(log, relay):
    return [m for m, r in zip(log["mode"], log["relay"], strict=True) if r == relay]


def test_a_vehicle_whose_telemetry_stops_holds_then_lands_and_the_other_flies_on():
    sc = ar.load_scenario(CHAIN, set={"sim.duration_s": 9.0})
    lost = lambda relay, t: relay == "r2" and 3.0 <= t < 7.0  # noqa: E731  bridge time: the mission starts ~1.2 s in
    flown, log = ar.fly_lockstep(sc, ar.plant_airframes(sc), telemetry_lost=lost)
    assert [e["relay"] for e in flown.metrics["lost_in_flight"]] == ["r2"]
    t_lost = flown.metrics["relays"]["r2"]["lost_at_s"]
    assert 3.0 < t_lost < 6.0  # land_after_s (3 s) after its last trusted telemetry
    modes = _events(log, "r2")
    assert "hold" in modes and "land" in modes and modes.index("hold") < modes.index("land")
    ts = flown.timeseries
    after = ts["t"] > t_lost + 0.1
    assert ts.loc[after, "r2.p_x"].isna().all() and (ts.loc[after, "capacity"] > 0).all()
    assert ts.loc[after, "sinr.r1.bs"].notna().all()  # r1 carries the route alone
    assert set(_events(log, "r1")) <= {"stream", "wait", "nmpc", "fallback"}


def test_a_short_telemetry_gap_holds_and_the_vehicle_takes_offboard_back():
    sc = ar.load_scenario(CHAIN, set={"sim.duration_s": 7.0})
    lost = lambda relay, t: relay == "r1" and 3.0 <= t < 3.6  # noqa: E731
    flown, log = ar.fly_lockstep(sc, ar.plant_airframes(sc), telemetry_lost=lost)
    modes = _events(log, "r1")
    assert "hold" in modes and "land" not in modes and modes[-1] in ("nmpc", "fallback")
    assert "lost_in_flight" not in flown.metrics and not flown.metrics["unsafe"]


def test_the_inspector_as_a_third_mavlink_system_is_flown_on_its_reports(chain):
    """The chain's inspector as a further in-repo vehicle (MissionFlyer: its mission, system 3 on its own link):
    the relays fly on its reports, which are where its path puts it, and the rate is the mission file's."""
    from aerorelay.assembly.parts import build
    from aerorelay.flight.airframes import MissionFlyer

    sc, flown_file, _, _ = chain
    path = build(sc).sources["inspector"]
    flown, log = ar.fly_lockstep(sc, ar.plant_airframes(sc), source_airframes={"inspector": MissionFlyer(path)})
    df = flown.timeseries
    assert not flown.metrics["unsafe"] and (df["flight_mode"] == "nmpc").mean() > 0.95
    p = df[["inspector.p_x", "inspector.p_y", "inspector.p_z"]].to_numpy()
    t0 = log.loc[log["mode"] != "stream", "t"].iloc[0]
    want = np.array([path.state(tm + t0 + sc.control_period_s).p for tm in df["t"]])
    assert np.max(np.linalg.norm(p - want, axis=1)) < 0.05  # its report one step on, as for one relay
    a, b = df["capacity"].to_numpy(), flown_file.timeseries["capacity"].to_numpy()
    assert a.mean() == pytest.approx(b.mean(), rel=0.01)
