"""MRAV-2 (source) inspection path: minimum-jerk segments through timed waypoints, or a CSV.

Each segment is a rest-to-rest minimum-jerk quintic, so position, velocity and acceleration are
continuous (velocity and acceleration vanish at every waypoint). Times in s, world frame, m.
MRAV-2 is coplanar: its attitude follows its acceleration (body z along ``(a + g e3)/|a + g e3|``,
zero yaw), so its antenna tilts with it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pyulog import ULog
from scipy.interpolate import make_smoothing_spline

from .geo import GeoFrame, local_samples, read_gpx, read_plan
from .geometry import E3, attitude_from_thrust

CSV_COLUMNS = ("t", "px", "py", "pz", "vx", "vy", "vz", "ax", "ay", "az")


@dataclass(frozen=True)
class SourceState:
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def attitude(self, gravity: float = 9.81) -> np.ndarray:
        """ZYX Euler angles (rad) of MRAV-2: body z along ``(a + g e3)``, zero yaw."""
        return attitude_from_thrust(self.a + gravity * E3, 0.0)


class SourceTrajectory:
    """Piecewise path queried by time; holds the last point after the end."""

    def state(self, t: float) -> SourceState:  # pragma: no cover - interface
        raise NotImplementedError

    @property
    def duration(self) -> float:  # pragma: no cover - interface
        raise NotImplementedError

    def attitude(self, t: float, gravity: float = 9.81) -> np.ndarray:
        """ZYX Euler angles (rad) of MRAV-2: body z along ``(a + g e3)``, zero yaw."""
        return self.state(t).attitude(gravity)


class _WaypointPath(SourceTrajectory):
    """A path through timed ``waypoints`` rows ``[t, x, y, z]`` (s, m)."""

    def __init__(self, waypoints):
        wp = np.asarray(waypoints, dtype=float)
        self.t = wp[:, 0]
        self.p = wp[:, 1:4]

    @property
    def duration(self) -> float:
        return float(self.t[-1])


class MinimumJerkPath(_WaypointPath):
    """Rest-to-rest minimum-jerk segments through ``waypoints`` rows ``[t, x, y, z]``."""

    def state(self, t: float) -> SourceState:
        if t <= self.t[0]:
            return SourceState(self.p[0].copy(), np.zeros(3), np.zeros(3))
        if t >= self.t[-1]:
            return SourceState(self.p[-1].copy(), np.zeros(3), np.zeros(3))
        i = int(np.searchsorted(self.t, t, side="right") - 1)
        T = self.t[i + 1] - self.t[i]
        s = (t - self.t[i]) / T
        dp = self.p[i + 1] - self.p[i]
        # s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 and its derivatives
        pos = 10 * s**3 - 15 * s**4 + 6 * s**5
        vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
        acc = (60 * s - 180 * s**2 + 120 * s**3) / T**2
        return SourceState(self.p[i] + pos * dp, vel * dp, acc * dp)


class LinearPath(_WaypointPath):
    """Straight segments at constant speed through ``waypoints`` rows ``[t, x, y, z]`` (e.g. a
    jammer driving along a road); holds the first/last point outside the waypoints' times.
    Acceleration is zero inside a segment (the corners are instantaneous turns)."""

    def state(self, t: float) -> SourceState:
        if t <= self.t[0] or t >= self.t[-1]:
            return SourceState((self.p[0] if t <= self.t[0] else self.p[-1]).copy(), np.zeros(3), np.zeros(3))
        i = int(np.searchsorted(self.t, t, side="right") - 1)
        T = self.t[i + 1] - self.t[i]
        v = (self.p[i + 1] - self.p[i]) / T
        return SourceState(self.p[i] + v * (t - self.t[i]), v, np.zeros(3))


class RepeatingPath(SourceTrajectory):
    """``path`` flown again and again from its first waypoint's time ``t0`` on, with period
    ``T = duration - t0`` (a jammer circling a site: its last waypoint back at its first); holds the
    first point before ``t0``. Its ``duration`` is infinite."""

    def __init__(self, path: _WaypointPath):
        self.path, self.t0 = path, float(path.t[0])
        self.period = float(path.t[-1]) - self.t0

    @property
    def duration(self) -> float:
        return float("inf")

    def state(self, t: float) -> SourceState:
        if t <= self.t0:
            return self.path.state(t)
        return self.path.state(self.t0 + (t - self.t0) % self.period)


class SampledPath(SourceTrajectory):
    """A path from samples: times ``t`` (s, increasing), positions, velocities, accelerations
    ``(n, 3)`` (world), linearly interpolated; holds the first/last sample outside them."""

    def __init__(self, t, p, v, a):
        self.t = np.asarray(t, float)
        names = ("px", "py", "pz", "vx", "vy", "vz", "ax", "ay", "az")
        self.cols = dict(zip(names, np.column_stack([p, v, a]).T, strict=True))

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def state(self, t: float) -> SourceState:
        g = {c: np.interp(t, self.t, v) for c, v in self.cols.items()}
        return SourceState(
            np.array([g["px"], g["py"], g["pz"]]), np.array([g["vx"], g["vy"], g["vz"]]), np.array([g["ax"], g["ay"], g["az"]])
        )


def smooth_derivatives(t: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration of sampled positions ``(n, 3)`` from a cubic smoothing spline per
    axis (scipy's ``make_smoothing_spline``, its smoothing chosen by generalized cross-validation)."""
    v, a = np.empty_like(p), np.empty_like(p)
    for i in range(3):
        spl = make_smoothing_spline(t, p[:, i])
        v[:, i], a[:, i] = spl.derivative(1)(t), spl.derivative(2)(t)
    return v, a


