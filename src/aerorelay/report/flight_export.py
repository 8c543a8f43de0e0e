"""A run's flown paths for autopilots and GIS tools (``aerorelay export RUN --format ...``; issue 63, item 4).

Every format is written into the run folder's ``export/`` (this program's; a file of the same name there is one it
wrote before and is replaced), from ``timeseries.parquet`` (world ENU, m; attitude ZYX, body FLU) and, for
geographic coordinates, the local frame's place on the earth (``[geo] origin`` of the run's scenario, or given):

- ``csv``: per vehicle, every logged step: ``t_s``; ``east_m, north_m, up_m`` (ENU); ``north_ned_m, east_ned_m,
  down_m`` (NED); ``lat_deg, lon_deg, alt_m`` (WGS84, with an origin); ``roll_rad, pitch_rad, yaw_rad`` (ZYX, world ENU,
  body FLU, as logged).
- ``plan``: per relay, a QGroundControl ``.plan`` (MAVLink mission, ``plannedHomePosition`` at the origin): a
  NAV_TAKEOFF at the start, then NAV_WAYPOINTs where the path bends (Douglas-Peucker, ``PLAN_TOLERANCE_M``), each
  after a DO_CHANGE_SPEED to the speed the relay flew that leg at, a waypoint where it hovered holding that long
  (param 1); altitudes relative to home (frame 3). Read back by ``models.geo.read_plan``: every waypoint on the flown
  path, the flown path within the tolerance of the waypoints' polyline, the times the flight's.
- ``geojson``: a FeatureCollection, one LineString per vehicle (``[lon, lat, alt]``, RFC 7946) with its name, role,
  first and last time.
- ``kml``: one placemark per vehicle (simplekml): its path as a LineString (absolute altitudes) and as a gx:Track
  with a time per point (Google Earth's time slider).
- ``ulog``: per relay, a PX4 ULog (the format of PX4's logger, version 1) with PX4's topic names and fields:
  ``vehicle_local_position`` (``x, y, z`` NED m, ``vx, vy, vz`` m/s, ``heading`` rad, ``xy_valid``, ``z_valid``,
  ``v_xy_valid``, ``v_z_valid``), ``vehicle_attitude`` (``q`` body FRD to NED, w x y z), ``vehicle_global_position``
  (``lat``, ``lon`` deg as float64, ``alt`` m, with an origin), ``vehicle_local_position_setpoint`` (the NMPC's
  position reference ``x, y, z``, NED m); infos ``sys_name``, ``ver_hw``, ``ver_sw``. Timestamps in us from the run's
  start. What PX4 logs besides (``vehicle_status``, sensors, estimator) is not written: Flight Review plots what a log
  has.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..flight.frames import rotation_enu_flu_to_ned_frd
from ..models.geo import DO_CHANGE_SPEED, NAV_TAKEOFF, NAV_WAYPOINT, GeoFrame
from ..models.geometry import quaternion_wxyz, rotation_zyx

FORMATS = ("csv", "plan", "geojson", "kml", "ulog")
GEOGRAPHIC = ("plan", "geojson", "kml")  # need the frame's place on the earth (csv and ulog add lat/lon with one)
PLAN_TOLERANCE_M = 0.05  # the .plan's waypoint polyline keeps the flown path within this (m)
EXPORT_FOLDER = "export"


TRACK_QUANTITIES = ("p_x", "p_y", "p_z", "phi", "theta", "psi")  # a vehicle's columns every export reads


def missing_columns(df: pd.DataFrame, names: list[str]) -> list[str]:
    """The columns an export of the vehicles ``names`` needs that the log lacks (``t`` and each one's pose)."""
    need = ["t", *(f"{n}.{q}" for n in names for q in TRACK_QUANTITIES)]
    return [c for c in need if c not in df.columns]


def vehicles(df: pd.DataFrame, relays: list[str], sources: list[str]) -> dict[str, str]:
    """The vehicles of the log that flew (a position at some step; a spare that never launched has none): name -> role
    (``relay`` or ``source``)."""
    def flew(n: str) -> bool:
        return not missing_columns(df, [n]) and bool(flown(df, n).any())
    out = {n: "relay" for n in relays if flew(n)}
    return out | {n: "source" for n in sources if flew(n)}


def flown(df: pd.DataFrame, name: str) -> np.ndarray:
    """The log's rows where a vehicle flew (its position and attitude finite; lost, a spare waiting: NaN)."""
    p = df[[f"{name}.p_{a}" for a in "xyz"]].to_numpy(float)
    eta = df[[f"{name}.{a}" for a in ("phi", "theta", "psi")]].to_numpy(float)
    return np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(eta), axis=1)


