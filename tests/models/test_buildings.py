"""``[buildings]`` (issue 63, item 2): a GeoJSON footprint file at lat/lon becomes prism obstacles at load. The
footprints' corners land where pyproj's geocentric transform and the ENU formula put them (``tests.geodesy``, not the
program's pipeline); a footprint that is not convex is tiled exactly by convex pieces (property-tested); heights come
from the height, the storeys or the default; every bad file is named with its feature; a relay flies past an L-shaped
building from such a file without entering it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon
from shapely.ops import unary_union

import aerorelay as ar
from aerorelay.config import ScenarioError
from aerorelay.models import buildings
from aerorelay.models.buildings import convex_pieces
from aerorelay.models.geo import GeoFrame
from aerorelay.models.obstacles import Prism
from tests.geodesy import enu_by_hand

ORIGIN = (46.05, 14.50, 300.0)
NOMINAL = "scenarios/nominal_tilted.toml"


def _ring(local_xy) -> list[list[float]]:
    """A closed GeoJSON ring (lon, lat) of local corners (m, ENU at ORIGIN, on the origin's height)."""
    ll = GeoFrame(ORIGIN).to_geodetic(np.column_stack([np.asarray(local_xy, float), np.zeros(len(local_xy))]))
    ring = [[float(lon), float(lat)] for lat, lon, _ in ll]
    return ring + [ring[0]]


def _feature(local_xy, **props) -> dict:
    return {"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": [_ring(local_xy)]}}


def _load(tmp_path: Path, features, **table) -> ar.config.Scenario:
    (tmp_path / "site.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return ar.load_scenario(NOMINAL, set={"geo.origin": list(ORIGIN), "buildings.geojson": str(tmp_path / "site.geojson"),
                                         **{f"buildings.{k}": v for k, v in table.items()}})


def test_a_rectangle_at_lat_lon_is_a_prism_where_the_formula_puts_its_corners(tmp_path):
    corners = [(2.0, -3.0), (6.0, -3.0), (6.0, -1.0), (2.0, -1.0)]
    feature = _feature(corners, height=7.5)
    sc = _load(tmp_path, [feature])
    (o,) = [o for o in sc.obstacle_list if o.name.startswith("building")]
    assert o.kind == "prism" and o.z_min_m == sc.world.ground_z_m and o.z_max_m == pytest.approx(7.5)
    lonlat = np.array(feature["geometry"]["coordinates"][0][:-1])
    by_hand = enu_by_hand(ORIGIN, lonlat[:, 1], lonlat[:, 0], np.full(len(lonlat), ORIGIN[2]))[:, :2]
    got = np.array(o.footprint_m)
    # the same corners, maybe starting elsewhere around the outline: each within 1 mm of one written by hand
    assert np.max(np.min(np.linalg.norm(got[:, None] - by_hand[None], axis=-1), axis=1)) < 1e-3
    assert sc.buildings is None and sc.buildings_resolved == {"file": str(tmp_path / "site.geojson"), "footprints": 1,
                                                              "kept": 1, "left_out": 0, "prisms": 1}


def test_heights_from_the_height_the_storeys_or_the_default(tmp_path):
    square = [(0.0, -4.0), (1.0, -4.0), (1.0, -3.0), (0.0, -3.0)]
    shifted = [[(x + 2 * k, y) for x, y in square] for k in range(4)]
    sc = _load(tmp_path, [_feature(shifted[0], height="12 m"), _feature(shifted[1], **{"building:levels": 4}),
                          _feature(shifted[2], levels=2), _feature(shifted[3])], default_height_m=5.0,
               levels_property="levels", level_height_m=2.5)
    tops = {o.name: o.z_max_m for o in sc.obstacle_list}
    assert tops == {"building0": 12.0, "building1": 5.0, "building2": 5.0, "building3": 5.0}
    with pytest.raises(ScenarioError, match=r"features\[0\].*no height.*default_height_m"):
        _load(tmp_path, [_feature(square)])


