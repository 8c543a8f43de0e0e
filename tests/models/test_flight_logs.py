"""Flight logs as missions: a PX4 ULog written by the test itself (the format's binary layout),
NED converted to the world frame with the offset/rotation option; CSVs with positions only."""

import struct

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.models.mission import CsvPath, UlogPath, ned_to_world

FIELDS = ("x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def write_ulog(path, t_us, rows):
    """A minimal ULog: header, flag bits, the vehicle_local_position format, one subscription, data."""
    fmt = "vehicle_local_position:uint64_t timestamp;" + "".join(f"float {f};" for f in FIELDS)
    out = b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0)
    out += _msg("B", bytes(16) + struct.pack("<QQQ", 0, 0, 0))
    out += _msg("F", fmt.encode())
    out += _msg("A", struct.pack("<BH", 0, 0) + b"vehicle_local_position")
    for ts, r in zip(t_us, rows, strict=True):
        out += _msg("D", struct.pack("<H", 0) + struct.pack("<Q", int(ts)) + struct.pack("<9f", *r))
    path.write_bytes(out)


def _flight(n=200, dt=0.05):
    t = np.arange(n) * dt
    # NED: north 0.5 m/s, east 0.2 m/s, climbing 0.3 m/s from 2 m up (z down)
    rows = np.column_stack([0.5 * t, 0.2 * t, -2.0 - 0.3 * t, np.full(n, 0.5), np.full(n, 0.2), np.full(n, -0.3),
                            np.zeros(n), np.zeros(n), np.zeros(n)])
    return 1_000_000 + (t * 1e6).astype(np.int64), rows


def test_ulog_path_converts_ned_and_applies_offset_and_yaw(tmp_path):
    f = tmp_path / "flight.ulg"
    ts, rows = _flight()
    write_ulog(f, ts, rows)
    path = UlogPath(f, yaw_deg=90.0, offset=(1.0, -2.0, 0.5))
    assert path.duration == pytest.approx(199 * 0.05, abs=1e-9)
    s = path.state(2.0)
    # at 2 s: NED (1.0, 0.4, -2.6) -> ENU (0.4, 1.0, 2.6) -> yaw 90: (-1.0, 0.4, 2.6) -> + offset
    np.testing.assert_allclose(s.p, [0.0, -1.6, 3.1], atol=1e-5)
    np.testing.assert_allclose(s.v, [-0.5, 0.2, 0.3], atol=1e-6)  # turned, not shifted
    np.testing.assert_allclose(ned_to_world(np.array([[1.0, 0.0, 0.0]])), [[0.0, 1.0, 0.0]])


def test_a_ulog_mission_flies_and_is_checked(tmp_path):
    f = tmp_path / "flight.ulg"
    ts, rows = _flight()
    write_ulog(f, ts, rows)
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"mission.trajectory_ulog": str(f),
                                                                "mission.ulog_offset_m": [-3.04, 5.79, 0.0],
                                                                "sim.duration_s": 1.0})
    np.testing.assert_allclose(sc.mission.start, [-3.04, 5.79, 2.0], atol=1e-5)
    m = ar.simulate(sc).metrics
    assert m["steps"] == 67 and not m["unsafe"]
    with pytest.raises(ScenarioError, match="below ground"):
        sc.with_updates({"mission.ulog_offset_m": [0.0, 0.0, -10.0]})
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"not a log")
    with pytest.raises(ScenarioError, match="mission.trajectory_ulog|mission: .*trajectory_ulog"):
        sc.with_updates({"mission.trajectory_ulog": str(bad)})


def test_csv_with_positions_only_gets_smooth_derivatives(tmp_path):
    t = np.arange(0.0, 10.0001, 0.1)
    p = np.column_stack([np.sin(t), 0.5 * t**2, np.full_like(t, 3.0)])
    f = tmp_path / "pos.csv"
    np.savetxt(f, np.column_stack([t, p]), delimiter=",", header="t,px,py,pz", comments="")
    path = CsvPath(f)
    s = path.state(5.0)
    np.testing.assert_allclose(s.p, [np.sin(5.0), 12.5, 3.0], atol=1e-9)
    np.testing.assert_allclose(s.v, [np.cos(5.0), 5.0, 0.0], atol=2e-2)
    np.testing.assert_allclose(s.a, [-np.sin(5.0), 1.0, 0.0], atol=0.1)
