"""``[[obstacles]]``: the structures the vehicles fly among, as boxes (axis-aligned buildings), prisms (a convex
footprint of any orientation extruded to a height) and vertical cylinders (towers, poles), each with a margin every
relay keeps (``models/obstacles.py``). Radio
links pass through them unless ``nlos_loss_db`` is set (a stated loss on every link whose straight
segment crosses the obstacle)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ..models.obstacles import Prism
from .base import NAME_PATTERN, Strict, Vec3
from .radio import ItuMaterial

MAX_OBSTACLES = 64  # every obstacle is a separating plane per stage of every relay's NMPC


class ObstacleConfig(Strict):
    """One obstacle: ``kind = "box"`` with ``min_m`` / ``max_m``, ``kind = "prism"`` with ``footprint_m`` (its convex
    footprint's corners (x, y) in order) and ``z_min_m`` / ``z_max_m``, or ``kind = "cylinder"`` with ``centre_m``
    (x, y), ``radius_m`` and ``z_min_m`` / ``z_max_m``."""

    name: str | None = Field(None, max_length=32, pattern=NAME_PATTERN, description="names it in errors and logs; "
                             "default obstacle<i>")
    kind: Literal["box", "prism", "cylinder"] = Field(description="box (axis-aligned), prism (a convex footprint of any "
                                                      "orientation, vertical) or cylinder (vertical)")
    min_m: Vec3 | None = Field(None, description="box: its lowest corner, m (world)")
    max_m: Vec3 | None = Field(None, description="box: its highest corner, m (world)")
    centre_m: list[float] | None = Field(None, min_length=2, max_length=2, description="cylinder: its axis (x, y), m")
    radius_m: float | None = Field(None, gt=0.0, le=1000.0, description="cylinder: its radius, m")
    footprint_m: list[list[float]] | None = Field(None, min_length=3, max_length=64, description="prism: its footprint's "
                                                  "corners [[x, y], ...], m (world), in order around it; convex")
    z_min_m: float | None = Field(None, description="cylinder or prism: its bottom, m (world z)")
    z_max_m: float | None = Field(None, description="cylinder or prism: its top, m (world z)")
    margin_m: float = Field(1.0, ge=0.0, le=50.0, description="how far from it every relay's planner and NMPC keep, m "
                            "(entering the obstacle itself makes a run unsafe)")
    nlos_loss_db: float = Field(0.0, ge=0.0, le=100.0, description="extra path loss of a radio link whose segment "
                                "crosses it, dB (0: radio passes through it)")
    material: ItuMaterial | None = Field(None, description="its ITU-R P.2040 material in the scene traced from the "
                                         "obstacles (channel.propagation.scene = 'obstacles'; default: "
                                         "channel.propagation.building_material)")

    @model_validator(mode="after")
    def _shape(self):
        fields = {"box": ("min_m", "max_m"), "cylinder": ("centre_m", "radius_m", "z_min_m", "z_max_m"),
                  "prism": ("footprint_m", "z_min_m", "z_max_m")}
        need = fields[self.kind]
        missing = [f for f in need if getattr(self, f) is None]
        if missing:
            raise ValueError(f"a {self.kind} needs {', '.join(missing)}")
        extra = sorted({f for fs in fields.values() for f in fs} - set(need))
        extra = [f for f in extra if getattr(self, f) is not None]
        if extra:
            raise ValueError(f"a {self.kind} has no {', '.join(extra)}")
        if self.kind == "box" and any(a >= b for a, b in zip(self.min_m, self.max_m, strict=True)):
            raise ValueError(f"min_m {self.min_m} must be below max_m {self.max_m} on every axis")
        if self.kind in ("cylinder", "prism") and self.z_min_m >= self.z_max_m:
            raise ValueError(f"z_min_m ({self.z_min_m}) must be below z_max_m ({self.z_max_m})")
        if self.kind == "prism":
            if any(len(c) != 2 for c in self.footprint_m):
                raise ValueError(f"footprint_m: every corner is [x, y] (m), got {self.footprint_m}")
            # the shape's own checks: convex, no repeated corner, not crossing itself (ValueError, named by validation)
            Prism(tuple((float(x), float(y)) for x, y in self.footprint_m), self.z_min_m, self.z_max_m)
        return self


class BuildingsConfig(Strict):
    """``[buildings]``: the buildings of a GeoJSON footprint file (lat/lon polygons with heights, as OpenStreetMap or a
    city's cadastre exports them) as prisms from the ground to their heights, at load: each footprint in the local
    frame of ``[geo] origin``, cut into convex pieces where it is not convex, one ``kind = "prism"`` obstacle each
    (named ``building<i>`` / ``building<i>_<k>``, ``i`` the feature's index), with this table's margin and radio
    loss. Footprints farther than ``reach_m`` from the box around the workspace, the base stations, the relays' starts
    and the jammers are left out (``aerorelay validate`` says how many); with the file's other obstacles at most 64
    prisms, or a named error."""

    geojson: str = Field(description="the footprint file (GeoJSON FeatureCollection of Polygon / MultiPolygon features, "
                         "WGS84 lon/lat), relative to the scenario file")
    height_property: str = Field("height", min_length=1, description="the feature property holding the height, m")
    levels_property: str = Field("building:levels", min_length=1, description="the feature property holding the "
                                 "number of storeys, used when the height is missing")
    level_height_m: float = Field(3.0, gt=0.0, le=10.0, description="a storey's height, m")
    default_height_m: float | None = Field(None, gt=0.0, le=1000.0, description="the height of a footprint with "
                                           "neither property, m (default: such a footprint is an error)")
    margin_m: float = Field(1.0, ge=0.0, le=50.0, description="how far from every building the relays keep, m")
    nlos_loss_db: float = Field(0.0, ge=0.0, le=100.0, description="extra path loss of a radio link whose segment "
                                "crosses a building, dB (0: radio passes through; the ray-traced channel sees walls "
                                "itself)")
    material: ItuMaterial | None = Field(None, description="the buildings' ITU-R P.2040 material in the scene traced "
                                         "from the obstacles (default: channel.propagation.building_material)")
    reach_m: float = Field(30.0, ge=0.0, le=100_000.0, description="footprints farther than this (m, horizontally) "
                           "from the box around the workspace, base stations, relays' starts and jammers are left out")
