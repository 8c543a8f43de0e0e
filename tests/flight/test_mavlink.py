"""The MAVLink offboard bridge against the in-repo vehicle over UDP on localhost, in lockstep (the
test owns the clock): offboard refused without a setpoint stream, arming only when told, offboard
entered after the stream and kept, one fresh setpoint per control period, stale telemetry to a
hold within one period (and the vehicle asked to hold), the vehicle's own offboard-loss timeout.
This tests the protocol, frames, rates and timeouts against our PX4 subset, not PX4 itself."""

from __future__ import annotations

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build_source
from aerorelay.experiments.flight import free_udp_port
from aerorelay.flight.airframes import PointMass
from aerorelay.flight.mavlink_bridge import OffboardBridge
from aerorelay.flight.mavlink_vehicle import MAV, MavlinkVehicle, VehicleSettings
from aerorelay.flight.px4 import OFFBOARD_LOSS_S
from aerorelay.models.geometry import rotation_zyx


@pytest.fixture()
def pair():
    def make(arm: bool = True, setpoint: str = "position"):
        sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates({"sim.duration_s": 20.0})
        ctrl = ar.controller(sc)  # the one controller; one relay is a network of one
        port = free_udp_port()
        vehicle = MavlinkVehicle(f"udpin:127.0.0.1:{port}", position=sc.nodes.relay)
        bridge = OffboardBridge({"relay": f"udpout:127.0.0.1:{port}"}, ctrl, {"source": build_source(sc)}, arm=arm,
                                setpoint=setpoint)
        T = ctrl.period
        for _ in range(5):  # handshake in lockstep: the bridge announces itself, the vehicle answers
            bridge.links["relay"].announce()
            vehicle.step(T)
            if bridge.links["relay"].heard_vehicle(0.05):
                break
        assert bridge.links["relay"].target == (1, 1)
        return sc, ctrl, vehicle, bridge, T
    return make


def _fly(vehicle, bridge, T, t0: float, seconds: float, vehicle_steps: bool = True) -> float:
    t = t0
    for _ in range(int(round(seconds / T))):
        if vehicle_steps:
            vehicle.step(T)
        bridge.tick(t)
        t += T
    return t


def test_offboard_is_refused_without_a_setpoint_stream(pair):
    _, _, vehicle, bridge, T = pair()
    bridge.links["relay"].request_mode("OFFBOARD")
    vehicle.step(T)
    assert vehicle.acks[-1] == (MAV.MAV_CMD_DO_SET_MODE, MAV.MAV_RESULT_DENIED) and vehicle.mode == "POSCTL"


def test_the_bridge_streams_then_arms_and_flies_offboard(pair):
    _, ctrl, vehicle, bridge, T = pair(arm=True)
    bridge.links["relay"].announce()
    vehicle.step(T)  # first telemetry
    t = _fly(vehicle, bridge, T, 0.0, 0.9)
    assert not vehicle.armed and vehicle.mode == "POSCTL"  # still streaming: PX4 wants 1 s of setpoints first
    t = _fly(vehicle, bridge, T, t, 1.0)
    assert vehicle.armed and vehicle.mode == "OFFBOARD"
    assert (MAV.MAV_CMD_DO_SET_MODE, MAV.MAV_RESULT_ACCEPTED) in vehicle.acks
    assert bridge.links["relay"].state.armed and bridge.links["relay"].state.custom_mode == (6 << 16)  # the vehicle's heartbeat says so
    n = len(vehicle.setpoint_times)
    t = _fly(vehicle, bridge, T, t, 3.0)
    assert vehicle.mode == "OFFBOARD"  # kept
    assert len(vehicle.setpoint_times) >= n  # (the vehicle keeps the last 2 s of them)
    # one setpoint per control period, each the one computed in that period
    times = np.array(vehicle.setpoint_times)
    assert np.allclose(np.diff(times[-50:]), T, atol=1e-9)
    assert all(r["mode"] == "nmpc" for r in bridge.log[-50:])
    # each setpoint the vehicle holds is the command computed in that period (float32 on the wire)
    for _ in range(20):
        cmd = bridge.tick(t)["relay"]
        vehicle.step(T)
        t += T
        np.testing.assert_allclose(vehicle.target["p"], cmd.position_m, atol=1e-5)
        np.testing.assert_allclose(vehicle.target["v"], cmd.velocity_m_s, atol=1e-5)
    # the vehicle follows the controller's setpoints
    assert np.linalg.norm(vehicle.p - cmd.position_m) < 0.5


