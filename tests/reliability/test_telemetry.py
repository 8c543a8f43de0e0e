"""Telemetry that is checked before it is flown (issue 45, item 1): each case failed before the fix.

The MAVLink bridge against the in-repo vehicle in lockstep over UDP on localhost, with a spoofer that
writes to the bridge's socket as another system (or as the vehicle itself, to forge bad telemetry);
the step API with bad inputs; the CLI's named errors for URLs, ports, names and durations."""

from __future__ import annotations

import math
import socket

import numpy as np
import pytest
from pymavlink import mavutil
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.assembly.parts import build_source
from aerorelay.cli import app
from aerorelay.control.relay_step import SourceState
from aerorelay.experiments.flight import free_udp_port
from aerorelay.flight.autopilot_loop import AccelerationFilter, rotation_from_quaternion
from aerorelay.flight.frames import enu_to_ned
from aerorelay.flight.mavlink import MavlinkUrlError, check_url
from aerorelay.flight.mavlink_bridge import OffboardBridge
from aerorelay.flight.mavlink_vehicle import MavlinkVehicle
from aerorelay.flight.names import check_ros_namespace

runner = CliRunner()
SCENARIO = "scenarios/nominal_tilted.toml"


@pytest.fixture(scope="module")
def sc():
    return ar.load_scenario(SCENARIO).with_updates({"sim.duration_s": 30.0})


def _flying(sc):
    """A bridge flying the in-repo vehicle in OFFBOARD (lockstep), and a spoofer on the bridge's socket."""
    ctrl = ar.controller(sc)  # the one controller; one relay is a network of one
    port = free_udp_port()
    vehicle = MavlinkVehicle(f"udpin:127.0.0.1:{port}", position=sc.nodes.relay)
    bridge = OffboardBridge({"relay": f"udpout:127.0.0.1:{port}"}, ctrl, {"source": build_source(sc)}, arm=True)
    link = bridge.links["relay"]
    T = ctrl.period
    for _ in range(5):
        link.announce()
        vehicle.step(T)
        if link.heard_vehicle(0.05):
            break
    t = 0.0
    for _ in range(int(2.5 / T)):
        vehicle.step(T)
        bridge.tick(t)
        t += T
    assert vehicle.mode == "OFFBOARD"
    bridge_port = link.link.port.getsockname()[1]

    def spoofer(system: int, component: int = 1):
        return mavutil.mavlink_connection(f"udpout:127.0.0.1:{bridge_port}", source_system=system, source_component=component,
                                          dialect="common")
    return ctrl, vehicle, bridge, T, t, spoofer


def _fly(vehicle, bridge, T, t, seconds, trace=None):
    for _ in range(int(round(seconds / T))):
        vehicle.step(T)
        bridge.tick(t)
        if trace is not None:
            trace.append((bridge.log[-1]["mode"], vehicle.mode, vehicle.target))
        t += T
    return t


def _inside(sc, p, slack=0.5):
    ws = sc.controller.workspace
    return np.all(np.asarray(p) >= np.asarray(ws.min) - slack) and np.all(np.asarray(p) <= np.asarray(ws.max) + slack)


def test_telemetry_from_another_system_is_ignored(sc):
    """Before: a second system reporting 500 m away was taken as the relay (sent 490 m out)."""
    ctrl, vehicle, bridge, T, t, spoofer = _flying(sc)
    other = spoofer(system=7)
    for _ in range(20):
        other.mav.local_position_ned_send(0, *enu_to_ned([500.0, 0.0, 10.0]), 0.0, 0.0, 0.0)
        t = _fly(vehicle, bridge, T, t, T)
    state = bridge.links["relay"].state
    assert state.foreign >= 20
    assert np.linalg.norm(state.position - vehicle.p) < 1e-3  # the vehicle's own position, not the stranger's
    assert all(r["mode"] == "nmpc" for r in bridge.log[-20:]) and vehicle.mode == "OFFBOARD"
    assert _inside(sc, vehicle.target["p"])


