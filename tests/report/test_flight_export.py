"""``aerorelay export RUN --format csv|plan|geojson|kml|ulog`` (issue 63, item 4): every format read back by another
reader (pandas, aerorelay's own .plan reader, json, an XML parser, pyulog), its geographic coordinates checked against
an ECEF-to-ENU rotation written out here from the WGS84 formulas (pyproj's EPSG:4978 for the ECEF point), not
against the exporter's own transform."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest
from pyulog import ULog
from typer.testing import CliRunner

import aerorelay as ar
from aerorelay.cli import app
from aerorelay.models.geo import read_plan
from tests.geodesy import enu_by_hand

HOME = (47.3977, 8.5456, 488.0)  # lat deg, lon deg, alt m (PX4's SITL home)
runner = CliRunner()


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """6 s of the nominal tilted mission (the relay climbs, turns and hovers), its frame at HOME."""
    out = tmp_path_factory.mktemp("export") / "run"
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 6.0, "geo.origin": list(HOME)})
    res = ar.simulate(sc)
    res.save(out, figures=False)
    return out, res.timeseries


def _enu_by_hand(lat, lon, alt) -> np.ndarray:
    return enu_by_hand(HOME, lat, lon, alt)


def _export(out, fmt, *extra):
    r = runner.invoke(app, ["export", str(out), "--format", fmt, *extra])
    assert r.exit_code == 0, r.output
    return r.output


def test_csv_has_every_step_in_enu_ned_and_wgs84(run):
    out, df = run
    _export(out, "csv")
    relay = pd.read_csv(out / "export" / "relay.csv")
    assert (out / "export" / "mrav2.csv").is_file() or len(list((out / "export").glob("*.csv"))) == 2
    assert len(relay) == len(df)
    np.testing.assert_allclose(relay[["east_m", "north_m", "up_m"]].to_numpy(), df[["relay.p_x", "relay.p_y", "relay.p_z"]],
                               atol=1e-6)
    np.testing.assert_allclose(relay[["north_ned_m", "east_ned_m", "down_m"]].to_numpy(),
                               np.column_stack([df["relay.p_y"], df["relay.p_x"], -df["relay.p_z"]]), atol=1e-6)
    enu = _enu_by_hand(relay["lat_deg"], relay["lon_deg"], relay["alt_m"])
    assert np.max(np.abs(enu - df[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy())) < 1e-3  # 1 mm


def test_plan_reads_back_as_the_flown_path_with_its_times(run):
    out, df = run
    _export(out, "plan")
    home, points = read_plan(out / "export" / "relay.plan")
    assert home == HOME
    wp = _enu_by_hand([p.lat for p in points], [p.lon for p in points], [p.alt for p in points])
    flown = df[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    t = df["t"].to_numpy()
    # every waypoint is a flown point, at the time it was flown there
    for (tw, q) in zip([p.t for p in points], wp, strict=True):
        k = int(np.argmin(np.linalg.norm(flown - q, axis=1)))
        assert np.linalg.norm(flown[k] - q) < 1e-3 and abs(t[k] - tw) < 0.05, (tw, t[k])
    # the flown path stays within 0.1 m of the waypoints' polyline
    def dist_to_polyline(x):
        best = np.inf
        for a, b in zip(wp[:-1], wp[1:], strict=True):
            ab = b - a
            s = 0.0 if ab @ ab == 0 else float(np.clip((x - a) @ ab / (ab @ ab), 0.0, 1.0))
            best = min(best, float(np.linalg.norm(x - a - s * ab)))
        return best
    assert max(dist_to_polyline(x) for x in flown) < 0.1
    assert len(points) < len(flown) / 4  # a mission, not a log


def test_geojson_and_kml_hold_every_vehicle_s_track(run):
    out, df = run
    _export(out, "geojson")
    _export(out, "kml")
    doc = json.loads((out / "export" / "tracks.geojson").read_text())
    feats = {f["properties"]["name"]: f for f in doc["features"]}
    assert doc["type"] == "FeatureCollection" and {f["properties"]["role"] for f in feats.values()} == {"relay", "source"}
    coords = np.array(feats["relay"]["geometry"]["coordinates"])  # [lon, lat, alt] (RFC 7946)
    assert coords.shape == (len(df), 3)
    enu = _enu_by_hand(coords[:, 1], coords[:, 0], coords[:, 2])
    assert np.max(np.abs(enu - df[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy())) < 1e-3
    ns = {"k": "http://www.opengis.net/kml/2.2", "gx": "http://www.google.com/kml/ext/2.2"}
    root = ET.parse(out / "export" / "tracks.kml").getroot()
    lines = root.findall(".//k:LineString/k:coordinates", ns)
    tracks = root.findall(".//gx:Track", ns)
    assert len(lines) == len(tracks) == len(feats)
    first = [tuple(float(v) for v in c.split(",")) for c in lines[0].text.split()]
    assert len(first) == len(df) and len(tracks[0].findall("k:when", ns)) == len(df)


def test_ulog_is_read_by_pyulog_with_px4_topics_in_ned(run):
    out, df = run
    _export(out, "ulog")
    log = ULog(str(out / "export" / "relay.ulg"))
    data = {d.name: d.data for d in log.data_list}
    assert set(data) == {"vehicle_local_position", "vehicle_attitude", "vehicle_global_position",
                         "vehicle_local_position_setpoint"}
    lp = data["vehicle_local_position"]
    assert len(lp["timestamp"]) == len(df) and np.all(np.diff(lp["timestamp"]) > 0)
    np.testing.assert_allclose(lp["timestamp"] * 1e-6, df["t"], atol=1e-6)
    np.testing.assert_allclose(np.column_stack([lp["x"], lp["y"], lp["z"]]),
                               np.column_stack([df["relay.p_y"], df["relay.p_x"], -df["relay.p_z"]]), atol=1e-4)
    q = np.column_stack([data["vehicle_attitude"][f"q[{i}]"] for i in range(4)])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
    # PX4's heading (NED) from the quaternion: pi/2 minus the logged ENU yaw
    yaw_ned = np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]), 1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2))
    diff = np.angle(np.exp(1j * (yaw_ned - (np.pi / 2 - df["relay.psi"].to_numpy()))))
    assert np.max(np.abs(diff)) < 1e-5
    gp = data["vehicle_global_position"]
    enu = _enu_by_hand(gp["lat"], gp["lon"], gp["alt"])
    assert np.max(np.abs(enu[:, :2] - df[["relay.p_x", "relay.p_y"]].to_numpy())) < 1e-3
    assert log.msg_info_dict["sys_name"] == "aerorelay"


def test_what_cannot_be_exported_is_refused_by_name(run, tmp_path):
    out, _ = run
    for args, needle in ((["--format", "shp"], "--format: one of mcap"), (["--format", "csv", "--relay", "nobody"], "--relay"),
                         (["--format", "mcap", "--relay", "relay"], "--relay and --origin apply"),
                         (["--format", "plan", "--origin", "91,0,0"], "--origin: lat in [-90, 90]"),
                         (["--format", "plan", "--origin", "1,2"], "three numbers")):
        r = runner.invoke(app, ["export", str(out), *args])
        assert r.exit_code == 2 and needle in r.output, (args, r.output)
    # a run without [geo] origin: the geographic formats need one, csv and ulog go without lat/lon
    plain = tmp_path / "plain"
    ar.simulate(ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 0.3})).save(plain, figures=False)
    r = runner.invoke(app, ["export", str(plain), "--format", "kml"])
    assert r.exit_code == 2 and "[geo] origin" in r.output
    _export(plain, "csv")
    assert "lat_deg" not in pd.read_csv(plain / "export" / "relay.csv").columns
    _export(plain, "plan", "--origin", ",".join(str(v) for v in HOME))
    assert read_plan(plain / "export" / "relay.plan")[0] == HOME


def test_geojson_and_kml_carry_the_obstacles_as_footprints_with_their_heights(tmp_path):
    """A run among a turned prism (a building) and a cylinder: the GeoJSON has each footprint as a Polygon whose
    corners are where the formula puts them, with its top in its properties; the KML has each roof extruded."""
    wall = [[-5.9, 4.1], [-4.6, 5.6], [-4.4, 5.4], [-5.7, 3.9]]
    obstacles = [{"name": "wall", "kind": "prism", "footprint_m": wall, "z_min_m": 0.0, "z_max_m": 3.0, "margin_m": 0.3},
                 {"name": "mast", "kind": "cylinder", "centre_m": [3.0, -3.0], "radius_m": 0.5, "z_min_m": 0.0,
                  "z_max_m": 8.0}]
    out = tmp_path / "run"
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 1.0, "geo.origin": list(HOME),
                                                                "obstacles": obstacles})
    ar.simulate(sc).save(out, figures=False)
    _export(out, "geojson")
    _export(out, "kml")
    feats = {f["properties"]["name"]: f for f in json.loads((out / "export" / "tracks.geojson").read_text())["features"]}
    w = feats["wall"]
    assert w["properties"]["role"] == "obstacle" and w["properties"]["z_max_m"] == 3.0
    ring = np.array(w["geometry"]["coordinates"][0])
    enu = _enu_by_hand(ring[:, 1], ring[:, 0], np.full(len(ring), HOME[2]))
    assert np.allclose(ring[0], ring[-1])  # closed (RFC 7946)
    got = enu[:-1, :2]
    assert np.max(np.min(np.linalg.norm(got[:, None] - np.array(wall)[None], axis=-1), axis=1)) < 1e-3
    mast = np.array(feats["mast"]["geometry"]["coordinates"][0])
    r = np.linalg.norm(_enu_by_hand(mast[:, 1], mast[:, 0], np.full(len(mast), HOME[2]))[:, :2] - [3.0, -3.0], axis=1)
    assert np.all(r >= 0.5 - 1e-3) and len(mast) == 33  # a 32-sided polygon around the circle
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    polys = ET.parse(out / "export" / "tracks.kml").getroot().findall(".//k:Polygon", ns)
    assert len(polys) == 2 and all(p.find("k:extrude", ns).text == "1" for p in polys)
