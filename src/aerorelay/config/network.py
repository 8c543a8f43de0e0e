"""Relay networks as data: ``[[relays]]`` (each a vehicle with its own NMPC), ``[[sources]]`` (the
inspection drones, each with its mission) and ``[network]`` (the routes from each source through
relays to the base station, and the separation every vehicle keeps). A file with ``[nodes] relay``
and ``[mission]`` is one relay named ``relay`` and one source named ``source``."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal

from pydantic import Field, field_validator

from .base import NAME_PATTERN, Strict, Vec3, nonzero_direction
from .mission import MissionConfig
from .platform import PlatformConfig
from .radio import NodeAntennaConfig

BASE_STATION = "bs"  # the base station's name in routes ([nodes] bs)
ANY_BASE_STATION = "any"  # a route's end: whichever base station serves it best ([[base_stations]], the handover rule)
LEGACY_RELAY, LEGACY_SOURCE = "relay", "source"  # the one relay and source of a file with [nodes] relay and [mission]


def sole(names: Iterable[str]) -> str | None:
    """The relay (or source) of a run that flew one, else None: the one rule by which outputs are laid out as one
    relay's runs always were (its metrics and timing at the top level, its figures unsuffixed). Presentation only:
    what is flown reads ``Scenario.shape``."""
    names = list(names)
    return names[0] if len(names) == 1 else None

# platform presets a relay may name (``platform = "quad_x"``); an inline table is a [platform] table
PLATFORM_PRESETS: dict[str, dict[str, Any]] = {
    "hexa_tilted": {},  # the paper's hexarotor, rotors tilted 20 deg (the [platform] defaults)
    "hexa_coplanar": {"tilt_deg": 0.0, "arm_length_m": 0.35},
    "octo_tilted": {"rotor_count": 8, "tilt_deg": 20.0, "arm_length_m": 0.35},
    "quad_x": {"rotors": [{"position": [s * 0.2475, t * 0.2475, 0.0], "axis": [0.0, 0.0, 1.0], "spin": spin}
                          for s, t, spin in ((1, 1, 1), (-1, 1, -1), (-1, -1, 1), (1, -1, -1))]},
}



class RelayConfig(Strict):
    """One relay of the fleet: its name, start and (optionally) its own platform and controller."""

    name: str = Field(min_length=1, max_length=32, pattern=NAME_PATTERN, description="names the relay in routes, logs "
                      "and reports (letters, digits, _ and -; a letter first)")
    start: Vec3 = Field(description="the relay's start, m (world), hovering; inside controller.workspace")
    platform: str | PlatformConfig | None = Field(None, description="a preset name (hexa_tilted, hexa_coplanar, "
                                                  "octo_tilted, quad_x) or an inline [platform] table; default: [platform]")
    controller: dict[str, Any] | None = Field(None, description="fields of [controller] this relay flies with instead "
                                              "of the shared ones (e.g. planner, mu, weights)")
    antenna: NodeAntennaConfig | None = Field(None, description="this relay's own antenna about its body z; default: "
                                              "[antenna]'s")
    lost_at_s: float | None = Field(None, gt=0.0, description="the relay is lost at this time, s (battery, fault): from "
                                    "then on it is gone, every route through it skips it and the others re-plan; "
                                    "before the mission's end; default: never")
    standby: bool = Field(False, description="a spare: it waits at its start, on no route, and launches when a relay "
                          "of the network will have to fly home ([platform.battery] go_home) so that it arrives before "
                          "that one leaves, then takes its place on its routes (docs/concepts/operations.md)")

    @field_validator("platform")
    @classmethod
    def _known_preset(cls, v):
        if isinstance(v, str) and v not in PLATFORM_PRESETS:
            raise ValueError(f"unknown platform preset {v!r}; use one of {sorted(PLATFORM_PRESETS)} or an inline table")
        return v


class SourceConfig(Strict):
    """One inspection drone (a source of data): its name and its mission."""

    name: str = Field(min_length=1, max_length=32, pattern=NAME_PATTERN, description="names the source in routes, logs "
                      "and reports")
    mission: MissionConfig = Field(default_factory=MissionConfig, description="its path, as [mission]")
    antenna: NodeAntennaConfig | None = Field(None, description="this source's own antenna about its body z; default: "
                                              "[antenna]'s (source_pattern)")


class BaseStationConfig(Strict):
    """One base station of several (``[[base_stations]]``): its name, where it stands, its antenna."""

    name: str = Field(min_length=1, max_length=32, pattern=NAME_PATTERN, description="names the base station in routes, "
                      "logs and reports ('any' is the route end meaning the best one)")
    position: Vec3 = Field(description="m (world); fixed, identity attitude")
    antenna: NodeAntennaConfig | None = Field(None, description="its own antenna about its axis; default: [antenna]'s "
                                              "bs_pattern (and bs_g_max, bs_exponent, bs_back_lobe for cosine)")
    axis: Vec3 | None = Field(None, description="its antenna's axis (world; normalized): a dipole's or sin_power's axis, a "
                              "cosine antenna's boresight; default: [antenna]'s (bs_tilt_deg, bs_azimuth_deg)")

    @field_validator("name")
    @classmethod
    def _not_any(cls, v):
        if v == ANY_BASE_STATION:
            raise ValueError(f"{ANY_BASE_STATION!r} is the route end that means the best base station; name it otherwise")
        return v

    _nonzero_axis = field_validator("axis")(lambda v: v if v is None else nonzero_direction(v, "a base station's antenna axis"))

    @field_validator("antenna")
    @classmethod
    def _axis_once(cls, v):
        if v is not None and v.axis is not None:
            raise ValueError("antenna.axis is a vehicle's, in its body frame; a base station's antenna axis is its own "
                             "'axis' (world), beside 'antenna'")
        return v


class NetworkConfig(Strict):
    """How data flows: each route from a source through relays to the base station ``bs``; how its hops share the
    time (``schedule``; the routes take turns; docs/concepts/networks.md)."""

    routes: list[list[str]] | None = Field(None, min_length=1, description="each [source, relay, ..., base station]: "
                                           "\"bs\" ([nodes] bs), a [[base_stations]] name, or \"any\" (the best base station "
                                           "by the route's rate, with the handover rule); default: one route per source through "
                                           "every relay in order to the base station (\"any\" with several)")
    handover_margin_db: float = Field(3.0, ge=0.0, le=30.0, description="a route ending at \"any\" hands over to "
                                      "another base station when that one's route rate exceeds the serving one's by this "
                                      "much, dB (10 log10 of the rates' ratio); a serving route that is dead hands over to "
                                      "any live one")
    handover_dwell_s: float = Field(2.0, ge=0.0, le=3600.0, description="a route stays with a base station at least this "
                                    "long after a handover (s); the first serving one is the best at t = 0")
    min_separation_m: float | None = Field(None, gt=0.0, le=100.0, description="between any two vehicles (relays and "
                                           "sources), m; default the vehicles' own size: twice the largest footprint radius "
                                           "of the relays' platforms (1.5 x the farthest rotor centre: the arm plus a rotor "
                                           "of half its length); a smaller value is refused")
    separation_neighbours: int = Field(4, ge=1, le=32, description="each relay's NMPC keeps min_separation_m from at most "
                                       "this many other vehicles at a time: the nearest over its horizon, by their predicted "
                                       "paths (a row each; a vehicle beyond them is counted in the relay's "
                                       "separation_unguarded_steps when it comes within twice the separation). A relay's "
                                       "step then costs the same in a network of any size (docs/results/networks.md)")
    route: bool = Field(True, description="the capacity planner flies near a pre-flight route (false: no route, no leash: "
                        "hill climbing from the starts alone)")
    schedule: Literal["tdma", "spatial_reuse", "full_duplex"] = Field(
        "tdma", description="how a route's hops share the time (the routes always take turns): 'tdma', a slot per hop; "
        "'spatial_reuse', hops that share no node in one slot, each the others' interference, the reuse distance that "
        "gives the most chosen per step (one relay: 'tdma' exactly); 'full_duplex', every hop at once, each relay "
        "hearing its own transmission self_interference_db below its power (half duplex where that gives more); "
        "docs/concepts/networks.md")
    self_interference_db: float = Field(110.0, ge=0.0, le=200.0, description="full duplex: a relay's own transmission "
                                        "at its receiver, this far below its transmit power (dB)")
    route_selection: Literal["fixed", "subsets"] = Field(
        "fixed", description="'fixed': each route takes every relay named on it; 'subsets': a route may skip any of its "
        "relays (the others kept in order, none at all: the direct link), the serving subset chosen from every step's "
        "true rates by the handover rule (handover_margin_db better, after handover_dwell_s), the skipped relays flying "
        "on their plans; logged per step (<source>.route), counted (route_switches), and the network's bound takes the "
        "best subset at every instant (docs/concepts/networks.md)")