@pytest.mark.parametrize("bad", ["nan", "jump"])
def test_bad_telemetry_is_held_named_and_offboard_comes_back(sc, bad):
    """Before: NaN telemetry sent 190 NaN setpoints; a 1 km jump was flown (the brake law ran 16.5 km);
    after one stale period the bridge never asked for OFFBOARD again and logged NMPC periods while the
    vehicle loitered."""
    ctrl, vehicle, bridge, T, t, spoofer = _flying(sc)
    forger = spoofer(system=1, component=1)  # as the vehicle itself
    p_bad = [math.nan] * 3 if bad == "nan" else (vehicle.p + [1000.0, 0.0, 0.0]).tolist()
    n0 = len(bridge.log)
    trace = []
    for _ in range(5):  # the forged message arrives after the vehicle's own each period
        vehicle.step(T)
        forger.mav.local_position_ned_send(0, *enu_to_ned(p_bad), 0.0, 0.0, 0.0)
        bridge.tick(t)
        trace.append((bridge.log[-1]["mode"], vehicle.mode, vehicle.target))
        t += T
    rows = bridge.log[n0:]
    assert rows[0]["mode"] == "hold"
    reason = "not finite" if bad == "nan" else "jumped"
    assert reason in rows[0]["rejected"]
    t = _fly(vehicle, bridge, T, t, 4.0, trace)  # good telemetry again: back to OFFBOARD (streamed 1 s first)
    assert vehicle.mode == "OFFBOARD" and bridge.phase["relay"] == "offboard" and bridge.log[-1]["mode"] == "nmpc"
    assert bridge.ended is None
    for mode, vmode, target in trace:  # every setpoint finite and in the workspace; no NMPC period while it held
        assert np.all(np.isfinite(target["p"])) and _inside(sc, target["p"])
        if mode == "nmpc":
            assert vmode == "OFFBOARD"
    assert any(vmode == "HOLD" for _, vmode, _ in trace)


def test_garbage_datagrams_do_not_end_the_flight(sc):
    ctrl, vehicle, bridge, T, t, spoofer = _flying(sc)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rng = np.random.default_rng(3)
    for _ in range(30):
        sock.sendto(rng.bytes(int(rng.integers(1, 300))), ("127.0.0.1", bridge.links["relay"].link.port.getsockname()[1]))
        t = _fly(vehicle, bridge, T, t, T)
    sock.close()
    assert vehicle.mode == "OFFBOARD" and all(r["mode"] == "nmpc" for r in bridge.log[-30:])


def test_a_vehicle_taken_out_of_offboard_ends_the_flight(sc):
    """A second ground station (or a pilot) switches the vehicle to POSCTL: the bridge does not fight it
    and does not log NMPC periods the vehicle does not fly."""
    ctrl, vehicle, bridge, T, t, _ = _flying(sc)
    gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{vehicle.link.port.getsockname()[1]}", source_system=200,
                                     source_component=190, dialect="common")
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 3, 0, 0, 0, 0, 0)  # POSCTL
    trace = []
    t = _fly(vehicle, bridge, T, t, 1.0, trace)
    assert vehicle.mode == "POSCTL"
    assert bridge.phase["relay"] == "ended" and "left OFFBOARD for POSCTL" in bridge.ended
    assert all(mode != "nmpc" or vmode == "OFFBOARD" for mode, vmode, _ in trace)
    assert bridge.log[-1]["mode"] == "ended"


def test_telemetry_stale_for_longer_than_land_after_lands_and_ends(sc):
    ctrl, vehicle, bridge, T, t, _ = _flying(sc)
    for _ in range(int((ctrl.stale.land_after_s + 0.5) / T)):  # the vehicle falls silent (not stepped)
        bridge.tick(t)
        t += T
    assert bridge.phase["relay"] == "ended" and "asked to land" in bridge.ended
    vehicle.step(T)
    assert vehicle.mode == "LAND"
    z0 = vehicle.p[2]
    for _ in range(100):
        vehicle.step(T)
    assert vehicle.p[2] < z0 - 0.2  # it descends (0.5 m/s: 0.75 m in 1.5 s, behind its point-mass autopilot)


