"""Geographic mission files (issue 48, item 1): WGS84 to the scenario's local east-north-up frame
with pyproj, checked against the closed-form geodetic -> ECEF -> ENU written here; a QGroundControl
.plan and a GPX track written in the test, their local waypoints and times computed by hand; bad files
named by item or point and field; a plan mission flies, its file copied into the run folder, which
flies again as it flew."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.models.geo import GeoFrame
from aerorelay.models.mission import GpxPath, PlanPath

A, F = 6378137.0, 1 / 298.257223563  # WGS84
E2 = F * (2 - F)
HOME = (47.397742, 8.545594, 488.0)  # PX4's SITL home (Zurich)
ROOT = Path(__file__).resolve().parents[2]


def _ecef(lat, lon, h):
    phi, lam = math.radians(lat), math.radians(lon)
    n = A / math.sqrt(1 - E2 * math.sin(phi) ** 2)
    return np.array([(n + h) * math.cos(phi) * math.cos(lam), (n + h) * math.cos(phi) * math.sin(lam),
                     (n * (1 - E2) + h) * math.sin(phi)])


def _enu(origin, lat, lon, h):
    """The textbook ENU of a geodetic point at a geodetic origin (rotation of the ECEF difference)."""
    phi, lam = math.radians(origin[0]), math.radians(origin[1])
    r = np.array([[-math.sin(lam), math.cos(lam), 0.0],
                  [-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)],
                  [math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)]])
    return r @ (_ecef(lat, lon, h) - _ecef(*origin))


@given(lat0=st.floats(-80, 80), lon0=st.floats(-179, 179), h0=st.floats(-100, 3000),
       dn=st.floats(-0.02, 0.02), de=st.floats(-0.02, 0.02), dh=st.floats(-200, 500))
def test_local_coordinates_are_the_closed_form_enu_and_round_trip_at_a_millimetre(lat0, lon0, h0, dn, de, dh):
    frame = GeoFrame((lat0, lon0, h0))
    point = (lat0 + dn, lon0 + de, h0 + dh)
    enu = frame.to_local(*point)[0]
    np.testing.assert_allclose(enu, _enu((lat0, lon0, h0), *point), atol=1e-3)
    back = frame.to_geodetic(enu)[0]
    np.testing.assert_allclose(frame.to_local(*back)[0], enu, atol=1e-3)
    assert abs(back[2] - point[2]) < 1e-3


def _item(command, lat=0.0, lon=0.0, alt=0.0, frame=3, p1=0.0, p2=0.0):
    return {"type": "SimpleItem", "command": command, "frame": frame, "autoContinue": True,
            "params": [p1, p2, 0, None, lat, lon, alt]}


def _plan(tmp_path, items, hover_speed=5.0) -> Path:
    f = tmp_path / "mission.plan"
    f.write_text(json.dumps({"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
                             "mission": {"version": 2, "firmwareType": 12, "vehicleType": 2, "cruiseSpeed": 15,
                                         "hoverSpeed": hover_speed, "plannedHomePosition": list(HOME), "items": items}}))
    return f


def _north(m):  # degrees of latitude for m metres north at HOME (meridian radius)
    phi = math.radians(HOME[0])
    return math.degrees(m / (A * (1 - E2) / (1 - E2 * math.sin(phi) ** 2) ** 1.5))


def _east(m):
    phi = math.radians(HOME[0])
    return math.degrees(m / (A / math.sqrt(1 - E2 * math.sin(phi) ** 2) * math.cos(phi)))


def test_a_plans_waypoints_speeds_and_holds_by_hand(tmp_path):
    """Takeoff to 10 m over home, 20 m north (hold 4 s), speed 2 m/s, 30 m east: waypoints at the
    closed-form ENU of each item, times from the distances over the speeds plus the hold."""
    items = [_item(22, HOME[0], HOME[1], 10.0), _item(16, HOME[0] + _north(20), HOME[1], 10.0, p1=4.0),
             _item(178, p2=2.0), _item(16, HOME[0] + _north(20), HOME[1] + _east(30), 10.0),
             _item(2000)]  # a camera command: no position
    path = PlanPath(_plan(tmp_path, items))
    want = [_enu(HOME, HOME[0], HOME[1], HOME[2] + 10.0), _enu(HOME, HOME[0] + _north(20), HOME[1], HOME[2] + 10.0),
            _enu(HOME, HOME[0] + _north(20), HOME[1] + _east(30), HOME[2] + 10.0)]
    np.testing.assert_allclose(path.p, [want[0], want[1], want[1], want[2]], atol=1e-3)
    d1, d2 = np.linalg.norm(want[1] - want[0]), np.linalg.norm(want[2] - want[1])
    assert d1 == pytest.approx(20.0, abs=0.01) and d2 == pytest.approx(30.0, abs=0.01)
    np.testing.assert_allclose(path.t, [0.0, d1 / 5.0, d1 / 5.0 + 4.0, d1 / 5.0 + 4.0 + d2 / 2.0], atol=1e-9)
    assert path.state(path.t[1] + 2.0).p == pytest.approx(want[1], abs=1e-6)  # holding


@pytest.mark.parametrize("change,named", [
    (lambda items: items[1].update(frame=10), r"mission.items\[1\].frame: 10; read are 0/5"),
    (lambda items: items[1].update(params=[0, 0, 0]), r"mission.items\[1\].params: need the seven"),
    (lambda items: items[1]["params"].__setitem__(4, "north"), r"mission.items\[1\].params\[4\] \(latitude\): not a finite number"),
    (lambda items: items.__setitem__(0, {"type": "ComplexItem"}), r"mission.items\[0\]: type 'ComplexItem'"),
])
def test_bad_plans_are_named_by_item_and_field(tmp_path, change, named):
    items = [_item(22, HOME[0], HOME[1], 10.0), _item(16, HOME[0] + _north(20), HOME[1], 10.0)]
    change(items)
    f = _plan(tmp_path, items)
    with pytest.raises(ValueError, match=named):
        PlanPath(f)
    with pytest.raises(ScenarioError, match=r"mission: trajectory_plan: .*mission.plan: " + named):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"mission.trajectory_plan": str(f)})


def _gpx(tmp_path, points, times=True) -> Path:
    pts = "".join(f'<trkpt lat="{lat!r}" lon="{lon!r}"><ele>{ele}</ele>'
                  + (f"<time>2026-12-04T10:00:{int(t):02d}Z</time>" if times else "") + "</trkpt>"
                  for t, lat, lon, ele in points)
    f = tmp_path / "track.gpx"
    f.write_text(f'<?xml version="1.0"?><gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">'
                 f"<trk><trkseg>{pts}</trkseg></trk></gpx>")
    return f


def test_a_gpx_track_in_the_local_frame_of_its_first_point(tmp_path):
    pts = [(k * 2.0, HOME[0] + _north(3.0 * k), HOME[1], HOME[2] + 0.5 * k) for k in range(8)]
    path = GpxPath(_gpx(tmp_path, pts))
    assert path.duration == pytest.approx(14.0)
    for t, lat, lon, ele in pts:
        np.testing.assert_allclose(path.state(t).p, _enu(pts[0][1:], lat, lon, ele), atol=1e-3)
    np.testing.assert_allclose(path.state(7.0).v, [0.0, 1.5, 0.25], atol=0.02)  # 3 m north and 0.5 m up every 2 s
    with pytest.raises(ValueError, match=r"track 0 segment 0 point 0: no <time>"):
        GpxPath(_gpx(tmp_path, pts, times=False))


def test_a_plan_mission_flies_and_its_run_folder_flies_it_again(tmp_path):
    """The nominal relay with a plan 2-4 m from its start, [geo] origin at home: the mission's local
    start is the plan's first item, the run folder holds mission.plan and re-flies the same run."""
    items = [_item(16, HOME[0] + _north(5.79), HOME[1] + _east(-3.04), 1.72),
             _item(16, HOME[0] + _north(5.0), HOME[1] + _east(-2.0), 4.0)]
    f = _plan(tmp_path, items, hover_speed=1.0)
    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                          set={"mission.trajectory_plan": str(f), "geo.origin": list(HOME), "sim.duration_s": 1.0})
    np.testing.assert_allclose(sc.mission.start, _enu(HOME, HOME[0] + _north(5.79), HOME[1] + _east(-3.04), HOME[2] + 1.72),
                               atol=1e-3)
    r = ar.simulate(sc)
    r.save(tmp_path / "run")
    assert (tmp_path / "run" / "mission.plan").read_bytes() == f.read_bytes()
    again = ar.load_scenario(tmp_path / "run" / "scenario.toml")
    assert Path(again.mission.trajectory_plan).name == "mission.plan"
    assert np.array_equal(ar.simulate(again).timeseries["capacity"].to_numpy(), r.timeseries["capacity"].to_numpy())


