"""What every configuration table shares: strict models, 3-vectors, timed waypoints, the error type."""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Waypoint = Annotated[list[float], Field(min_length=4, max_length=4)]


class ScenarioError(ValueError):
    """A scenario failed validation; ``str()`` lists one line per bad field."""


NAME_PATTERN = r"^[A-Za-z][A-Za-z0-9_-]*$"  # a vehicle, station, jammer or obstacle name: a letter, then letters, digits, _ or -


class Strict(BaseModel):
    """A configuration table: unknown fields rejected, no inf / NaN unless a field says so (fading
    K = inf means "no fading"), assignments validated."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False, strict=True)


PAPER_PLANNER = "trajectory_generator"  # the paper's generator: one name for one relay and fleets ("paper" is read as it)
NETWORK_PLANNER = "equidistant"  # a network's planner when controller.planner names none (one relay's: PAPER_PLANNER)


def papers_generator_named(v):
    """A planner name as given, ``"paper"`` read as ``PAPER_PLANNER``."""
    return PAPER_PLANNER if v == "paper" else v


def on_the_earth(v: list[float]) -> list[float]:
    """A geodetic ``[lat_deg, lon_deg, alt_m]`` unchanged; ValueError unless lat is in [-90, 90] deg and
    lon in [-180, 180] deg."""
    if not (-90 <= v[0] <= 90 and -180 <= v[1] <= 180):
        raise ValueError("[lat_deg, lon_deg, alt_m] needs lat in [-90, 90] deg and lon in [-180, 180] deg")
    return v


def nonzero_direction(v: list[float], what: str) -> list[float]:
    """``v`` unchanged; ValueError when it has no direction (norm below 1e-9)."""
    if math.hypot(*v) < 1e-9:
        raise ValueError(f"{what} must be a non-zero direction")
    return v


def check_waypoint_times(wps: list[list[float]], first_zero: bool) -> None:
    """Waypoint times ``w[0]`` (s) non-negative, strictly increasing, the first 0 when ``first_zero``."""
    t = [w[0] for w in wps]
    if first_zero and t[0] != 0.0:
        raise ValueError(f"the first waypoint time must be 0 s, got {t[0]}")
    if t[0] < 0.0:
        raise ValueError(f"waypoint times must be >= 0 s, got {t[0]}")
    if any(b <= a for a, b in zip(t, t[1:], strict=False)):
        raise ValueError(f"waypoint times must be strictly increasing, got {t}")


def dbm_to_w(dbm: float) -> float:
    """``10^((dBm - 30)/10)`` W."""
    return 10.0 ** ((dbm - 30.0) / 10.0)