# -- the step API -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def stepped(sc):
    """A controller stepped 0.3 s from the nominal start with the exact source (a trusted history)."""
    ctrl = ar.controller(sc).one_relay()
    src = build_source(sc)
    x = ctrl.vehicle.hover_state(sc.nodes.relay)
    for k in range(20):
        t = k * ctrl.period
        s = src.state(t)
        ctrl.step(t, x, SourceState(np.asarray(s.p), np.asarray(s.v), np.asarray(s.a)))
    return ctrl, src, x, 20 * ctrl.period


def _source(src, t, **change):
    s = src.state(t)
    fields = {"p": np.asarray(s.p, float), "v": np.asarray(s.v, float), "a": np.asarray(s.a, float)} | change
    return SourceState(**fields)


def test_step_rejects_non_finite_and_future_and_jumping_states(stepped):
    ctrl, src, x, t = stepped
    nan = x.copy()
    nan[0] = math.nan
    cmd = ctrl.step(t, nan, _source(src, t))
    assert cmd.mode == "hold" and "not finite (position)" in cmd.rejected
    cmd = ctrl.step(t + 0.01, x, _source(src, t), state_stamp=t + 5.0)  # before: the NMPC flew 5 s old states
    assert cmd.mode == "hold" and "ahead of the clock" in cmd.rejected
    far = x.copy()
    far[0] += 1000.0
    cmd = ctrl.step(t + 0.02, far, _source(src, t))
    assert cmd.mode == "hold" and "jumped" in cmd.rejected
    cmd = ctrl.step(t + 0.03, x, _source(src, t + 0.03))  # a good state again resumes the NMPC
    assert cmd.mode in ("nmpc", "fallback") and cmd.rejected is None


def test_a_nan_source_holds_and_does_not_keep_the_brake_law_on(stepped):
    """Before: a NaN source went into the NMPC and kept the brake law on for good."""
    ctrl, src, x, t = stepped
    t = t + 1.0
    cmd = ctrl.step(t, x, _source(src, t, p=np.array([math.nan, 0.0, 0.0])))
    assert cmd.mode == "hold" and "source not finite" in cmd.rejected
    modes = [ctrl.step(t + k * ctrl.period, x, _source(src, t + k * ctrl.period)).mode for k in range(1, 6)]
    assert modes[-1] == "nmpc"


def test_step_names_wrong_shapes_and_a_clock_going_backwards(stepped):
    ctrl, src, x, t = stepped
    t = t + 2.0
    with pytest.raises(ValueError, match=r"source\.v must be three numbers"):
        ctrl.step(t, x, _source(src, t, v=np.zeros(2)))
    with pytest.raises(ValueError, match=r"relay_states\['relay'\] must be 18 numbers"):
        ctrl.step(t, x[:5], _source(src, t))
    ctrl.step(t, x, _source(src, t))
    with pytest.raises(ValueError, match="clock went backwards"):
        ctrl.step(t - 1.0, x, _source(src, t))
    with pytest.raises(ValueError, match="finite time"):
        ctrl.step(math.nan, x, _source(src, t))


def test_a_first_state_that_cannot_be_trusted_is_named():
    ctrl = ar.controller(ar.load_scenario(SCENARIO)).one_relay()
    x = ctrl.vehicle.hover_state([0.0, 0.0, 2.0])
    x[7] = math.inf
    with pytest.raises(ValueError, match=r"not finite \(velocity\).*nothing to hold"):
        ctrl.step(0.0, x, SourceState(np.zeros(3), np.zeros(3), np.zeros(3)))


def test_a_zero_quaternion_is_not_a_rotation():
    assert np.all(np.isnan(rotation_from_quaternion([0, 0, 0, 0])))
    assert np.all(np.isnan(rotation_from_quaternion([math.nan, 0, 0, 1])))
    np.testing.assert_allclose(rotation_from_quaternion([1, 0, 0, 0]), np.eye(3))
    assert np.all(np.isnan(rotation_from_quaternion([2, 0, 0, 0])))  # not a unit quaternion: a bad message
    np.testing.assert_allclose(rotation_from_quaternion([1.005, 0, 0, 0]), np.eye(3))  # float32 on the wire: normalized