POSITION_COLUMNS = ("t", "px", "py", "pz")
MAX_TRACK_ROWS = 500_000  # a mission file's samples at most: 83 min at 100 Hz (a 3,000,000-row CSV took 150 s and 1.6 GB)
MAX_TRACK_BYTES = 100 * 2**20  # ... and its size (a GPX or ULog: a track's XML or log, not a mission, above this)


def check_track_size(path: str | Path, *, rows: bool) -> None:
    """A mission file small enough to read in bounded time, before it is read: at most ``MAX_TRACK_BYTES`` and (a
    text file of one sample per line, ``rows``) ``MAX_TRACK_ROWS`` lines; ValueError naming the file, its size and
    the limit otherwise."""
    size = Path(path).stat().st_size
    if size > MAX_TRACK_BYTES:
        raise ValueError(f"{path}: {size / 2**20:.0f} MiB, larger than a mission file is read ({MAX_TRACK_BYTES // 2**20} MiB): "
                         "thin the track (every k-th sample) or cut it to the mission")
    if rows:
        with open(path, "rb") as f:
            lines = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(2**20), b""))
        if lines > MAX_TRACK_ROWS + 1:
            raise ValueError(f"{path}: {lines - 1:,} rows, more than a mission file is read ({MAX_TRACK_ROWS:,}: "
                             f"{MAX_TRACK_ROWS / 100 / 60:.0f} min at 100 Hz): thin the track (every k-th row)")


class CsvPath(SampledPath):
    """A user trajectory from a CSV with header ``t,px,py,pz,vx,vy,vz,ax,ay,az``, or positions only
    ``t,px,py,pz`` (velocity and acceleration then from a smoothing spline); linear interpolation."""

    def __init__(self, path: str | Path):
        check_track_size(path, rows=True)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # numpy's warnings (empty file, ragged rows) become named errors
                data = np.genfromtxt(path, delimiter=",", names=True, ndmin=1)
        except (OSError, ValueError, UserWarning) as exc:
            raise ValueError(f"{path}: not a readable CSV ({exc})") from None
        names = data.dtype.names or ()
        full = all(c in names for c in CSV_COLUMNS)
        if not full and not all(c in names for c in POSITION_COLUMNS):
            missing = [c for c in CSV_COLUMNS if c not in names]
            raise ValueError(f"{path}: missing CSV columns {missing}; expected {','.join(CSV_COLUMNS)} or {','.join(POSITION_COLUMNS)}")
        least = 2 if full else 5  # positions only: the smoothing spline needs 5 samples
        if data.size < least:
            raise ValueError(f"{path}: needs at least {least} rows of data, has {data.size}")
        for c in CSV_COLUMNS if full else POSITION_COLUMNS:
            col = np.asarray(data[c], float)
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise ValueError(f"{path}: column {c} row {bad[0] + 1} is not a finite number")
        t = np.asarray(data["t"], float)
        if np.any(np.diff(t) <= 0):
            raise ValueError(f"{path}: column t must be strictly increasing")
        p = np.column_stack([np.asarray(data[c], float) for c in ("px", "py", "pz")])
        if full:
            v = np.column_stack([np.asarray(data[c], float) for c in ("vx", "vy", "vz")])
            a = np.column_stack([np.asarray(data[c], float) for c in ("ax", "ay", "az")])
        else:
            try:
                with warnings.catch_warnings():  # absurd samples overflow inside scipy; the scenario names them
                    warnings.simplefilter("ignore", RuntimeWarning)
                    v, a = smooth_derivatives(t, p)
            except ValueError as exc:
                raise ValueError(f"{path}: no smooth velocity and acceleration fit these positions (scipy: {exc}); "
                                 f"give the columns {','.join(CSV_COLUMNS)}") from None
        super().__init__(t, p, v, a)


