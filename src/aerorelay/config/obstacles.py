"""``[[obstacles]]``: the structures the vehicles fly among, as boxes (buildings) and vertical
cylinders (towers, poles), each with a margin every relay keeps (``models/obstacles.py``). Radio
links pass through them unless ``nlos_loss_db`` is set (a stated loss on every link whose straight
segment crosses the obstacle)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import NAME_PATTERN, Strict, Vec3


class ObstacleConfig(Strict):
    """One obstacle: ``kind = "box"`` with ``min_m`` / ``max_m``, or ``kind = "cylinder"`` with
    ``centre_m`` (x, y), ``radius_m`` and ``z_min_m`` / ``z_max_m``."""

    name: str | None = Field(None, max_length=32, pattern=NAME_PATTERN, description="names it in errors and logs; "
                             "default obstacle<i>")
    kind: Literal["box", "cylinder"] = Field(description="box (axis-aligned) or cylinder (vertical)")
    min_m: Vec3 | None = Field(None, description="box: its lowest corner, m (world)")
    max_m: Vec3 | None = Field(None, description="box: its highest corner, m (world)")
    centre_m: list[float] | None = Field(None, min_length=2, max_length=2, description="cylinder: its axis (x, y), m")
    radius_m: float | None = Field(None, gt=0.0, le=1000.0, description="cylinder: its radius, m")
    z_min_m: float | None = Field(None, description="cylinder: its bottom, m (world z)")
    z_max_m: float | None = Field(None, description="cylinder: its top, m (world z)")
    margin_m: float = Field(1.0, ge=0.0, le=50.0, description="how far from it every relay's planner and NMPC keep, m "
                            "(entering the obstacle itself makes a run unsafe)")
    nlos_loss_db: float = Field(0.0, ge=0.0, le=100.0, description="extra path loss of a radio link whose segment "
                                "crosses it, dB (0: radio passes through it)")

    @model_validator(mode="after")
    def _shape(self):
        box = ("min_m", "max_m")
        cyl = ("centre_m", "radius_m", "z_min_m", "z_max_m")
        need, other = (box, cyl) if self.kind == "box" else (cyl, box)
        missing = [f for f in need if getattr(self, f) is None]
        if missing:
            raise ValueError(f"a {self.kind} needs {', '.join(missing)}")
        extra = [f for f in other if getattr(self, f) is not None]
        if extra:
            raise ValueError(f"a {self.kind} has no {', '.join(extra)}")
        if self.kind == "box" and any(a >= b for a, b in zip(self.min_m, self.max_m, strict=True)):
            raise ValueError(f"min_m {self.min_m} must be below max_m {self.max_m} on every axis")
        if self.kind == "cylinder" and self.z_min_m >= self.z_max_m:
            raise ValueError(f"z_min_m ({self.z_min_m}) must be below z_max_m ({self.z_max_m})")
        return self