def track(df: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A vehicle's flown steps (``flown``): times (s), positions ``(n, 3)`` ENU (m) and ZYX angles ``(n, 3)`` (rad)."""
    rows = df[flown(df, name)]
    return (rows["t"].to_numpy(float), rows[[f"{name}.p_{a}" for a in "xyz"]].to_numpy(float),
            rows[[f"{name}.{a}" for a in ("phi", "theta", "psi")]].to_numpy(float))


def write_csv(df: pd.DataFrame, name: str, frame: GeoFrame | None, path: Path) -> Path:
    t, p, eta = track(df, name)
    cols = {"t_s": t, "east_m": p[:, 0], "north_m": p[:, 1], "up_m": p[:, 2],
            "north_ned_m": p[:, 1], "east_ned_m": p[:, 0], "down_m": -p[:, 2]}
    if frame is not None:
        geo = frame.to_geodetic(p)
        cols |= {"lat_deg": geo[:, 0], "lon_deg": geo[:, 1], "alt_m": geo[:, 2]}
    cols |= {"roll_rad": eta[:, 0], "pitch_rad": eta[:, 1], "yaw_rad": eta[:, 2]}
    pd.DataFrame(cols).to_csv(path, index=False, float_format="%.12g")  # lat/lon: 1e-10 deg, 0.01 mm
    return path


def _douglas_peucker(p: np.ndarray, tol: float) -> list[int]:
    """The indices of ``p`` ``(n, 3)`` kept so that every point lies within ``tol`` of the kept polyline (iterative)."""
    keep = {0, len(p) - 1}
    stack = [(0, len(p) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = p[i], p[j]
        ab = b - a
        L2 = float(ab @ ab)
        seg = p[i + 1:j]
        s = np.clip(((seg - a) @ ab) / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(seg))
        d = np.linalg.norm(seg - (a + s[:, None] * ab), axis=1)
        k = int(np.argmax(d))
        if d[k] > tol:
            m = i + 1 + k
            keep.add(m)
            stack += [(i, m), (m, j)]
    return sorted(keep)


def plan_items(t: np.ndarray, p: np.ndarray, frame: GeoFrame, tol: float = PLAN_TOLERANCE_M) -> list[dict]:
    """The .plan's mission items for a path flown at times ``t`` (s) through ``p`` ``(n, 3)`` ENU (m) (the module)."""
    geo = frame.to_geodetic(p)
    home_alt = frame.origin[2]
    idx = _douglas_peucker(p, tol)
    items: list[dict] = []

    def item(command: int, params: list, frame_id: int = 3) -> None:
        items.append({"type": "SimpleItem", "command": command, "frame": frame_id, "params": params,
                      "autoContinue": True, "doJumpId": len(items) + 1})

    def position(k: int) -> list[float]:
        return [float(geo[k, 0]), float(geo[k, 1]), float(geo[k, 2] - home_alt)]

    item(NAV_TAKEOFF, [0.0, 0.0, 0.0, None, *position(idx[0])])
    item(NAV_WAYPOINT, [0.0, 0.0, 0.0, None, *position(idx[0])])  # where a hover at the start holds
    last = idx[0]
    for b in idx[1:]:
        dist, dt = float(np.linalg.norm(p[b] - p[last])), float(t[b] - t[last])
        if dt <= 0:
            continue
        if dist <= tol:  # a hover: the last waypoint holds that long
            items[-1]["params"][0] = float(items[-1]["params"][0]) + dt
            last = b
            continue
        item(DO_CHANGE_SPEED, [1.0, dist / dt, -1.0, 0.0, 0.0, 0.0, 0.0], frame_id=2)
        item(NAV_WAYPOINT, [0.0, 0.0, 0.0, None, *position(b)])
        last = b
    return items


def write_plan(df: pd.DataFrame, name: str, frame: GeoFrame, path: Path) -> Path:
    t, p, _ = track(df, name)
    if len(t) < 2:
        raise ValueError(f"export: {name} flew {len(t)} step(s); a .plan needs a path of two at least")
    items = plan_items(t, p, frame)
    doc = {"fileType": "Plan", "version": 1, "groundStation": "aerorelay",
           "geoFence": {"circles": [], "polygons": [], "version": 2}, "rallyPoints": {"points": [], "version": 2},
           "mission": {"version": 2, "firmwareType": 12, "vehicleType": 2, "cruiseSpeed": 5.0,
                       "hoverSpeed": 5.0,
                       "plannedHomePosition": [float(v) for v in frame.origin], "items": items}}
    path.write_text(json.dumps(doc, indent=2) + "\n")
    return path


Outline = tuple[str, tuple, float, float]  # an obstacle's name, footprint corners (x, y m), bottom and top (m)


def _ring(frame: GeoFrame, corners, z: float) -> np.ndarray:
    """A closed ring of footprint corners at height ``z`` (local m) as (lat, lon, alt) rows."""
    c = np.asarray(corners, float)
    return frame.to_geodetic(np.column_stack([np.vstack([c, c[:1]]), np.full(len(c) + 1, z)]))


def write_geojson(df: pd.DataFrame, who: dict[str, str], frame: GeoFrame, path: Path,
                  outlines: Sequence[Outline] = ()) -> Path:
    """Every vehicle's track as a LineString and every obstacle (``outlines``) as its footprint's Polygon at the ground
    with its bottom and top (m above the frame's origin) in its properties, as GIS tools extrude buildings."""
    features = []
    for name, corners, z_min, z_max in outlines:
        ring = _ring(frame, corners, z_min)
        features.append({"type": "Feature", "properties": {"name": name, "role": "obstacle", "z_min_m": float(z_min),
                                                           "z_max_m": float(z_max), "height_m": float(z_max - z_min)},
                         "geometry": {"type": "Polygon", "coordinates": [[[round(float(lon), 9), round(float(lat), 9)]
                                                                           for lat, lon, _ in ring]]}})
    for name, role in who.items():
        t, p, _ = track(df, name)
        geo = frame.to_geodetic(p)
        features.append({"type": "Feature", "properties": {"name": name, "role": role, "t_start_s": float(t[0]),
                                                           "t_end_s": float(t[-1]), "points": len(t)},
                         "geometry": {"type": "LineString",
                                      "coordinates": [[round(float(lon), 9), round(float(lat), 9), round(float(alt), 4)]
                                                      for lat, lon, alt in geo]}})
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}) + "\n")
    return path


