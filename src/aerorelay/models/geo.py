"""Geographic mission files in the scenario's local frame: a QGroundControl ``.plan`` (MAVLink mission
items) and a GPX track, converted from WGS84 (latitude, longitude in deg, altitude in m above the
ellipsoid) to local east-north-up metres at a geodetic origin with pyproj (PROJ's ``cart`` and
``topocentric`` steps: exact ENU, not a flat-earth approximation).

* ``.plan``: the mission's position items (NAV_WAYPOINT 16, NAV_TAKEOFF 22, NAV_LOITER_TIME 19,
  NAV_LAND 21) in order; frames 0 / 5 (altitude above mean sea level, taken as above the ellipsoid:
  the geoid's offset is the same for every point of one mission and cancels against an origin given
  the same way) and 3 / 6 (altitude relative to the plan's home). Timing from the plan's speeds: the
  mission's ``hoverSpeed`` (default 5 m/s), changed by DO_CHANGE_SPEED (178); a waypoint's hold time
  (param 1) and a loiter's time add a second waypoint at the same place. Terrain-relative frames and
  items without a position are named errors.
* GPX: every track point of every segment (or, without tracks, the route points) with its time
  (required) and elevation (required), times from the first point.

Errors name the file, the item or point and the field (``ValueError``).
"""

from __future__ import annotations

import datetime
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LAND, NAV_TAKEOFF, DO_CHANGE_SPEED = 16, 19, 21, 22, 178
POSITION_COMMANDS = (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LAND, NAV_TAKEOFF)
AMSL_FRAMES, RELATIVE_FRAMES = (0, 5), (3, 6)  # MAV_FRAME_GLOBAL(_INT), MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT)
DEFAULT_HOVER_SPEED_M_S = 5.0  # QGroundControl's default multirotor mission speed


class GeoFrame:
    """Local east-north-up metres at a geodetic ``origin`` ``(lat_deg, lon_deg, alt_m)`` (WGS84)."""

    def __init__(self, origin):
        from pyproj import Transformer  # the geodesy standard; imported where it is used

        lat, lon, alt = (float(v) for v in origin)
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and math.isfinite(alt)):
            raise ValueError(f"geodetic origin {origin}: need lat in [-90, 90] deg, lon in [-180, 180] deg, a finite altitude")
        self.origin = (lat, lon, alt)
        pipeline = (f"+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart +ellps=WGS84 "
                    f"+step +proj=topocentric +ellps=WGS84 +lat_0={lat!r} +lon_0={lon!r} +h_0={alt!r}")
        self._t = Transformer.from_pipeline(pipeline)

    def to_local(self, lat, lon, alt) -> np.ndarray:
        """``(n, 3)`` east, north, up (m) of points in degrees and metres."""
        e, n, u = self._t.transform(np.asarray(lon, float), np.asarray(lat, float), np.asarray(alt, float))
        return np.column_stack([np.atleast_1d(e), np.atleast_1d(n), np.atleast_1d(u)])

    def to_geodetic(self, enu) -> np.ndarray:
        """``(n, 3)`` latitude (deg), longitude (deg), altitude (m) of local points (the inverse)."""
        enu = np.atleast_2d(np.asarray(enu, float))
        lon, lat, alt = self._t.transform(enu[:, 0], enu[:, 1], enu[:, 2], direction="INVERSE")
        return np.column_stack([np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(alt)])


@dataclass(frozen=True)
class GeoPoint:
    """A timed geodetic point: time (s), latitude and longitude (deg), altitude (m)."""

    t: float
    lat: float
    lon: float
    alt: float


