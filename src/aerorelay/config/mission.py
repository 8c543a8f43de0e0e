"""``[mission]``: MRAV-2's path as data (timed waypoints, or a CSV or PX4 ULog flight file, read
and checked when the table is validated: the file is part of the data)."""

from __future__ import annotations

import functools
from pathlib import Path

from pydantic import Field, field_validator, model_validator

from ..filecheck import not_a_file
from ..models.mission import CsvPath, GpxPath, PlanPath, SourceTrajectory, UlogPath
from .base import Strict, Vec3, Waypoint, check_waypoint_times, on_the_earth


@functools.lru_cache(maxsize=16)
def _flight_file_path(kind: str, file: str, stamp: tuple, yaw_deg: float, offset: tuple, origin: tuple | None):
    """A CSV, ULog, QGroundControl plan or GPX path, cached by file, modification stamp and frame (read-only objects)."""
    path: SourceTrajectory
    if kind == "ulog":
        path = UlogPath(file, yaw_deg=yaw_deg, offset=list(offset))
    elif kind == "plan":
        path = PlanPath(file, origin)
    elif kind == "gpx":
        path = GpxPath(file, origin)
    else:
        path = CsvPath(file)
    return path


def flight_path(kind: str, file: str, yaw_deg: float = 0.0, offset=(0.0, 0.0, 0.0), origin=None):
    """A mission file's path (``kind`` ``csv``, ``ulog``, ``plan`` or ``gpx``), read once per content:
    every check of a load and the path itself share it. ValueError names a file that cannot be read."""
    st = Path(file).stat()
    return _flight_file_path(kind, file, (st.st_mtime_ns, st.st_size), float(yaw_deg), tuple(offset),
                             None if origin is None else tuple(origin))


def readable_file(field: str, file: str, read) -> None:
    """``file`` (named by ``field``) exists and ``read()`` reads it; a ValueError naming the field otherwise."""
    why = not_a_file(file)
    if why is not None:
        raise ValueError(f"{field}: {why}: {file}")
    try:
        read()
    except ValueError as exc:
        raise ValueError(f"{field}: {exc}") from None


FILE_KINDS = {"trajectory_csv": "csv", "trajectory_ulog": "ulog", "trajectory_plan": "plan", "trajectory_gpx": "gpx"}
COPY_NAMES = {"csv": "mission.csv", "ulog": "mission.ulg", "plan": "mission.plan", "gpx": "mission.gpx"}  # a run folder's copy