def test_no_arming_unless_told(pair):
    _, _, vehicle, bridge, T = pair(arm=False)
    bridge.links["relay"].announce()
    vehicle.step(T)
    _fly(vehicle, bridge, T, 0.0, 2.0)
    assert not vehicle.armed and MAV.MAV_CMD_COMPONENT_ARM_DISARM not in [c for c, _ in vehicle.acks]


def test_stale_telemetry_holds_within_one_period_and_hands_back(pair):
    _, ctrl, vehicle, bridge, T = pair(arm=True)
    bridge.links["relay"].announce()
    vehicle.step(T)
    t = _fly(vehicle, bridge, T, 0.0, 2.5)
    assert vehicle.mode == "OFFBOARD"
    last = bridge.links["relay"].state.received_at
    # telemetry stops (the vehicle is not stepped): the bridge holds once it is older than hold_after_s
    modes = []
    while t <= last + ctrl.stale.hold_after_s + 2 * T:
        modes.append((t - last, bridge.tick(t)["relay"].mode))
        t += T
    first_hold = next(age for age, m in modes if m == "hold")
    assert ctrl.stale.hold_after_s < first_hold <= ctrl.stale.hold_after_s + T
    assert all(m == "nmpc" for age, m in modes if age <= ctrl.stale.hold_after_s)
    assert "AUTO.LOITER" in bridge.links["relay"].requested
    vehicle.step(T)  # the vehicle reads the hold request
    assert vehicle.mode == "HOLD"


def test_the_vehicle_leaves_offboard_when_setpoints_stop(pair):
    _, _, vehicle, bridge, T = pair(arm=True)
    bridge.links["relay"].announce()
    vehicle.step(T)
    _fly(vehicle, bridge, T, 0.0, 2.5)
    assert vehicle.mode == "OFFBOARD"
    for _ in range(int(OFFBOARD_LOSS_S / T) - 2):
        vehicle.step(T)
    assert vehicle.mode == "OFFBOARD"
    for _ in range(4):
        vehicle.step(T)
    assert vehicle.mode == "HOLD"


def test_attitude_setpoints_fly_too(pair):
    _, _, vehicle, bridge, T = pair(arm=True, setpoint="attitude")
    bridge.links["relay"].announce()
    vehicle.step(T)
    _fly(vehicle, bridge, T, 0.0, 2.5)
    assert vehicle.mode == "OFFBOARD" and vehicle.target["kind"] == "attitude"
    assert vehicle.target["thrust"] == pytest.approx(0.5, abs=0.05)  # about hover: hover_throttle 0.5 of full throttle


def test_odometry_telemetry_reads_as_position_and_attitude_do():
    """ODOMETRY (local NED, velocity in body FRD) gives the bridge the same state as LOCAL_POSITION_NED
    and ATTITUDE_QUATERNION: a tilted, yawed, moving vehicle read back in ENU/FLU."""
    sc = ar.load_scenario("scenarios/nominal_tilted.toml")
    ctrl = ar.controller(sc)
    states = []
    for telemetry in ("odometry", "local_position"):
        port = free_udp_port()
        af = PointMass([1.0, -2.0, 3.0])
        af.v, af.R, af.rates = np.array([0.5, -1.5, 0.25]), rotation_zyx([0.2, -0.1, 1.0]), np.array([0.1, -0.2, 0.3])
        vehicle = MavlinkVehicle(f"udpin:127.0.0.1:{port}", settings=VehicleSettings(telemetry=telemetry), airframe=af)
        bridge = OffboardBridge({"relay": f"udpout:127.0.0.1:{port}"}, ctrl, {"source": build_source(sc)})
        bridge.links["relay"].announce()
        vehicle.step(0.01)  # disarmed: the airframe sits; its telemetry goes out
        bridge.links["relay"]._read(0.01)
        st = bridge.links["relay"].state
        np.testing.assert_allclose(st.position, af.p, atol=1e-5)
        np.testing.assert_allclose(st.velocity, af.v, atol=1e-5)
        np.testing.assert_allclose(st.R, af.R, atol=1e-6)
        np.testing.assert_allclose(st.rates, af.rates, atol=1e-6)
        states.append(np.concatenate([st.position, st.velocity, st.R.ravel(), st.rates]))
        bridge.links["relay"].link.close()
        vehicle.link.close()
    np.testing.assert_allclose(states[0], states[1], atol=1e-5)