def test_footprints_out_of_reach_are_left_out(tmp_path):
    near, far = [(0.0, -4.0), (1.0, -4.0), (1.0, -3.0)], [(500.0, 0.0), (510.0, 0.0), (510.0, 10.0)]
    sc = _load(tmp_path, [_feature(near, height=3), _feature(far, height=3)])
    assert [o.name for o in sc.obstacle_list] == ["building0"]
    assert sc.buildings_resolved["left_out"] == 1
    sc = _load(tmp_path, [_feature(near, height=3), _feature(far, height=3)], reach_m=600.0)
    assert [o.name for o in sc.obstacle_list] == ["building0", "building1"]


@pytest.mark.parametrize("outline, pieces", [
    ([(0, 0), (10, 0), (10, 4), (4, 4), (4, 10), (0, 10)], 2),  # an L
    ([(0, 0), (12, 0), (12, 10), (8, 10), (8, 4), (4, 4), (4, 10), (0, 10)], 3),  # a U
])
def test_an_l_and_a_u_are_their_fewest_convex_pieces(outline, pieces):
    got = convex_pieces(outline)
    assert len(got) == pieces
    assert unary_union([Polygon(p) for p in got]).symmetric_difference(Polygon(outline)).area < 1e-9


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 2 * math.pi), st.floats(2.0, 20.0)), min_size=3, max_size=24, unique_by=lambda a: round(a[0], 2)))
@example([(0.0, 19.9765625), (1.0, 2.0), (2.0, 4.0), (2 * math.pi, 19.984375)])  # corners 8 mm apart: a sliver lost
@example([(0.0, 19.9765625), (1.0, 2.0), (2.0, 3.0), (2 * math.pi, 19.984375)])  # ... or a piece of two corners
def test_convex_pieces_tile_any_simple_footprint(polar):
    """Star-shaped outlines around the origin (simple by construction): the pieces are convex prisms (Prism's own
    check), do not overlap and cover the outline."""
    polar = sorted(polar)
    outline = [(r * math.cos(a), r * math.sin(a)) for a, r in polar]
    poly = Polygon(outline)
    if not poly.is_valid or poly.area < 1.0:
        return
    got = convex_pieces(outline)
    shapes = [Polygon(p) for p in got]
    for p in got:
        Prism(tuple(p), 0.0, 1.0)  # convex, no repeated corner, not crossing itself
    assert abs(sum(s.area for s in shapes) - poly.area) < 1e-6 * poly.area  # no overlap ...
    assert unary_union(shapes).symmetric_difference(poly).area < 1e-6 * poly.area  # ... and nothing missing
    assert len(got) <= len(outline) - 2  # no more than its triangles


@pytest.mark.parametrize("mutate, needle", [
    (lambda d: {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"height": 3},
                                                           "geometry": {"type": "Point", "coordinates": [14.5, 46.05]}}]},
     r"features\[0\]: a Point is not a footprint"),
    (lambda d: {"type": "FeatureCollection", "features": [_feature([(0, 0), (4, 4), (4, 0), (0, 4)], height=3)]},
     r"features\[0\]: not a simple polygon \(Self-intersection"),
    (lambda d: {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"height": 3, "name": "north"},
                "geometry": {"type": "Polygon", "coordinates": [[[14.5, 91.0], [14.6, 46.0], [14.5, 46.0], [14.5, 91.0]]]}}]},
     r"features\[0\] \(north\): corner \(lon 14.5, lat 91\) is off the earth"),
    (lambda d: {"type": "FeatureCollection", "features": [_feature([(0, 0), (1e-3, 0), (0, 1e-3)], height=3)]},
     r"an empty footprint"),
    (lambda d: {"type": "FeatureCollection", "features": [_feature([(0, -4), (1, -4), (1, -3)], height=-2)]},
     r"'height' = -2 must be a positive number"),
    (lambda d: [1, 2, 3], r"a GeoJSON FeatureCollection"),
])
def test_bad_footprint_files_are_named(tmp_path, mutate, needle):
    (tmp_path / "site.geojson").write_text(json.dumps(mutate(None)))
    with pytest.raises(ScenarioError, match=needle) as exc:
        ar.load_scenario(NOMINAL, set={"geo.origin": list(ORIGIN), "buildings.geojson": str(tmp_path / "site.geojson")})
    assert "buildings.geojson" in str(exc.value) and "site.geojson" in str(exc.value)