def _number(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{where}: not a finite number ({v!r})")
    return float(v)


def read_plan(path: str | Path) -> tuple[tuple[float, float, float], list[GeoPoint]]:
    """A QGroundControl ``.plan``: its home ``(lat, lon, alt)`` and the mission's timed points (see the module)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable QGroundControl plan ({type(exc).__name__}: {exc})") from None
    mission = doc.get("mission") if isinstance(doc, dict) else None
    if not isinstance(mission, dict) or not isinstance(mission.get("items"), list):
        raise ValueError(f"{path}: no mission.items (a QGroundControl .plan has fileType 'Plan' and a mission table)")
    home = mission.get("plannedHomePosition")
    if not (isinstance(home, list) and len(home) == 3):
        raise ValueError(f"{path}: mission.plannedHomePosition must be [lat, lon, alt]")
    lat0, lon0, alt0 = (_number(v, f"{path}: mission.plannedHomePosition[{i}]") for i, v in enumerate(home))
    home_t = (lat0, lon0, alt0)
    speed = _number(mission.get("hoverSpeed", DEFAULT_HOVER_SPEED_M_S), f"{path}: mission.hoverSpeed")
    if speed <= 0:
        raise ValueError(f"{path}: mission.hoverSpeed must be > 0 m/s, got {speed}")
    frame = GeoFrame(home_t)
    points: list[GeoPoint] = []
    t, last = 0.0, None
    for k, item in enumerate(mission["items"]):
        where = f"{path}: mission.items[{k}]"
        if not isinstance(item, dict):
            raise ValueError(f"{where}: not an item table")
        if item.get("type") != "SimpleItem":
            raise ValueError(f"{where}: type {item.get('type')!r}; only SimpleItem is read (flatten surveys and "
                             "structure scans into waypoints in QGroundControl)")
        command, params = item.get("command"), item.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise ValueError(f"{where}.params: need the seven MAVLink mission-item parameters")
        if command == DO_CHANGE_SPEED:
            new = _number(params[1], f"{where}.params[1] (speed)")
            if new > 0:
                speed = new
            continue
        if command not in POSITION_COMMANDS:
            continue  # camera, gimbal and other commands do not move the vehicle
        frame_id = item.get("frame")
        lat, lon = _number(params[4], f"{where}.params[4] (latitude)"), _number(params[5], f"{where}.params[5] (longitude)")
        alt = _number(params[6], f"{where}.params[6] (altitude)")
        if frame_id in RELATIVE_FRAMES:
            alt += home_t[2]
        elif frame_id not in AMSL_FRAMES:
            raise ValueError(f"{where}.frame: {frame_id!r}; read are 0/5 (above mean sea level) and 3/6 (relative to "
                             "home); terrain-relative altitudes need a terrain model")
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise ValueError(f"{where}: latitude {lat} / longitude {lon} out of range")
        here = frame.to_local(lat, lon, alt)[0]
        if last is not None:
            t += float(np.linalg.norm(here - last)) / speed
        points.append(GeoPoint(t, lat, lon, alt))
        hold = _number(params[0], f"{where}.params[0] (hold time)") if command in (NAV_WAYPOINT, NAV_LOITER_TIME) else 0.0
        if hold > 0:
            t += hold
            points.append(GeoPoint(t, lat, lon, alt))
        last = here
    if len(points) < 2:
        raise ValueError(f"{path}: the mission has {len(points)} position item(s); a path needs two at least")
    return home_t, points


def xml_text(data: bytes) -> str:
    """An XML file's text in the encoding its declaration names (``<?xml ... encoding="ISO-8859-1"?>``; UTF-8 when it
    names none, as XML defines), its declaration's encoding removed (the text is decoded already)."""
    head = re.match(rb"\s*<\?xml[^>]*?encoding\s*=\s*[\"']([A-Za-z0-9._-]+)[\"']", data)
    encoding = head.group(1).decode("ascii") if head else "utf-8"
    text = data.decode(encoding)
    return re.sub(r"(<\?xml[^>]*?)\s+encoding\s*=\s*[\"'][A-Za-z0-9._-]+[\"']", r"\1", text, count=1)


def read_gpx(path: str | Path) -> list[GeoPoint]:
    """A GPX file's timed points (every track point, or else every route point), times from the first (s)."""
    import gpxpy  # the GPX standard's reader; imported where it is used

    path = Path(path)
    try:
        doc = gpxpy.parse(xml_text(path.read_bytes()))
    except (OSError, UnicodeDecodeError, LookupError, ValueError, gpxpy.gpx.GPXException) as exc:
        raise ValueError(f"{path}: not a readable GPX file ({type(exc).__name__}: {exc})") from None
    raw: list = [(f"track {i} segment {j} point {k}", p) for i, tr in enumerate(doc.tracks)
                 for j, seg in enumerate(tr.segments) for k, p in enumerate(seg.points)]
    if not raw:
        raw = [(f"route {i} point {k}", p) for i, r in enumerate(doc.routes) for k, p in enumerate(r.points)]
    if len(raw) < 2:
        raise ValueError(f"{path}: {len(raw)} track or route point(s); a path needs two at least")
    out, t0 = [], None
    for where, p in raw:
        if p.time is None:
            raise ValueError(f"{path}: {where}: no <time> (a timed track is needed to fly it)")
        if p.elevation is None or not math.isfinite(p.elevation):
            raise ValueError(f"{path}: {where}: " + ("no <ele>" if p.elevation is None else f"<ele> {p.elevation} is not a "
                             "number") + " (an altitude is needed to fly it)")
        if not (math.isfinite(p.latitude) and -90.0 <= p.latitude <= 90.0 and math.isfinite(p.longitude)
                and -180.0 <= p.longitude <= 180.0):
            raise ValueError(f"{path}: {where}: lat {p.latitude:g}, lon {p.longitude:g} is not on the earth (latitude in "
                             "[-90, 90], longitude in [-180, 180] degrees)")
        stamp = p.time if p.time.tzinfo else p.time.replace(tzinfo=datetime.UTC)
        t0 = stamp if t0 is None else t0
        out.append(GeoPoint((stamp - t0).total_seconds(), float(p.latitude), float(p.longitude), float(p.elevation)))
    times = np.array([q.t for q in out])
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        raise ValueError(f"{path}: {raw[bad[0] + 1][0]}: its time is not after the one before (times must increase)")
    return out


def local_samples(points: list[GeoPoint], frame: GeoFrame) -> tuple[np.ndarray, np.ndarray]:
    """Times ``(n,)`` (s) and local positions ``(n, 3)`` (m, ENU at the frame's origin) of ``points``."""
    t = np.array([p.t for p in points])
    enu = frame.to_local([p.lat for p in points], [p.lon for p in points], [p.alt for p in points])
    return t, enu