def write_kml(df: pd.DataFrame, who: dict[str, str], frame: GeoFrame, path: Path, start_utc: str,
              outlines: Sequence[Outline] = ()) -> Path:
    """Every vehicle's track (a line and a timed gx:Track) and every obstacle (``outlines``) as its roof's polygon
    extruded to the ground (Google Earth's buildings), altitudes absolute."""
    import datetime

    import simplekml  # KML's writer for Python; imported where it is used

    kml = simplekml.Kml(name=path.stem)
    for name, corners, _, z_max in outlines:
        roof = _ring(frame, corners, z_max)
        poly = kml.newpolygon(name=name, outerboundaryis=[(float(lon), float(lat), float(alt)) for lat, lon, alt in roof])
        poly.extrude = 1
        poly.altitudemode = simplekml.AltitudeMode.absolute
    t0 = datetime.datetime.fromisoformat(start_utc)
    for name, role in who.items():
        t, p, _ = track(df, name)
        geo = frame.to_geodetic(p)
        coords = [(float(lon), float(lat), float(alt)) for lat, lon, alt in geo]
        line = kml.newlinestring(name=f"{name} ({role})", coords=coords)
        line.altitudemode = simplekml.AltitudeMode.absolute
        trk = kml.newgxtrack(name=f"{name} ({role}), timed")
        trk.altitudemode = simplekml.AltitudeMode.absolute
        trk.newwhen([(t0 + datetime.timedelta(seconds=float(s))).strftime("%Y-%m-%dT%H:%M:%S.%fZ") for s in t])
        trk.newgxcoord(coords)
    kml.save(str(path))
    return path


