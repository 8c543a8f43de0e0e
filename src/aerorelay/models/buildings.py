"""Buildings from a GeoJSON file of footprints: each footprint (a lat/lon polygon with a height) in the scenario's
local frame as convex pieces, each one vertical prism (``models.obstacles.Prism``), for ``[buildings]``.

A footprint that is not convex (an L, a U, a courtyard's outline) is cut into convex pieces: the polygon's
constrained Delaunay triangles (GEOS, through shapely), merged greedily while two neighbours' union stays convex
(Hertel-Mehlhorn's rule: at most four times the fewest pieces; an L gives 2, a U 3). Interior rings (courtyards) are
filled: a relay does not fly into a courtyard. Corners closer than ``SIMPLIFY_M`` to the line through their
neighbours are dropped first (surveyed outlines carry many), so a footprint's pieces are few.

Every problem is a ``BuildingsError`` naming the file and the feature: not GeoJSON, a geometry that is not a
polygon, an empty or self-intersecting polygon (GEOS's reason), a coordinate off the earth, a missing or
non-positive height, a file too large (``MAX_FILE_BYTES``, ``MAX_FEATURES``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..filecheck import not_a_file
from .geo import GeoFrame

MAX_FILE_BYTES = 200_000_000  # a district's footprints are a few MB; a country's are refused before reading
MAX_FEATURES = 100_000
MAX_CORNERS = 256  # per footprint after simplification (its convex pieces are found in O(corners^2))
SIMPLIFY_M = 0.05  # corners closer than this to the outline without them are dropped
MIN_AREA_M2 = 0.01


class BuildingsError(ValueError):
    """A footprint file that cannot be read as buildings; the message names the file and the feature."""


@dataclass(frozen=True)
class Footprint:
    """One building: its feature's index and name in the file, its outline (local x, y, m, counter-clockwise, not
    closed) and its height above the ground (m)."""

    index: int
    name: str
    outline: tuple[tuple[float, float], ...]
    height_m: float


def _height(props: dict, where: str, height_property: str, levels_property: str, level_height_m: float,
            default_height_m: float | None) -> float:
    def number(key: str) -> float | None:
        v = props.get(key)
        if v is None:
            return None
        if isinstance(v, str):  # OpenStreetMap writes "12", "12 m", "12.5"
            v = v.strip().removesuffix("m").strip()
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise BuildingsError(f"{where}: property {key!r} = {props.get(key)!r} is not a number") from None
        if not (math.isfinite(x) and x > 0):
            raise BuildingsError(f"{where}: property {key!r} = {props.get(key)!r} must be a positive number")
        return x

    h = number(height_property)
    if h is None and (levels := number(levels_property)) is not None:
        h = levels * level_height_m
    if h is None:
        h = default_height_m
    if h is None:
        raise BuildingsError(f"{where}: no height (property {height_property!r}, or {levels_property!r} x "
                             f"{level_height_m:g} m): give it in the file or set buildings.default_height_m")
    if h > 1000.0:
        raise BuildingsError(f"{where}: height {h:g} m is above 1000 m")
    return h


def _rings(geometry, where: str) -> list[list]:
    """The outer rings of a Polygon or MultiPolygon geometry (GeoJSON coordinates), holes left out."""
    if not isinstance(geometry, dict):
        raise BuildingsError(f"{where}: no geometry")
    kind, coords = geometry.get("type"), geometry.get("coordinates")
    polys: object
    if kind == "Polygon":
        polys = [coords]
    elif kind == "MultiPolygon":
        polys = coords
    else:
        raise BuildingsError(f"{where}: a {kind} is not a footprint (Polygon or MultiPolygon)")
    if not isinstance(polys, list) or not polys:
        raise BuildingsError(f"{where}: an empty {kind}")
    rings = []
    for poly in polys:
        if not isinstance(poly, list) or not poly or not isinstance(poly[0], list):
            raise BuildingsError(f"{where}: an empty polygon")
        rings.append(poly[0])
    return rings


def _to_local(ring: list, frame: GeoFrame, where: str) -> np.ndarray:
    try:
        pts = np.array([[float(c[0]), float(c[1])] for c in ring])
    except (TypeError, ValueError, IndexError):
        raise BuildingsError(f"{where}: corners are [lon_deg, lat_deg] (GeoJSON's order), got {ring[:3]!r}...") from None
    if len(pts) < 4:  # GeoJSON rings are closed: 3 corners and the first again
        raise BuildingsError(f"{where}: a polygon needs 3 corners or more, got {max(len(pts) - 1, 0)}")
    bad = ~((np.abs(pts[:, 1]) <= 90.0) & (np.abs(pts[:, 0]) <= 180.0) & np.all(np.isfinite(pts), axis=1))
    if bad.any():
        lon, lat = pts[np.argmax(bad)]
        raise BuildingsError(f"{where}: corner (lon {lon:g}, lat {lat:g}) is off the earth: longitude in [-180, 180] deg, "
                             "latitude in [-90, 90] deg (GeoJSON writes longitude first)")
    return frame.to_local(pts[:, 1], pts[:, 0], np.full(len(pts), frame.origin[2]))[:, :2]


def read_footprints(path: str | Path, frame: GeoFrame, *, height_property: str = "height",
                    levels_property: str = "building:levels", level_height_m: float = 3.0,
                    default_height_m: float | None = None) -> list[Footprint]:
    """Every footprint of the GeoJSON file ``path`` (a FeatureCollection of Polygon / MultiPolygon features, WGS84
    lon/lat) in ``frame``'s local metres, its height from the feature's ``height_property`` (m), else its
    ``levels_property`` x ``level_height_m``, else ``default_height_m``; a MultiPolygon is one footprint per polygon.
    BuildingsError naming the file and feature (see the module)."""
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    path = Path(path)
    why = not_a_file(path)  # a FIFO would block the read, a folder would raise
    if why is not None:
        raise BuildingsError(f"{path}: {'no such footprint file' if why.startswith('no such file') else why}")
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise BuildingsError(f"{path}: no such footprint file") from None
    if size > MAX_FILE_BYTES:
        raise BuildingsError(f"{path}: {size / 1e6:.0f} MB is more than the {MAX_FILE_BYTES / 1e6:.0f} MB a footprint "
                             "file may have: cut it to the district the relays fly in")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BuildingsError(f"{path}: not GeoJSON ({exc})") from None
    if isinstance(doc, dict) and doc.get("type") == "Feature":
        features = [doc]
    elif isinstance(doc, dict) and doc.get("type") == "FeatureCollection" and isinstance(doc.get("features"), list):
        features = doc["features"]
    else:
        raise BuildingsError(f"{path}: a GeoJSON FeatureCollection (or one Feature) of building footprints, got "
                             f"{type(doc).__name__ if not isinstance(doc, dict) else doc.get('type')!r}")
    if len(features) > MAX_FEATURES:
        raise BuildingsError(f"{path}: {len(features)} features, more than the {MAX_FEATURES} a footprint file may have: "
                             "cut it to the district the relays fly in")
    out = []
    for i, feat in enumerate(features):
        props = feat.get("properties") if isinstance(feat, dict) else None
        props = props if isinstance(props, dict) else {}
        label = props.get("name") or (feat.get("id") if isinstance(feat, dict) else None)
        where = f"{path}: features[{i}]" + (f" ({label})" if label else "")
        if not isinstance(feat, dict) or feat.get("type") != "Feature":
            raise BuildingsError(f"{where}: not a GeoJSON Feature")
        height = _height(props, where, height_property, levels_property, level_height_m, default_height_m)
        rings = _rings(feat.get("geometry"), where)
        for k, ring in enumerate(rings):
            at = where if len(rings) == 1 else f"{where} polygon {k}"
            xy = _to_local(ring, frame, at)
            poly = Polygon(xy)
            if not poly.is_valid:
                raise BuildingsError(f"{at}: not a simple polygon ({explain_validity(poly)})")
            if poly.area < MIN_AREA_M2:
                raise BuildingsError(f"{at}: an empty footprint ({poly.area:.2g} m^2)")
            poly = poly.simplify(SIMPLIFY_M, preserve_topology=True)
            ext = np.asarray(poly.exterior.coords)[:-1]
            if len(ext) > MAX_CORNERS:
                raise BuildingsError(f"{at}: {len(ext)} corners, more than {MAX_CORNERS}: simplify the outline")
            if not poly.exterior.is_ccw:
                ext = ext[::-1]
            out.append(Footprint(i, str(label) if label else f"features[{i}]", tuple(map(tuple, ext.tolist())), height))
    return out


def _convex(poly, tol: float = 1e-9) -> bool:
    return poly.area >= poly.convex_hull.area * (1.0 - tol)


def _corners(poly) -> list[tuple[float, float]]:
    """A convex polygon's corners counter-clockwise, corners in a line with their neighbours dropped (within 1e-9 of
    the line's length: the seams a union of triangles leaves; 1 mm dropped a real corner 8 mm from the next, and with
    it a sliver of the footprint, or left a piece of two corners: found by hypothesis, 2026-12-06)."""
    from shapely.geometry.polygon import orient
    v = np.asarray(orient(poly).exterior.coords)[:-1]
    keep = []
    for j in range(len(v)):
        a, b, c = v[j - 1], v[j], v[(j + 1) % len(v)]
        ab, ac = b - a, c - a
        if abs(ab[0] * ac[1] - ab[1] * ac[0]) > 1e-9 * float(ac @ ac):  # b's distance off the line a-c, over its length
            keep.append((float(b[0]), float(b[1])))
    return keep


def convex_pieces(outline) -> list[list[tuple[float, float]]]:
    """A simple polygon's outline (x, y corners) as convex pieces that tile it (see the module), each its corners."""
    import shapely
    from shapely.geometry import Polygon

    poly = Polygon(outline)
    if _convex(poly):
        return [_corners(poly)]
    pieces = [t for t in shapely.constrained_delaunay_triangles(poly).geoms if t.area > 1e-12]
    merged = True
    while merged:
        merged = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                shared = pieces[i].intersection(pieces[j])
                if shared.length <= 1e-9:  # no common edge
                    continue
                union = pieces[i].union(pieces[j])
                if union.geom_type == "Polygon" and _convex(union):
                    pieces[i] = union
                    del pieces[j]
                    merged = True
                    break
            if merged:
                break
    return [_corners(p) for p in pieces]
