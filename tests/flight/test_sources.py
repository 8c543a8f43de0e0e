"""The source as a second MAVLink system: an in-repo vehicle (system 2) flying the scenario's mission,
read by ``MavlinkSource`` over UDP on localhost in lockstep: its NED position back in ENU (shifted by
its origin), its acceleration estimated from its velocity, the relay's controller flying on it, and
holding within one control period when it goes silent."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build_source
from aerorelay.experiments.flight import fly_lockstep, free_udp_port
from aerorelay.flight.airframes import MissionFlyer, PointMass
from aerorelay.flight.mavlink_bridge import OffboardBridge
from aerorelay.flight.mavlink_vehicle import MavlinkVehicle, VehicleSettings
from aerorelay.flight.sources import MavlinkSource

SC = ar.load_scenario("scenarios/nominal_tilted.toml")
T = SC.control_period_s


def _source_vehicle(port: int) -> MavlinkVehicle:
    return MavlinkVehicle(f"udpin:127.0.0.1:{port}", settings=VehicleSettings(telemetry_hz=1.0 / T), system=2,
                          airframe=MissionFlyer(build_source(SC)))


def test_the_second_system_is_read_in_enu_shifted_by_its_origin():
    port = free_udp_port()
    vehicle, path = _source_vehicle(port), build_source(SC)
    src = MavlinkSource(f"udpout:127.0.0.1:{port}", system=2, origin_enu=(10.0, -20.0, 0.5))
    assert src.known(0.0, 0.0) is None  # nothing heard yet
    t = 0.0
    for _ in range(int(round(6.0 / T))):
        vehicle.step(T)
        t += T
        known = src.known(t, t)
    want = path.state(vehicle.t)
    np.testing.assert_allclose(known.p, np.asarray(want.p) + [10.0, -20.0, 0.5], atol=1e-4)  # float32 on the wire
    np.testing.assert_allclose(known.v, want.v, atol=1e-4)
    assert known.stamp == pytest.approx(t)
    # the acceleration from the velocity's change, filtered: close to the path's once it has settled
    assert np.linalg.norm(known.a - np.asarray(path.state(vehicle.t - 0.1).a)) < 0.2 * max(1.0, np.linalg.norm(want.a))
    src.link.close()
    vehicle.link.close()


def test_the_relay_flies_on_the_second_systems_reports():
    result, log = fly_lockstep(SC, {"relay": PointMass(SC.nodes.relay)}, duration_s=3.0,
                               source_airframes={"source": MissionFlyer(build_source(SC))})
    df = result.timeseries
    assert (df["flight_mode"] == "nmpc").all() and not result.metrics["unsafe"]
    t0 = log.loc[log["mode"] != "stream", "t"].iloc[0]  # the bridge time OFFBOARD began: the mission's clock is 0 there
    path = build_source(SC)
    # the source vehicle's clock is the bridge's; its report at bridge time t is where it was one step on
    want = np.array([path.state(tm + t0 + T).p for tm in df["t"]])
    np.testing.assert_allclose(df[["source.p_x", "source.p_y", "source.p_z"]].to_numpy(), want, atol=1e-4)


def test_a_silent_source_makes_the_relay_hold_within_one_period():
    ctrl = ar.controller(SC)
    port, source_port = free_udp_port(), free_udp_port()
    relay = MavlinkVehicle(f"udpin:127.0.0.1:{port}", settings=VehicleSettings(telemetry_hz=1.0 / T), airframe=PointMass(SC.nodes.relay))
    source_vehicle = _source_vehicle(source_port)
    bridge = OffboardBridge({"relay": f"udpout:127.0.0.1:{port}"}, ctrl,
                            {"source": MavlinkSource(f"udpout:127.0.0.1:{source_port}", system=2)}, arm=True)
    link = bridge.links["relay"]
    t = 0.0
    while not link.heard_vehicle():
        link.announce()
        relay.step(T)
        source_vehicle.step(T)
        t += T
    modes, last_report = [], None
    for k in range(int(round(4.0 / T))):
        relay.step(T)
        if k * T < 3.0:  # the source reports for 3 s, then goes silent
            source_vehicle.step(T)
            last_report = t
        cmds = bridge.tick(t)
        modes.append((t, None if cmds is None else cmds["relay"].mode))
        t += T
    assert [m for _, m in modes if m is not None][0] == "nmpc"
    held_at = next(tt for tt, m in modes if m == "hold")
    # stale once older than hold_after_s; held at the first period after that, and from then on
    assert held_at - last_report <= ctrl.stale.hold_after_s + T + 1e-9
    assert all(m == "hold" for tt, m in modes if tt >= held_at)
    for each in (link.link, bridge.sources["source"].link, relay.link, source_vehicle.link):
        each.close()


def test_a_source_system_or_origin_is_for_one_source_given_by_name_or_alone():
    """``--source-system`` / ``--source-origin`` set one source's MAVLink system and frame: refused, before any vehicle
    is contacted, with two sources' URLs."""
    sc = ar.load_scenario("scenarios/two_sources.toml")
    names = [s.name for s in sc.source_list]
    urls = {r.name: f"udpout:127.0.0.1:{free_udp_port()}" for r in sc.relay_list}
    two = {n: f"udpin:127.0.0.1:{free_udp_port()}" for n in names}
    with pytest.raises(ValueError, match="for one source read with --source-mavlink"):
        ar.api.fly(sc, urls, source_url=two, source_system=5, duration_s=0.1)
    with pytest.raises(ValueError, match="for one source read with --source-mavlink"):
        ar.api.fly(sc, urls, source_url=two, source_origin=(1.0, 0.0, 0.0), duration_s=0.1)