class MissionConfig(Strict):
    """MRAV-2 path: minimum-jerk segments through timed waypoints ``[t_s, x, y, z]`` or a CSV."""

    waypoints: list[Waypoint] = Field(
        default_factory=lambda: [
            [0.0, -3.04, 5.79, 1.72],
            [12.0, -1.5, 4.29, 9.0],
            [17.0, -1.5, 4.29, 9.0],
            [28.0, -3.0, 4.29, 16.5],
            [38.0, 0.0, 4.29, 16.5],
            [47.0, -1.5, 4.29, 17.5],
        ],
        min_length=2,
        description="MRAV-2's timed path [[t_s, x, y, z], ...] (s, m world), minimum-jerk segments, first time 0",
    )
    trajectory_csv: str | None = Field(None, description="CSV with columns t,px,py,pz,vx,vy,vz,ax,ay,az (or t,px,py,pz)")
    trajectory_ulog: str | None = Field(None, description="PX4 flight log (ULog): vehicle_local_position, NED")
    ulog_yaw_deg: float = Field(0.0, ge=-360.0, le=360.0, description="turns the ULog's east-north frame about z, deg")
    ulog_offset_m: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="shifts the ULog's path, m (world)")
    trajectory_plan: str | None = Field(None, description="a QGroundControl .plan (MAVLink mission items, WGS84): its "
                                        "waypoints, loiters and speeds timed into minimum-jerk segments in the local frame at "
                                        "geo_origin (default the plan's home)")
    trajectory_gpx: str | None = Field(None, description="a GPX track (timed points with elevation, WGS84) in the local "
                                       "frame at geo_origin (default its first point)")
    geo_origin: Vec3 | None = Field(None, description="where the scenario's local frame sits: [lat_deg, lon_deg, alt_m] "
                                    "(WGS84; x east, y north, z up, m); default [geo] origin, else the file's home / first point")

    @field_validator("waypoints")
    @classmethod
    def _increasing_times(cls, wps):
        check_waypoint_times(wps, first_zero=True)
        return wps

    @field_validator("trajectory_csv")
    @classmethod
    def _readable_csv(cls, v):
        if v is None:
            return v
        why = not_a_file(v)
        if why is not None:
            raise ValueError(f"{why}: {v}")
        flight_path("csv", v)  # finite numbers, >= 2 rows, increasing time, every column (ValueError names the problem)
        return v

    _geo_origin_on_the_earth = field_validator("geo_origin")(lambda v: v if v is None else on_the_earth(v))

    @model_validator(mode="after")
    def _readable_geo_file(self):
        given = [f for f in FILE_KINDS if getattr(self, f) is not None]
        if len(given) > 1:
            raise ValueError(f"give one of {', '.join(FILE_KINDS)}, not {' and '.join(given)}")
        for field in ("trajectory_plan", "trajectory_gpx"):
            f = getattr(self, field)
            if f is None:
                continue
            readable_file(field, f, lambda field=field, f=f: flight_path(FILE_KINDS[field], f, origin=self.geo_origin))
        return self

    @model_validator(mode="after")
    def _readable_ulog(self):
        if self.trajectory_ulog is None:
            return self
        if self.trajectory_csv is not None:
            raise ValueError("give one of trajectory_csv and trajectory_ulog, not both")
        ulog = self.trajectory_ulog
        readable_file("trajectory_ulog", ulog, lambda: flight_path("ulog", ulog, self.ulog_yaw_deg, self.ulog_offset_m))
        return self

    @property
    def flown_field(self) -> str | None:
        """The field of the mission file that flies (``trajectory_csv`` / ``_ulog`` / ``_plan`` / ``_gpx``), if any."""
        return next((f for f in ("trajectory_ulog", "trajectory_csv", "trajectory_plan", "trajectory_gpx")
                     if getattr(self, f) is not None), None)

    @property
    def flown_file(self) -> str | None:
        """The mission file that flies (ULog, CSV, plan or GPX), if any."""
        field = self.flown_field
        return None if field is None else getattr(self, field)

    @property
    def copy_name(self) -> str | None:
        """The name of the flown file's copy in a run folder (``mission.csv``, ``.ulg``, ``.plan``, ``.gpx``)."""
        field = self.flown_field
        return None if field is None else COPY_NAMES[FILE_KINDS[field]]

    def flight(self) -> CsvPath | UlogPath | PlanPath | GpxPath | None:
        """The flight file's reading (``models.mission``), read once per content stamp (the checks
        of a load ask for it several times); None for a waypoint mission or a file that is gone."""
        f = self.flown_file
        if not (f and Path(f).is_file()):
            return None
        if self.trajectory_ulog:
            return flight_path("ulog", f, self.ulog_yaw_deg, self.ulog_offset_m)
        kind = FILE_KINDS[self.flown_field or "trajectory_csv"]
        return flight_path(kind, f, origin=self.geo_origin if kind in ("plan", "gpx") else None)

    @property
    def duration_s(self) -> float:
        """Mission length (s): the last waypoint's time, or the flight file's last time."""
        flight = self.flight()
        return flight.duration if flight is not None else self.waypoints[-1][0]

    @property
    def start(self) -> list[float]:
        """MRAV-2's initial position (m)."""
        flight = self.flight()
        if flight is not None:
            return [float(v) for v in flight.state(0.0).p]
        return list(self.waypoints[0][1:])
