"""MRAV-2 (source) inspection path: minimum-jerk segments through timed waypoints, or a CSV.

Each segment is a rest-to-rest minimum-jerk quintic, so position, velocity and acceleration are
continuous (velocity and acceleration vanish at every waypoint). Times in s, world frame, m.
MRAV-2 is coplanar: its attitude follows its acceleration (body z along ``(a + g e3)/|a + g e3|``,
zero yaw), so its antenna tilts with it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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


class MinimumJerkPath(SourceTrajectory):
    """Rest-to-rest minimum-jerk segments through ``waypoints`` rows ``[t, x, y, z]``."""

    def __init__(self, waypoints):
        wp = np.asarray(waypoints, dtype=float)
        self.t = wp[:, 0]
        self.p = wp[:, 1:4]

    @property
    def duration(self) -> float:
        return float(self.t[-1])

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


class LinearPath(SourceTrajectory):
    """Straight segments at constant speed through ``waypoints`` rows ``[t, x, y, z]`` (e.g. a
    jammer driving along a road); holds the first/last point outside the waypoints' times.
    Acceleration is zero inside a segment (the corners are instantaneous turns)."""

    def __init__(self, waypoints):
        wp = np.asarray(waypoints, dtype=float)
        self.t = wp[:, 0]
        self.p = wp[:, 1:4]

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def state(self, t: float) -> SourceState:
        if t <= self.t[0] or t >= self.t[-1]:
            return SourceState((self.p[0] if t <= self.t[0] else self.p[-1]).copy(), np.zeros(3), np.zeros(3))
        i = int(np.searchsorted(self.t, t, side="right") - 1)
        T = self.t[i + 1] - self.t[i]
        v = (self.p[i + 1] - self.p[i]) / T
        return SourceState(self.p[i] + v * (t - self.t[i]), v, np.zeros(3))


class CsvPath(SourceTrajectory):
    """A user trajectory from a CSV with header ``t,px,py,pz,vx,vy,vz,ax,ay,az`` (linear interpolation)."""

    def __init__(self, path: str | Path):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # numpy's warnings (empty file, ragged rows) become named errors
                data = np.genfromtxt(path, delimiter=",", names=True, ndmin=1)
        except (OSError, ValueError, UserWarning) as exc:
            raise ValueError(f"{path}: not a readable CSV ({exc})") from None
        missing = [c for c in CSV_COLUMNS if c not in (data.dtype.names or ())]
        if missing:
            raise ValueError(f"{path}: missing CSV columns {missing}; expected {','.join(CSV_COLUMNS)}")
        if data.size < 2:
            raise ValueError(f"{path}: needs at least 2 rows of data, has {data.size}")
        for c in CSV_COLUMNS:
            col = np.asarray(data[c], float)
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise ValueError(f"{path}: column {c} row {bad[0] + 1} is not a finite number")
        self.t = np.asarray(data["t"], float)
        if np.any(np.diff(self.t) <= 0):
            raise ValueError(f"{path}: column t must be strictly increasing")
        self.cols = {c: np.asarray(data[c], float) for c in CSV_COLUMNS[1:]}

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def state(self, t: float) -> SourceState:
        g = {c: np.interp(t, self.t, v) for c, v in self.cols.items()}
        return SourceState(
            np.array([g["px"], g["py"], g["pz"]]), np.array([g["vx"], g["vy"], g["vz"]]), np.array([g["ax"], g["ay"], g["az"]])
        )


def source_trajectory(mission) -> SourceTrajectory:
    """Build MRAV-2's path from a ``MissionConfig``."""
    if mission.trajectory_csv:
        return CsvPath(mission.trajectory_csv)
    return MinimumJerkPath(mission.waypoints)