# ---- PX4 ULog (https://docs.px4.io/main/en/dev_log/ulog_file_format.html) ----

ULOG_MAGIC = b"ULog\x01\x12\x35"
ULOG_TOPICS: dict[str, list[tuple[str, str]]] = {  # PX4's topic names and field names; timestamp first
    "vehicle_local_position": [("uint64_t", "timestamp"), ("float", "x"), ("float", "y"), ("float", "z"),
                               ("float", "vx"), ("float", "vy"), ("float", "vz"), ("float", "heading"),
                               ("bool", "xy_valid"), ("bool", "z_valid"), ("bool", "v_xy_valid"), ("bool", "v_z_valid")],
    "vehicle_attitude": [("uint64_t", "timestamp"), ("float[4]", "q")],
    "vehicle_global_position": [("uint64_t", "timestamp"), ("double", "lat"), ("double", "lon"), ("float", "alt")],
    "vehicle_local_position_setpoint": [("uint64_t", "timestamp"), ("float", "x"), ("float", "y"), ("float", "z")],
}
_PACK = {"uint64_t": "Q", "float": "f", "double": "d", "bool": "?", "float[4]": "4f"}


def _ulog_message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _ulog_info(key_type: str, key: str, value: str) -> bytes:
    raw = value.encode()
    name = f"char[{len(raw)}] {key}".encode()
    return _ulog_message(b"I", struct.pack("<B", len(name)) + name + raw)


def write_ulog(df: pd.DataFrame, name: str, frame: GeoFrame | None, path: Path, version: str) -> Path:
    """Relay ``name``'s flight as a PX4 ULog (the module: topics, fields, frames)."""
    t, p, eta = track(df, name)
    if len(t) == 0:
        raise ValueError(f"export: {name} flew no step; nothing to log")
    us = np.round(t * 1e6).astype(np.int64)
    rows = df[flown(df, name)]
    v = rows[[f"{name}.v_{a}" for a in "xyz"]].to_numpy(float)
    ref = rows[[f"{name}.pd_{a}" for a in "xyz"]].to_numpy(float) if f"{name}.pd_x" in df.columns else None
    topics = {k: f for k, f in ULOG_TOPICS.items() if frame is not None or k != "vehicle_global_position"}
    if ref is None:
        topics.pop("vehicle_local_position_setpoint")
    out = bytearray(ULOG_MAGIC + bytes([1]) + struct.pack("<Q", int(us[0])))
    out += _ulog_message(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))  # flag bits: no compat/incompat flags
    for topic, fields in topics.items():
        out += _ulog_message(b"F", (topic + ":" + "".join(f"{ty} {fi};" for ty, fi in fields)).encode())
    for key, value in (("sys_name", "aerorelay"), ("ver_hw", "AERORELAY_SIM"), ("ver_sw", version)):
        out += _ulog_info("char", key, value)
    ids = {topic: k for k, topic in enumerate(topics)}
    for topic, k in ids.items():
        out += _ulog_message(b"A", struct.pack("<BH", 0, k) + topic.encode())
    geo = frame.to_geodetic(p) if frame is not None else None
    formats = {topic: "<H" + "".join(_PACK[ty] for ty, _ in fields) for topic, fields in topics.items()}
    for i in range(len(t)):
        R_ned = rotation_enu_flu_to_ned_frd(rotation_zyx(eta[i]))
        q = quaternion_wxyz(R_ned)
        heading = math.atan2(R_ned[1, 0], R_ned[0, 0])
        ned, vned = (p[i, 1], p[i, 0], -p[i, 2]), (v[i, 1], v[i, 0], -v[i, 2])
        rows = {"vehicle_local_position": (*ned, *vned, heading, True, True, True, True),
                "vehicle_attitude": tuple(float(c) for c in q)}
        if geo is not None:
            rows["vehicle_global_position"] = (float(geo[i, 0]), float(geo[i, 1]), float(geo[i, 2]))
        if ref is not None:
            rows["vehicle_local_position_setpoint"] = (ref[i, 1], ref[i, 0], -ref[i, 2])
        for topic, values in rows.items():
            out += _ulog_message(b"D", struct.pack(formats[topic], ids[topic], int(us[i]), *values))
    path.write_bytes(bytes(out))
    return path