@pytest.mark.parametrize("items,hover_speed,said", [
    ([_item(16, HOME[0], HOME[1], 10.0), _item(16, HOME[0], HOME[1], 10.0)], 5.0, "a mission of 0 s"),
    ([_item(22, HOME[0], HOME[1], 10.0), _item(16, HOME[0] + _north(20), HOME[1], 10.0)], 1e9, "faster than any multirotor"),
], ids=["one-place", "1e9-m-s"])
def test_a_degenerate_plan_is_named_not_flown(tmp_path, items, hover_speed, said):
    """Issue 61: a .plan whose items are all at one place, or flown at 1e9 m/s, flew a 0 s mission, exit 0."""
    from aerorelay.config import ScenarioError

    f = _plan(tmp_path, items, hover_speed)
    with pytest.raises(ScenarioError, match=rf"mission[.:] ?trajectory_plan: .*{said}"):
        ar.load_scenario("scenarios/nominal_tilted.toml", set={"mission.trajectory_plan": str(f), "geo.origin": list(HOME)})


def test_a_gpx_file_is_read_in_the_encoding_its_declaration_names_and_a_point_off_the_earth_is_named(tmp_path):
    """Issue 61: a valid GPX file in ISO-8859-1 (its XML declaration says so) was refused as non-UTF-8; latitude 95
    said "array must not contain infs or NaNs" (no file, no point)."""
    pts = [(k * 2.0, HOME[0] + _north(3.0 * k), HOME[1], HOME[2] + 0.5 * k) for k in range(8)]
    utf8 = _gpx(tmp_path, pts).read_text()
    latin = tmp_path / "latin.gpx"
    latin.write_bytes(utf8.replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="ISO-8859-1"?>')
                      .replace('creator="test"', 'creator="caf\u00e9"').encode("latin-1"))
    assert GpxPath(latin).duration == pytest.approx(14.0)
    off = [(t, 95.0 if k == 3 else lat, lon, ele) for k, (t, lat, lon, ele) in enumerate(pts)]
    with pytest.raises(ValueError, match=r"track\.gpx: track 0 segment 0 point 3: lat 95, lon .* is not on the earth"):
        GpxPath(_gpx(tmp_path, off))


def test_a_plan_point_from_another_place_is_named_by_its_distance_not_as_below_ground(tmp_path):
    """A waypoint 1 degree (111 km) north of the others was 'MRAV-2's path goes below ground': the local frame's
    ground falls away with the earth's curvature (970 m there). It is named by how far it is from the workspace."""
    items = [_item(16, HOME[0] + _north(5.79), HOME[1] + _east(-3.04), 1.72),
             _item(16, HOME[0] + 1.0, HOME[1] + _east(-2.0), 4.0)]
    f = _plan(tmp_path, items, hover_speed=1.0)
    with pytest.raises(ScenarioError, match=r"mission\.trajectory_plan sample \d+: MRAV-2 at .* is 1\.11\de\+05 m from "
                                            r"controller\.workspace; .*world\.mission_max_distance_m = 1000 m"):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"mission.trajectory_plan": str(f), "geo.origin": list(HOME)})