def test_the_file_itself_is_named_when_missing_not_json_or_too_large(tmp_path, monkeypatch):
    where = {"geo.origin": list(ORIGIN), "buildings.geojson": str(tmp_path / "none.geojson")}
    with pytest.raises(ScenarioError, match="none.geojson: no such footprint file"):
        ar.load_scenario(NOMINAL, set=where)
    (tmp_path / "none.geojson").write_text("{not json")
    with pytest.raises(ScenarioError, match="none.geojson: not GeoJSON"):
        ar.load_scenario(NOMINAL, set=where)
    monkeypatch.setattr(buildings, "MAX_FEATURES", 2)
    (tmp_path / "none.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [{}] * 3}))
    with pytest.raises(ScenarioError, match="3 features, more than the 2"):
        ar.load_scenario(NOMINAL, set=where)
    with pytest.raises(ScenarioError, match=r"needs \[geo\] origin"):
        ar.load_scenario(NOMINAL, set={"buildings.geojson": str(tmp_path / "none.geojson")})


def test_more_prisms_than_the_nmpc_keeps_out_of_are_refused(tmp_path):
    squares = [[(x, y), (x + 0.5, y), (x + 0.5, y + 0.5), (x, y + 0.5)] for x in range(-6, 7) for y in (-5, 0, 5, 10, 15, 20)]
    with pytest.raises(ScenarioError, match=r"78 convex prisms.*more than the 64"):
        _load(tmp_path, [_feature(s, height=2) for s in squares])


def test_a_relative_footprint_file_is_read_beside_the_scenario(tmp_path):
    (tmp_path / "site.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        _feature([(0.0, -4.0), (1.0, -4.0), (1.0, -3.0)], height=3)]}))
    (tmp_path / "s.toml").write_text(f'name = "site"\n[geo]\norigin = {list(ORIGIN)}\n[buildings]\ngeojson = "site.geojson"\n')
    sc = ar.load_scenario(tmp_path / "s.toml")
    assert [o.name for o in sc.obstacle_list] == ["building0"]


def _l_block() -> list[tuple[float, float]]:
    """An L across the relay's way in the nominal mission: the turned wall of test_prism (which both planners cross
    by 0.15 m without it) with an arm on its far side."""
    a = math.radians(50.0)
    c, d, n = np.array([-5.2, 4.65]), np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    pts = [c - d + 0.15 * n, c + d + 0.15 * n, c + d - 1.35 * n, c + 0.7 * d - 1.35 * n, c + 0.7 * d - 0.15 * n,
           c - d - 0.15 * n]
    return [(float(p[0]), float(p[1])) for p in pts]


def test_a_relay_flies_past_an_l_shaped_building_from_a_footprint_file(tmp_path):
    sc = _load(tmp_path, [_feature(_l_block(), height=3.0, name="L")], margin_m=0.4)
    assert sorted(o.name for o in sc.obstacle_list) == ["building0_0", "building0_1"]
    r = ar.simulate(sc.with_updates({"sim.duration_s": 8.0}))
    m = r.metrics
    assert not m["unsafe"] and m["safety_violations"] == 0
    p = r.timeseries[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    assert np.all(p[:, 2] < 3.0)  # beside the building, not over it: the outline alone decides
    outline = Polygon(_l_block())
    inside = np.array([outline.contains(Point(q[:2])) for q in p])
    clearance = np.array([outline.exterior.distance(Point(q[:2])) for q in p])
    assert not inside.any() and clearance.min() > 0.1  # outside the bare L (shapely's), most of the margin kept
    assert clearance.min() == pytest.approx(m["obstacle_clearance_min_m"], abs=1e-6)  # the verdict measures the same