def test_the_source_acceleration_filter_tracks_a_constant_acceleration():
    """The ROS node handed the controller zero; the shared filter estimates it (first order, tau 0.1 s)."""
    f = AccelerationFilter(0.1)
    for k in range(200):
        a = f.update(0.01 * k, [2.0 * 0.01 * k, 0.0, -1.0 * 0.01 * k])
    np.testing.assert_allclose(a, [2.0, 0.0, -1.0], atol=1e-6)


# -- named errors before anything flies -------------------------------------------------------------

def test_a_port_in_use_is_a_named_error():
    """Before: a second ``sitl`` bound a used port silently (pymavlink binds with SO_REUSEADDR)."""
    port = free_udp_port()
    first = MavlinkVehicle(f"udpin:127.0.0.1:{port}")
    try:
        with pytest.raises(MavlinkUrlError, match="cannot listen on 127.0.0.1"):
            MavlinkVehicle(f"udpin:127.0.0.1:{port}")
        r = runner.invoke(app, ["sitl", SCENARIO, "--listen", f"udpin:127.0.0.1:{port}", "--duration", "1"])
        assert r.exit_code == 2 and "--listen" in r.output and "cannot listen" in r.output
    finally:
        first.link.close()


@pytest.mark.parametrize("url", ["nonsense", "udpout:127.0.0.1:99999", "udpin::14540", "udpout:127.0.0.1:port", "/dev/no-such-tty"])
def test_bad_mavlink_urls_are_named(url):
    with pytest.raises(MavlinkUrlError, match="--mavlink"):
        check_url(url, "--mavlink")
    r = runner.invoke(app, ["fly", SCENARIO, "--mavlink", url, "--duration", "1"])
    assert r.exit_code == 2 and "--mavlink" in r.output


@pytest.mark.parametrize("duration", ["nan", "-1", "0", "inf"])
def test_fly_refuses_durations_that_are_not_positive_and_finite(duration):
    r = runner.invoke(app, ["fly", SCENARIO, "--mavlink", "udpout:127.0.0.1:14999", "--duration", duration])
    assert r.exit_code == 2 and "--duration must be a finite number of seconds > 0" in r.output


@pytest.mark.parametrize("name", ["1relay", "re lay", "relay/", "a__b", "", "relay-1"])
def test_invalid_ros_names_are_named(name):
    with pytest.raises(ValueError, match="--relay"):
        check_ros_namespace(name, "--relay")
    r = runner.invoke(app, ["ros", SCENARIO, "--relay", name, "--duration", "1"])
    assert r.exit_code == 2 and "not a ROS 2 namespace" in r.output


def test_valid_ros_names_pass():
    assert check_ros_namespace("r1", "--relay") == "r1"
    assert check_ros_namespace("/fleet/r_2", "--relay") == "fleet/r_2"


def test_fly_exits_3_on_an_unsafe_flight(monkeypatch):
    """Before: ``aerorelay fly`` exited 0 while metrics.json said unsafe."""
    import pandas as pd

    from aerorelay import api

    class Flown:
        metrics = {"unsafe": True, "unsafe_reason": "left the workspace by 490.00 m"}

    monkeypatch.setattr(api, "fly", lambda *a, **k: (Flown(), pd.DataFrame({"mode": ["nmpc"], "relay": ["relay"]})))
    r = runner.invoke(app, ["fly", SCENARIO, "--mavlink", "udpout:127.0.0.1:14999"])
    assert r.exit_code == 3 and "left the workspace by 490.00 m" in r.output


def test_a_lockstep_flight_names_the_telemetry_it_did_not_trust():
    """flight.parquet's ``rejected`` column and the metrics' count: none on a clean lockstep flight."""
    sc = ar.load_scenario(SCENARIO)
    result, log = ar.fly_lockstep(sc, ar.PointMass(sc.nodes.relay), duration_s=1.0)
    assert "rejected" in log and (log["rejected"] == "").all()
    assert result.metrics["telemetry_rejected_periods"] == 0 and result.metrics["telemetry_rejected_reason"] == ""
    assert not result.metrics["unsafe"]