def ned_to_world(p_ned: np.ndarray, yaw_deg: float = 0.0, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """PX4's local NED (x north, y east, z down) to this project's world frame (z up): east, north,
    up, then turned by ``yaw_deg`` about z and shifted by ``offset`` (m)."""
    enu = np.column_stack([p_ned[:, 1], p_ned[:, 0], -p_ned[:, 2]])
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return enu @ R.T + np.asarray(offset, float)


ULOG_HEADER_BYTES = 16  # magic (7), version (1), timestamp (8); then messages: uint16 size, uint8 type, payload


def ulog_cut_at(path: str | Path) -> int | None:
    """Where a ULog file is cut (the byte offset of its last, incomplete message), or None when its
    messages end exactly at the end of the file. pyulog stops silently at a cut message, so a log
    truncated in the middle would otherwise fly as a shorter mission."""
    data = Path(path).read_bytes()
    pos, end = ULOG_HEADER_BYTES, len(data)
    while pos + 3 <= end:
        size = int.from_bytes(data[pos:pos + 2], "little")
        if pos + 3 + size > end:
            return pos
        pos += 3 + size
    return None if pos == end else pos


class UlogPath(SampledPath):
    """MRAV-2's path from a PX4 flight log (ULog): ``vehicle_local_position`` (x, y, z, vx, vy, vz,
    ax, ay, az; NED) converted to the world frame (``ned_to_world``; velocities and accelerations
    turned, not shifted), time from the first sample (s)."""

    TOPIC = "vehicle_local_position"

    def __init__(self, path: str | Path, *, yaw_deg: float = 0.0, offset=(0.0, 0.0, 0.0)):
        try:
            log = ULog(str(path), message_name_filter_list=[self.TOPIC])
        except Exception as exc:  # pyulog raises several kinds on a corrupt file
            raise ValueError(f"{path}: not a readable PX4 ULog ({type(exc).__name__}: {exc})") from None
        if log.file_corruption:
            raise ValueError(f"{path}: pyulog reports a corrupt file (bytes skipped to find its messages again)")
        cut = ulog_cut_at(path)
        if cut is not None:
            raise ValueError(f"{path}: truncated: its last message, at byte {cut} of {Path(path).stat().st_size}, is incomplete "
                             "(the file was cut while written or copied); flying it would fly part of the mission")
        data = next((d for d in log.data_list if d.name == self.TOPIC), None)
        if data is None:
            raise ValueError(f"{path}: no {self.TOPIC} topic in this ULog")
        d = data.data
        need = ("timestamp", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")
        missing = [f for f in need if f not in d]
        if missing:
            raise ValueError(f"{path}: {self.TOPIC} lacks the fields {missing}")
        t = (np.asarray(d["timestamp"], float) - float(d["timestamp"][0])) * 1e-6
        if t.size < 2 or np.any(np.diff(t) <= 0):
            raise ValueError(f"{path}: {self.TOPIC} needs >= 2 samples at increasing times")
        cols = {f: np.asarray(d[f], float) for f in need[1:]}
        for f, c in cols.items():
            bad = np.flatnonzero(~np.isfinite(c))
            if bad.size:
                raise ValueError(f"{path}: {self.TOPIC} holds non-finite values ({f} of sample {bad[0] + 1})")
        turn = (lambda x, y, z: ned_to_world(np.column_stack([x, y, z]), yaw_deg))
        p = ned_to_world(np.column_stack([cols["x"], cols["y"], cols["z"]]), yaw_deg, offset)
        super().__init__(t, p, turn(cols["vx"], cols["vy"], cols["vz"]), turn(cols["ax"], cols["ay"], cols["az"]))


class CirclePath(SourceTrajectory):
    """Horizontal circles about ``center`` (m, world) of ``radius`` (m), one lap every ``period`` (s),
    from due east of the center, counter-clockwise seen from above unless ``clockwise``; analytic
    velocity and (centripetal) acceleration. Its ``duration`` is infinite."""

    def __init__(self, center, radius: float, period: float, clockwise: bool = False):
        self.center, self.r = np.asarray(center, float), float(radius)
        self.period, self.clockwise = float(period), bool(clockwise)
        self.w = (-1.0 if clockwise else 1.0) * 2.0 * np.pi / float(period)

    @property
    def duration(self) -> float:
        return math.inf

    def state(self, t: float) -> SourceState:
        c, s = math.cos(self.w * t), math.sin(self.w * t)
        p = self.center + self.r * np.array([c, s, 0.0])
        v = self.r * self.w * np.array([-s, c, 0.0])
        a = -self.r * self.w**2 * np.array([c, s, 0.0])
        return SourceState(p, v, a)


class PlanPath(MinimumJerkPath):
    """MRAV-2's path from a QGroundControl ``.plan`` (``models.geo.read_plan``): its position items as
    timed waypoints in the local frame at ``origin`` (default the plan's home), minimum-jerk segments."""

    def __init__(self, path: str | Path, origin=None):
        check_track_size(path, rows=False)
        home, points = read_plan(path)
        t, enu = local_samples(points, GeoFrame(origin if origin is not None else home))
        keep = np.concatenate([[True], np.diff(t) > 1e-9])  # two items at one place without a hold: one waypoint
        super().__init__(np.column_stack([t[keep], enu[keep]]))
        self.cols = {"px": self.p[:, 0], "py": self.p[:, 1], "pz": self.p[:, 2]}  # its samples, as a sampled path's


class GpxPath(SampledPath):
    """MRAV-2's path from a GPX track (``models.geo.read_gpx``) in the local frame at ``origin``
    (default its first point), velocity and acceleration from a smoothing spline (as a positions-only CSV)."""

    def __init__(self, path: str | Path, origin=None):
        check_track_size(path, rows=False)
        points = read_gpx(path)
        if len(points) > MAX_TRACK_ROWS:
            raise ValueError(f"{path}: {len(points):,} points, more than a mission file is read ({MAX_TRACK_ROWS:,}): "
                             "thin the track (every k-th point)")
        first = (points[0].lat, points[0].lon, points[0].alt)
        t, p = local_samples(points, GeoFrame(origin if origin is not None else first))
        if t.size < 5:
            raise ValueError(f"{path}: needs at least 5 timed points (the smoothing spline of its velocity), has {t.size}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            v, a = smooth_derivatives(t, p)
        super().__init__(t, p, v, a)


def source_trajectory(mission) -> SourceTrajectory:
    """Build MRAV-2's path from a ``MissionConfig``: a ULog, a CSV, or waypoints."""
    if getattr(mission, "trajectory_ulog", None):
        return UlogPath(mission.trajectory_ulog, yaw_deg=mission.ulog_yaw_deg, offset=mission.ulog_offset_m)
    if getattr(mission, "trajectory_plan", None) or getattr(mission, "trajectory_gpx", None):
        flight = mission.flight()
        if flight is None:
            raise ValueError(f"{mission.flown_file}: no such file")
        return flight
    if mission.trajectory_csv:
        return CsvPath(mission.trajectory_csv)
    return MinimumJerkPath(mission.waypoints)


MAX_FILE_SPEED_M_S = 100.0  # no multirotor (nor a jammer's car) flies a mission faster: a faster file is a units error


def check_flies(path) -> None:
    """A mission that is one: longer than 0 s, no faster than ``MAX_FILE_SPEED_M_S`` anywhere (sampled every 0.1 s
    and at its points); ValueError saying which otherwise (a .plan with every item at one place flew a 0 s mission)."""
    if not path.duration > 0.0:
        raise ValueError(f"a mission of {path.duration:g} s: its points are all at one place or at one time (nothing to fly)")
    t = np.linspace(0.0, path.duration, int(min(max(path.duration / 0.1, 2), 20000)) + 1)
    speed = np.array([float(np.linalg.norm(path.state(float(k)).v)) for k in t])
    k = int(np.argmax(speed))
    if speed[k] > MAX_FILE_SPEED_M_S:
        raise ValueError(f"flown at {speed[k]:.3g} m/s at t = {t[k]:.3g} s, faster than any multirotor mission "
                         f"({MAX_FILE_SPEED_M_S:g} m/s): a units error? (a .plan's speed, a CSV's time column in ms)")
