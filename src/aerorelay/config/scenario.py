"""The scenario as plain data: every table, the cheap cross-field checks (names, coincident nodes,
the relay's start in its workspace, whole plant steps per control period), TOML text, dotted-key
updates and the named error lines. What needs physics (hover, reachable alignment, propagation
geometry, the mission file against the ground) is checked in ``assembly.checks``.

Every field carries its unit in its name or docstring. Unknown fields are rejected. Defaults are
the paper's Table I values and the working spec's resolved choices (docs/concepts/spec.md), so an
empty ``[section]`` is valid.
"""

from __future__ import annotations

import copy
import logging
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, Field, PrivateAttr, ValidationError, field_validator, model_validator

from ..models.buildings import BuildingsError, convex_pieces, read_footprints
from ..models.geo import GeoFrame
from ..models.obstacles import obstacle_model
from .air import WindConfig
from .applies import GENERATORS as PAPER_GENERATORS
from .applies import OBSTACLE, dormant, dotted, generated_scene, refusal
from .base import NETWORK_PLANNER, PAPER_PLANNER, ScenarioError, Strict, Vec3, on_the_earth, papers_generator_named
from .controller import ControllerConfig
from .errors import format_errors
from .mission import MissionConfig
from .network import (
    ANY_BASE_STATION,
    BASE_STATION,
    LEGACY_RELAY,
    LEGACY_SOURCE,
    PLATFORM_PRESETS,
    BaseStationConfig,
    NetworkConfig,
    RelayConfig,
    SourceConfig,
)
from .obstacles import MAX_OBSTACLES, BuildingsConfig, ObstacleConfig
from .platform import PlatformConfig
from .radio import AntennaConfig, ChannelConfig, JammerConfig, NodesConfig
from .sections import BoundConfig, EstimationConfig, PerturbationConfig, SimConfig, VerdictConfig, WorldConfig
from .tomltext import compact_toml

log = logging.getLogger(__name__)

MIN_NODE_SEPARATION_M = 0.1


def _numbered(jammer: Any, i: int) -> Any:
    """One of several ``[[jammers]]`` tables, named ``jammer<i+1>`` when it has no name."""
    if isinstance(jammer, dict) and "name" not in jammer:
        return {**jammer, "name": f"jammer{i + 1}"}
    if isinstance(jammer, BaseModel) and "name" not in jammer.model_fields_set:
        return jammer.model_copy(update={"name": f"jammer{i + 1}"})
    return jammer


class GeoConfig(Strict):
    """``[geo]``: the scenario's local frame on the earth, for geographic mission files."""

    origin: Vec3 = Field(description="[lat_deg, lon_deg, alt_m] (WGS84) of the local frame's origin: x east, y north, "
                         "z up (m); every trajectory_plan / trajectory_gpx mission without its own geo_origin uses it")

    _on_the_earth = field_validator("origin")(on_the_earth)


@dataclass(frozen=True)
class Shape:
    """What differs between the paper's problem (one relay carrying one source) and a network, field by field, each
    for a reason of physics or cost; read as data (``Scenario.shape``), never as a branch on the number of relays."""

    name: str
    planner: str  # the default planner: the paper's generator plans one relay toward one source and one base station
    bound_grid_m: float  # the bound's default grid: a network's bound grows with the square of its cells per relay pair
    bound_dt_s: float  # the bound's default time step (as the grid)
    route_dt_s: float  # the capacity planner's pre-flight route's step: a network's route is refined at each step
    plans: Literal["relay", "network"]  # which factory of the planner's registry entry plans it (planning.base.PLANNERS)
    bound: Literal["path", "network"]  # one relay's exact path bound (its grid and axes) or the network's cube bound
    neighbours: bool  # each relay's NMPC looks at its moving route neighbours (every relay keeps apart from every vehicle)
    hessian_floor: Literal["paper", "relative"]  # the generator's default eigenvalue floor: the paper's numbers for its
    # problem (relative at one relay in physical units left rma_av's relay at 7.4 m/s into its box's wall: results)


PAPERS_PROBLEM = Shape("one relay and one source", PAPER_PLANNER, 0.5, 0.5, 1.0, "relay", "path", False, "paper")
NETWORK_PROBLEM = Shape("a network", NETWORK_PLANNER, 2.0, 2.0, 2.0, "network", "network", True, "relative")


# a setting's old spellings (path in the file) -> its one field: read with a deprecation message naming it
RENAMED: dict[tuple[str, ...], tuple[str, ...]] = {
    ("network", "planner"): ("controller", "planner"),
    ("network", "route_dt_s"): ("controller", "capacity", "route_dt_s"),
    ("bound", "network_grid_m"): ("bound", "grid_m"),
    ("bound", "network_dt_s"): ("bound", "dt_s"),
}
# the settings a network's planner reads once for the whole network: a relay's own value is refused by name (every other
# [relays.controller] field is honoured for that relay: its NMPC, its shaper's limits, its axes, its governor speed)
NETWORK_WIDE: tuple[tuple[str, ...], ...] = (
    ("mu",), ("hessian_eig_floor",), ("hessian_floor",), ("senses_jammer_state",),
    *(("capacity", f) for f in ("margin_m", "leash_m", "route_grid_m", "route_dt_s", "lookahead_s", "yaw_rate_deg_s",
                                "excursion_m", "excursion_std_m", "excursion_max_loss", "scoring", "replan_every")))
# what only one relay's capacity planner does (circling to localize a jammer), refused in a network unless off (its
# value here); a fleet's planner yaws its relays as the one relay's does (planning.fleet_capacity)
ONE_TIME_GRID: tuple[tuple[str, ...], ...] = (("horizon",), ("ts_s",))  # every relay's NMPC's, for any network
ONE_RELAY_ONLY: dict[str, float] = {"excursion_m": 0.0}
_SAID_RENAMED: set[str] = set()


def said_renamed(old: str, new: str) -> None:
    """The deprecation message of an old spelling, once per process."""
    if old not in _SAID_RENAMED:
        _SAID_RENAMED.add(old)
        log.warning("%s is read as %s (one spelling for one relay or a network since 2026-12-05); write %s", old, new, new)


class Scenario(Strict):
    """A complete, validated relay scenario."""

    # the positions the file gave at lat/lon (``<field>_wgs84``) with their local values (m), for ``aerorelay validate``
    _wgs84_resolved: list = PrivateAttr(default_factory=list)
    _buildings_resolved: dict | None = PrivateAttr(default=None)

    def __eq__(self, other: object) -> bool:
        """Equal settings: what the file resolved at load (its lat/lon positions, its footprint file) is where the
        values came from, not part of them (a scenario written out and read again equals the one loaded)."""
        if not isinstance(other, Scenario):
            return NotImplemented
        return self.__dict__ == other.__dict__

    __hash__ = None  # type: ignore[assignment]  # mutable settings, as pydantic's models

    @property
    def wgs84_resolved(self) -> list[tuple[str, list]]:
        """The positions written at lat/lon (``<field>_wgs84``) and their local values (m, ENU at ``[geo] origin``)."""
        return list(self._wgs84_resolved)

    @property
    def buildings_resolved(self) -> dict | None:
        """What ``[buildings]`` became at load (its file, footprints kept and left out, prisms); None without it."""
        return None if self._buildings_resolved is None else dict(self._buildings_resolved)

    name: str = Field("scenario", description="names the scenario in outputs and reports")
    description: str = Field("", description="free text, shown in reports")
    seed: int = Field(0, ge=0, description="seeds every random element (noise, fading, shadowing, the energy detector)")
    injected: list[str] = Field(default_factory=list, description="written by a run flown with parts passed from Python "
                                "(a planner object, a radio scene, jammers) that this file cannot say: what they were; such a "
                                "file does not fly again without them (ar.simulate(sc, planner=...))")
    platform: PlatformConfig = Field(default_factory=PlatformConfig)
    antenna: AntennaConfig = Field(default_factory=AntennaConfig)
    channel: ChannelConfig = Field(default_factory=ChannelConfig)
    nodes: NodesConfig = Field(default_factory=NodesConfig)
    jammer: JammerConfig | None = Field(None, description="one jammer (the paper's); or [[jammers]] for any number")
    jammers: list[JammerConfig] | None = Field(None, max_length=32, description="any number of jammers (array of tables)")
    controller: ControllerConfig = Field(default_factory=ControllerConfig)
    mission: MissionConfig = Field(default_factory=MissionConfig)
    sim: SimConfig = Field(default_factory=SimConfig)
    perturbations: PerturbationConfig = Field(default_factory=PerturbationConfig)
    bound: BoundConfig = Field(default_factory=BoundConfig)
    estimation: EstimationConfig = Field(default_factory=EstimationConfig)
    world: WorldConfig = Field(default_factory=WorldConfig)
    verdict: VerdictConfig = Field(default_factory=VerdictConfig)
    geo: GeoConfig | None = Field(None, description="where the scenario's local frame sits on the earth (geographic mission files)")
    relays: list[RelayConfig] | None = Field(None, min_length=0, max_length=16, description="the relays of a network "
                                             "(replaces nodes.relay)")
    sources: list[SourceConfig] | None = Field(None, min_length=1, max_length=16, description="the inspection drones "
                                               "(replaces [mission])")
    base_stations: list[BaseStationConfig] | None = Field(None, min_length=1, max_length=8, description="several base "
                                                         "stations (replaces nodes.bs); a route ends at one by name or "
                                                         "at \"any\"")
    network: NetworkConfig = Field(default_factory=NetworkConfig)
    wind: WindConfig | None = Field(None, description="mean wind and Dryden gusts on every relay (default: still air)")
    obstacles: list[ObstacleConfig] | None = Field(None, max_length=MAX_OBSTACLES, description="boxes, prisms and "
                                                   "vertical cylinders the vehicles fly among (array of tables)")
    buildings: BuildingsConfig | None = Field(None, description="buildings from a GeoJSON footprint file, turned into "
                                              "prism obstacles at load (needs [geo] origin)")

    @model_validator(mode="before")
    @classmethod
    def _one_spelling(cls, data):
        """Old spellings of a setting read as its one field, with a deprecation message naming it (``RENAMED``); both
        spellings with different values are a named error."""
        if not isinstance(data, dict):
            return data
        data = copy.deepcopy(data)
        for old, new in RENAMED.items():
            table = data.get(old[0])
            if not isinstance(table, dict) or old[1] not in table:
                continue
            value = table.pop(old[1])
            if not table and old[0] == "network":
                data.pop("network")
            node = data
            for part in new[:-1]:
                node = node.setdefault(part, {}) if isinstance(node, dict) else node
                if not isinstance(node, dict):
                    raise ValueError(f"{'.'.join(new[:-1])}: must be a table (it takes {'.'.join(old)}'s value)")
            same = papers_generator_named if new[-1] == "planner" else (lambda v: v)
            if new[-1] in node and same(node[new[-1]]) != same(value):
                raise ValueError(f"{'.'.join(old)} = {value!r} and {'.'.join(new)} = {node[new[-1]]!r}: one setting spelled "
                                 f"twice with two values; write {'.'.join(new)} only ({'.'.join(old)} is its old spelling)")
            node[new[-1]] = value
            said_renamed('.'.join(old), '.'.join(new))
        return data

    @model_validator(mode="before")
    @classmethod
    def _one_jammer_table(cls, data):
        if isinstance(data, dict):
            if data.get("jammer") is not None and data.get("jammers") is not None:
                raise ValueError("give either [jammer] (one jammer) or [[jammers]] (any number), not both")
            if data.get("jammer") is None and data.get("jammers") is None:
                data = {**data, "jammer": {}}
            if isinstance(data.get("jammers"), list) and len(data["jammers"]) > 1:
                data = {**data, "jammers": [_numbered(j, i) for i, j in enumerate(data["jammers"])]}
        return data

    @property
    def jammer_configs(self) -> list[JammerConfig]:
        """Every jammer of the scenario, in order ([jammer] or [[jammers]])."""
        return list(self.jammers) if self.jammers is not None else [self.jammer] if self.jammer is not None else []

    def jammer_field(self, i: int) -> str:
        return "jammer" if self.jammers is None else f"jammers[{i}]"

    @model_validator(mode="after")
    def _consistent(self):
        if self.jammers is not None:
            names = [j.name for j in self.jammers]
            dup = sorted({n for n in names if names.count(n) > 1})
            if dup:
                raise ValueError(f"jammers: names must be unique, {dup} used more than once")
        self._one_way_to_name_the_fleet()
        pts = {
            **{self._base_station_field(i, "position"): b.position for i, b in enumerate(self.base_station_list)},
            **{self._relay_field(i, "start", legacy="nodes.relay"): r.start for i, r in enumerate(self.relay_list)},
            **{f"{self.jammer_field(i)}.position": j.position for i, j in enumerate(self.jammer_configs)},
            **{self._source_field(i, "mission start", legacy="mission.waypoints[0]"): s.mission.start
               for i, s in enumerate(self.source_list)},
        }
        names = list(pts)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                d = math.dist(pts[a], pts[b])
                if d < MIN_NODE_SEPARATION_M:
                    raise ValueError(
                        f"{a} and {b} coincide ({d:.3g} m apart); nodes must be >= {MIN_NODE_SEPARATION_M} m apart"
                    )
        modes = {j.localization for j in self.jammer_configs}
        if len(modes) > 1:
            raise ValueError("jammer.localization: every jammer must use the same mode (oracle or estimated)")
        for i, r in enumerate(self.relay_list):  # inside its own workspace, the one its NMPC and the verdict keep it in
            ws = self.controller_of(i).workspace
            if not ws.contains(r.start):
                where = self._relay_field(i, "start", legacy="nodes.relay")
                box = (f"relays[{i}].controller.workspace" if self.relays and "workspace" in (self.relays[i].controller or {})
                       else "controller.workspace")
                raise ValueError(f"{where} {r.start} must lie inside {box} [{ws.min}, {ws.max}]")
        self._routes_hold()
        nodes = self.base_station_names + [r.name for r in self.relay_list] + [s.name for s in self.source_list]
        for i, j in enumerate(self.jammer_configs):
            if j.point_at is not None and j.point_at not in nodes:
                raise ValueError(f"{self.jammer_field(i)}.point_at: {j.point_at!r} is not a node ({', '.join(nodes)})")
            if j.point_at in self.standby_names:
                raise ValueError(f"{self.jammer_field(i)}.point_at: {j.point_at!r} is a spare, on no route at the start; aim "
                                 "the jammer at a node of the network")
        self._one_planner()
        self._separation_holds()
        self._fading_has_its_strength()
        self._baseline_can_be_computed()
        self._schedule_holds()
        self._obstacles_hold()
        self._one_time_grid()
        self._losses_hold()
        for i in range(len(self.relay_list)):
            self.controller_of(i)
        steps = self.sim.plant_rate_hz * self.control_period_s
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise ValueError(
                f"the control period ({self.control_period_s} s) must be a whole number of plant steps "
                f"(sim.plant_rate_hz = {self.sim.plant_rate_hz})"
            )
        return self

    # --- the fleet: relays, sources, routes (legacy files: one relay 'relay', one source 'source') ---

    @property
    def names_its_fleet(self) -> bool:
        """Whether the file names its fleet ([[relays]] / [[sources]], any number) instead of nodes.relay and
        [mission] (a spelling: a file's layout, not its number of relays)."""
        return self.relays is not None or self.sources is not None

    @property
    def vehicle_count(self) -> int:
        """Every vehicle of the scenario: its relays (spares included) and its sources."""
        return len(self.relay_list) + len(self.source_list)

    @property
    def relay_list(self) -> list[RelayConfig]:
        """Every relay: ``[[relays]]``, or the one at ``nodes.relay`` named ``relay``."""
        return list(self.relays) if self.relays is not None else [RelayConfig(name=LEGACY_RELAY, start=self.nodes.relay)]

    @property
    def source_list(self) -> list[SourceConfig]:
        """Every source: ``[[sources]]``, or the one flying ``[mission]`` named ``source``."""
        return list(self.sources) if self.sources is not None else [SourceConfig(name=LEGACY_SOURCE, mission=self.mission)]

    @property
    def standby_names(self) -> list[str]:
        """The spare relays (``standby = true``): on no route until one takes a relay's place."""
        return [r.name for r in self.relay_list if r.standby]

    @property
    def base_station_list(self) -> list[BaseStationConfig]:
        """Every base station: ``[[base_stations]]``, or the one at ``nodes.bs`` named ``bs``."""
        if self.base_stations is not None:
            return list(self.base_stations)
        return [BaseStationConfig(name=BASE_STATION, position=self.nodes.bs)]

    @property
    def base_station_names(self) -> list[str]:
        return [b.name for b in self.base_station_list]

    def _base_station_field(self, i: int, what: str) -> str:
        return "nodes.bs" if self.base_stations is None else f"base_stations[{i}].{what}"

    @property
    def route_list(self) -> list[list[str]]:
        """Every route ``[source, relay, ..., base station]``: ``network.routes``, or one per source
        through every relay in order to the base station (``"any"`` of several)."""
        if self.network.routes is not None:
            return [list(r) for r in self.network.routes]
        relays = [r.name for r in self.relay_list if not r.standby]
        names = self.base_station_names
        end = names[0] if len(names) == 1 else ANY_BASE_STATION
        return [[s.name, *relays, end] for s in self.source_list]

    @property
    def first_station(self) -> BaseStationConfig:
        """The base station the first route ends at (the first listed for ``"any"``): the one a planner
        or NMPC that looks toward one base station looks at."""
        end = self.route_list[0][-1]
        return next((b for b in self.base_station_list if b.name == end), self.base_station_list[0])

    @property
    def has_route_choice(self) -> bool:
        """Whether a route may change in flight: its end (``has_handover``) or which of its relays carry it
        (``network.route_selection = "subsets"``)."""
        return self.has_handover or self.network.route_selection == "subsets"

    @property
    def has_handover(self) -> bool:
        """Whether a route ends at ``"any"`` of several base stations (the handover rule picks its end)."""
        return len(self.base_station_list) > 1 and any(r[-1] == ANY_BASE_STATION for r in self.route_list)

    @property
    def starts(self) -> dict[str, list[float]]:
        """Every vehicle's start by node name (m, world): the relays', then the sources' (their missions')."""
        return {r.name: r.start for r in self.relay_list} | {s.name: s.mission.start for s in self.source_list}

    @property
    def shape(self) -> Shape:
        """The paper's problem (one relay, one source) or a network: the one place the number of nodes decides
        anything (``Shape``: defaults, the planner's factory, the bound, an NMPC's neighbours)."""
        # exactly one relay and one source (their sum 2, twice the relays' 2); the direct link (no relay) is a network
        return PAPERS_PROBLEM if len(self.relay_list) + len(self.source_list) == 2 == 2 * len(self.relay_list) else NETWORK_PROBLEM

    @property
    def planner(self) -> str:
        """The planner's name (``controller.planner``; one relay's own ``relays[0].controller.planner``, refused for a
        relay of a network): by default the paper's generator for one relay and one source, the equidistant planner
        for a network (``Shape.planner``)."""
        return self.shared_controller.planner or self.shape.planner

    @property
    def hessian_floor(self) -> str:
        """The generator's eigenvalue floor rule (``controller.hessian_floor``; default the paper's for one relay and one
        source, relative for a network: ``Shape.hessian_floor``)."""
        return self.controller.hessian_floor or self.shape.hessian_floor

    @property
    def bound_grid_m(self) -> float:
        """The bound's position grid (``bound.grid_m``; default 0.5 m for one relay, 2 m for a network's bound,
        whose cost grows with the square of its cells)."""
        return self.bound.grid_m if self.bound.grid_m is not None else self.shape.bound_grid_m

    @property
    def bound_dt_s(self) -> float:
        """The bound's time grid (``bound.dt_s``; default 0.5 s for one relay, 2 s for a network)."""
        return self.bound.dt_s if self.bound.dt_s is not None else self.shape.bound_dt_s

    @property
    def route_dt_s(self) -> float:
        """The capacity planner's pre-flight route's time step (``controller.capacity.route_dt_s``, one relay's own or
        the network's: a relay of a network's is refused; default 1 s for one relay, 2 s for a network's route, refined
        on the network's rate at each step)."""
        given = self.shared_controller.capacity.route_dt_s
        return given if given is not None else self.shape.route_dt_s

    def controller_field(self, i: int, path: tuple[str, ...]) -> str:
        """Where relay ``i``'s controller setting ``path`` was written: ``relays[i].controller.<path>`` when its own
        table says it, else ``controller.<path>`` (the shared one it inherits): the field a refusal names."""
        node: object = self.relay_list[i].controller or {}
        for part in path:
            if not isinstance(node, dict) or part not in node:
                return "controller." + ".".join(path)
            node = node[part]
        return f"relays[{i}].controller." + ".".join(path)

    def _one_value(self, paths: tuple[tuple[str, ...], ...], why: str, because: str) -> None:
        """Each controller setting of ``paths`` has one value for every relay, the shared one: a relay's own differing
        value is refused naming its field and ``why``."""
        for i in range(len(self.relay_list)):
            own = self.controller_of(i)
            for path in paths:
                mine: object = own
                shared: object = self.controller
                for part in path:
                    mine, shared = getattr(mine, part), getattr(shared, part)
                if mine != shared:
                    raise ValueError(f"{self.controller_field(i, path)}: {why} controller.{'.'.join(path)} = {shared!r} "
                                     f"({because}); got {mine!r}")

    def _one_planner(self) -> None:
        """One planner plans a network: a relay's own ``controller.planner`` and what the planner reads once for every
        relay (``NETWORK_WIDE``) are refused there, as one relay's own capacity behaviours (``ONE_RELAY_ONLY``); the
        paper's generator needs ``mu > 0``."""
        if self.shape.plans == "network":  # one planner reads these once for every relay
            for i, r in enumerate(self.relay_list):
                if r.controller and r.controller.get("planner") is not None:
                    raise ValueError(f"relays[{i}].controller.planner: one planner plans the whole network "
                                     "(controller.planner); a relay of a network has none of its own")
                own = self.controller_of(i)
                for name, off in ONE_RELAY_ONLY.items():
                    if getattr(own.capacity, name) != off:
                        raise ValueError(f"{self.controller_field(i, ('capacity', name))}: only one relay's capacity planner "
                                         f"does this (a network's planners do not: leave it at {off!r}); got "
                                         f"{getattr(own.capacity, name)!r}")
            self._one_value(NETWORK_WIDE, "the network's planner plans every relay with one", "a relay's own speed and "
                            "acceleration limits, axes, tilt fraction, governor speed and NMPC are its own")
        for i in range(len(self.relay_list)):
            if self.planner == PAPER_PLANNER and self.controller_of(i).mu <= 0.0:
                raise ValueError(f"{self.controller_field(i, ('mu',))}: mu = 0 makes the trajectory generator's surrogate "
                                 "link H_bar = sqrt(mu) G_bar / d vanish (its inverse capacity is infinite); use mu > 0 with "
                                 "controller.planner = 'trajectory_generator'")

    @property
    def has_two_hops(self) -> bool:
        """One route of two hops to one base station, the paper's (source -> relay -> base station): the physics of its
        two hops (the link budget's Gamma_21 and Gamma_10, the relay's reachable alignment between the source and the
        base station) is the paper's; a chain's relay aligns with its route neighbours."""
        return len(self.route_list) == 1 and len(self.route_list[0]) == 3 and not self.has_route_choice

    def relay_view(self, i: int) -> Scenario:
        """Relay ``i``'s view of the scenario: its own platform and controller (``[[relays]]``) as the scenario's,
        so every part reads them where a file with ``nodes.relay`` has them (its NMPC is the one its network's planner
        declares: ``assembly.planners``)."""
        ctrl = self.controller_of(i)
        if self.relays is None or (self.relays[i].platform is None and not self.relays[i].controller):
            return self
        return self.model_copy(update={"platform": self.platform_of(i), "controller": ctrl})

    def platform_of(self, i: int) -> PlatformConfig:
        """Relay ``i``'s platform: its own (a preset or a table), else ``[platform]``."""
        p = self.relay_list[i].platform
        if p is None:
            return self.platform
        return PlatformConfig(**PLATFORM_PRESETS[p]) if isinstance(p, str) else p

    @property
    def shared_controller(self) -> ControllerConfig:
        """The controller settings one value holds for every relay (``_one_value``: the planner, the route's step): any
        relay's, its ``[relays.controller]`` over ``[controller]``; ``[controller]`` with no relay (the direct link)."""
        return self.controller_of(0) if self.relay_list else self.controller

    def controller_of(self, i: int) -> ControllerConfig:
        """Relay ``i``'s controller: ``[controller]`` with its ``[relays.controller]`` fields over it."""
        override = self.relay_list[i].controller
        if not override:
            return self.controller
        try:
            return ControllerConfig.model_validate(_merged(self.controller.model_dump(), override))
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(x) for x in first["loc"])
            raise ValueError(f"relays[{i}].controller.{loc}: {first['msg'].removeprefix('Value error, ')}") from None

    def _one_time_grid(self) -> None:
        """Every relay's NMPC predicts on the shared horizon and step (the relays exchange their plans)."""
        self._one_value(ONE_TIME_GRID, "every relay of a fleet predicts on the shared", "they exchange their plans")

    def _losses_hold(self) -> None:
        """``relays.lost_at_s``: one relay at least never lost, no jammer aimed at a relay that is lost. A
        loss at or after the flight's end does not happen in it (``--duration 3`` on a scenario that loses
        a relay at 30 s flies the first 3 s with every relay)."""
        lost = {r.name: (i, r.lost_at_s) for i, r in enumerate(self.relay_list)
                if r.lost_at_s is not None and r.lost_at_s < self.duration_s}
        if lost and len(lost) == len(self.relay_list):
            i = max(i for i, _ in lost.values())
            raise ValueError(f"relays[{i}].lost_at_s: every relay would be lost; keep one relay at least (no lost_at_s)")
        for i, j in enumerate(self.jammer_configs):
            if j.point_at in lost:
                raise ValueError(f"{self.jammer_field(i)}.point_at: {j.point_at!r} is lost at {lost[j.point_at][1]:g} s "
                                 "(relays.lost_at_s); aim the jammer at a node that stays")

    @property
    def losses(self) -> list[tuple[float, frozenset[str]]]:
        """When relays are lost: ``(t, every relay lost by then)`` in time order (s); empty: none is."""
        times = sorted({r.lost_at_s for r in self.relay_list if r.lost_at_s is not None and r.lost_at_s < self.duration_s})
        return [(t, frozenset(r.name for r in self.relay_list if r.lost_at_s is not None and r.lost_at_s <= t))
                for t in times]

    def without_relays(self, lost: frozenset[str]) -> Scenario:
        """The fleet with the relays ``lost`` gone: every route through one skips it (a route keeps its
        source and the base station), no loss left to happen."""
        relays = [r.model_copy(update={"lost_at_s": None}) for r in self.relay_list if r.name not in lost]
        routes = [[n for n in route if n not in lost] for route in self.route_list]
        routes = [r for i, r in enumerate(routes) if r not in routes[:i]]  # two routes may become one
        network = self.network.model_copy(update={"routes": routes})
        return self.model_copy(update={"relays": relays, "network": network})

    def network_of(self, relays: list[str], routes: list[list[str]]) -> Scenario:
        """The fleet flying ``relays`` (names, spares among them now on routes) on ``routes``, no loss left to happen:
        what a network planner is built for after relays are lost, gone home or taken over."""
        by_name = {r.name: r for r in self.relay_list}
        flying = [by_name[n].model_copy(update={"lost_at_s": None, "standby": False}) for n in relays]
        # the network's planner and its route step, kept when one relay and one source are left (whose defaults are
        # the one relay's)
        controller = self.controller.model_copy(update={
            "planner": self.planner,
            "capacity": self.controller.capacity.model_copy(update={"route_dt_s": self.route_dt_s})})
        return self.model_copy(update={"relays": flying, "network": self.network.model_copy(update={"routes": routes}),
                                       "controller": controller})

    def _relay_field(self, i: int, what: str, *, legacy: str) -> str:
        return legacy if self.relays is None else f"relays[{i}].{what}"

    def _source_field(self, i: int, what: str, *, legacy: str) -> str:
        return legacy if self.sources is None else f"sources[{i}].{what}"

    def _one_way_to_name_the_fleet(self) -> None:
        if self.relays is not None and "relay" in self.nodes.model_fields_set:
            raise ValueError("nodes.relay: give the relays as [[relays]] or one nodes.relay, not both")
        if self.sources is not None and "mission" in self.model_fields_set:
            raise ValueError("mission: give the sources as [[sources]] (each with its [sources.mission]) or one "
                             "[mission], not both")
        if self.base_stations is not None and "bs" in self.nodes.model_fields_set:
            raise ValueError("nodes.bs: give the base stations as [[base_stations]] or one nodes.bs, not both")
        names = [s.name for s in self.source_list] + [r.name for r in self.relay_list] + self.base_station_names
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"network: {twice} named more than once (sources, relays and base stations "
                             f"{self.base_station_names} need distinct names)")
        if ANY_BASE_STATION in names:
            raise ValueError(f"network: {ANY_BASE_STATION!r} is the route end meaning the best base station; name the "
                             "vehicle otherwise")

    def _routes_hold(self) -> None:
        """Each route from a source through relays to a base station (or ``"any"``), no node twice, no
        route twice; every relay and every source on a route."""
        sources, relays = [s.name for s in self.source_list], [r.name for r in self.relay_list]
        stations = self.base_station_names
        ends = stations + [ANY_BASE_STATION]
        routes = self.route_list
        for i, route in enumerate(routes):
            where = f"network.routes[{i}]"
            unknown = [n for n in route if n not in sources + relays + ends]
            if unknown:
                raise ValueError(f"{where}: no node named {unknown[0]!r} (sources {sources}, relays {relays}, base "
                                 f"stations {stations} or 'any')")
            if len(route) < 2 or route[-1] not in ends:
                raise ValueError(f"{where}: {route} must end at a base station ({', '.join(ends)})")
            inner = [n for n in route[:-1] if n in ends]
            if inner:
                raise ValueError(f"{where}: {route} passes the base station {inner[0]!r} before its end")
            if route[0] not in sources:
                raise ValueError(f"{where}: {route} must start at a source ({', '.join(sources)})")
            twice = [n for n in route if route.count(n) > 1]
            if twice:
                raise ValueError(f"{where}: {route} passes {twice[0]!r} twice (a cycle)")
            wrong = [n for n in route[1:-1] if n not in relays]
            if wrong:
                raise ValueError(f"{where}: {wrong[0]!r} inside the route is not a relay (relays {relays})")
            if route in routes[:i]:
                raise ValueError(f"{where}: {route} is given twice")
        used = {n for r in routes for n in r}
        for i, r in enumerate(self.relay_list):
            if r.standby and r.name in used:
                raise ValueError(f"relays[{i}].standby: the spare {r.name!r} is on a route; a spare waits on none until it "
                                 "takes a relay's place")
            if not r.standby and r.name not in used:
                raise ValueError(f"relays[{i}]: {r.name!r} is on no route of network.routes (a relay carries data)")
        self._spares_can_take_over()
        for i, s in enumerate(self.source_list):
            if s.name not in used:
                raise ValueError(f"sources[{i}]: {s.name!r} is on no route of network.routes (its data goes nowhere)")

    def _spares_can_take_over(self) -> None:
        """A spare has a relay to stand by for (one that flies home: ``[platform.battery] go_home``), is never lost at
        a time, and one relay at least flies from the start."""
        spares = [i for i, r in enumerate(self.relay_list) if r.standby]
        if not spares:
            return
        if len(spares) == len(self.relay_list):
            raise ValueError(f"relays[{spares[-1]}].standby: every relay is a spare; one at least flies from the start")
        batteries = [(r, self.platform_of(i).battery) for i, r in enumerate(self.relay_list)]
        homing = [r.name for r, b in batteries if not r.standby and b is not None and b.go_home]
        if not homing:
            raise ValueError(f"relays[{spares[0]}].standby: no relay of the network flies home ([platform.battery] with "
                             "go_home = true, its own or the shared one), so the spare would never launch")
        flying = len(self.relay_list) - len(spares)
        if flying == 1 and len(self.source_list) == 1 and self.controller.planner is None:
            raise ValueError(f"relays[{spares[0]}].standby: with a spare, one relay and one source are a network, planned by "
                             "a network's planner before and after the spare takes over; name it (controller.planner = "
                             "\"capacity\", \"equidistant\", ...)")
        for i in spares:
            if self.relay_list[i].lost_at_s is not None:
                raise ValueError(f"relays[{i}].lost_at_s: a spare is not lost at a time (it is on no route until it takes over)")

    @property
    def obstacle_list(self) -> list[ObstacleConfig]:
        """The obstacles, each named (``obstacle<i>`` when the file gives no name)."""
        return [o if o.name else o.model_copy(update={"name": f"obstacle{i + 1}"}) for i, o in enumerate(self.obstacles or [])]

    def _obstacles_hold(self) -> None:
        """Unique names; every relay starts outside every obstacle and its margin (its NMPC could
        not keep out from inside); the base station and the jammers outside the obstacles."""
        names = [str(o.name) for o in self.obstacle_list]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"obstacles: names must be unique, {dup} used more than once")
        for i, o in enumerate(self.obstacle_list):
            shape = obstacle_model(o)
            for j, r in enumerate(self.relay_list):
                d = float(shape.signed_distance(r.start))
                if d < 0:
                    where = self._relay_field(j, "start", legacy="nodes.relay")
                    raise ValueError(f"{where} {r.start} lies {-d:.2f} m inside obstacles[{i}] ({o.name}) and its "
                                     f"margin ({o.margin_m} m): start every relay outside")
            fixed = {**{self._base_station_field(k, "position"): b.position for k, b in enumerate(self.base_station_list)},
                     **{f"{self.jammer_field(k)}.position": j.position for k, j in enumerate(self.jammer_configs)}}
            bare = obstacle_model(o, margin=False)
            for where, p in fixed.items():
                if float(bare.signed_distance(p)) < 0:
                    raise ValueError(f"{where} {p} lies inside obstacles[{i}] ({o.name})")

    def _fading_has_its_strength(self) -> None:
        """``[channel.fading] model = "doppler"`` without a finite ``perturbations.fading_k_db`` draws no
        fading: a setting that does nothing is named, not kept silently."""
        k = self.perturbations.fading_k_db
        if self.channel.fading.model != "iid" and (k is None or not math.isfinite(k)):
            raise ValueError(f"channel.fading.model: {self.channel.fading.model!r} needs perturbations.fading_k_db, the "
                             f"Rician K in dB (0 for Rayleigh); without it (got {k}) no fading is drawn")

    def _schedule_holds(self) -> None:
        """``network.schedule`` other than time division needs the links between the hops' transmitters and receivers
        (not a ray-traced channel's) and a planner that plans with it (the paper's generator's surrogate is time
        division: it takes spatial reuse only where no two hops of a route share no node, i.e. where it is time
        division)."""
        schedule = self.network.schedule
        if schedule == "tdma":
            return
        if self.channel.propagation.model == "ray_traced":
            raise ValueError(f"network.schedule: {schedule!r} counts the links between the hops' transmitters and "
                             "receivers, which the ray-traced channel does not trace; allowed with "
                             "channel.propagation.model = 'ray_traced': 'tdma'")
        reuse = any(len(r) - 1 >= 3 for r in self.route_list)  # a route with two hops that share no node
        if self.planner in PAPER_GENERATORS and (schedule == "full_duplex" or reuse):
            raise ValueError(f"network.schedule: {schedule!r} changes the rate the paper's trajectory generator "
                             f"(controller.planner = {self.planner!r}) plans with its time-division surrogate (eq. 12-13); "
                             "allowed with it: 'tdma' (and 'spatial_reuse' where no route has three hops); or a planner "
                             "that scores the rate itself ('capacity', 'equidistant')")

    def _baseline_can_be_computed(self) -> None:
        """``sim.baseline = "direct"`` is the direct link on the deterministic channel (``sim.baseline``): with random
        channel terms or a ray-traced channel the run's rate would be set against a link the flight did not see."""
        if self.sim.baseline != "direct":
            return
        k = self.perturbations.fading_k_db
        random = [what for what, on in (
            ("perturbations.fading_k_db (fading)", k is not None and math.isfinite(k)),
            ("channel.propagation's per-seed shadowing or LoS states", self.channel.propagation.random),
            ("channel.propagation.model = 'ray_traced'", self.channel.propagation.model == "ray_traced")) if on]
        if random:
            raise ValueError(f"sim.baseline: 'direct' is the direct link on the deterministic channel; this scenario's "
                             f"rate has {', '.join(random)}, which the direct link's would not: not built; allowed "
                             "here: 'none'")

    @property
    def vehicle_size_m(self) -> float:
        """The closest two vehicles' centres may come before they touch, m: twice the largest footprint
        radius of the relays' platforms (``PlatformConfig.footprint_radius_m``; a source's size is taken
        as a relay's)."""
        return 2.0 * max((self.platform_of(i).footprint_radius_m for i in range(len(self.relay_list))),
                         default=self.platform.footprint_radius_m)  # no relay: the sources' size, taken as [platform]'s

    @property
    def separation_m(self) -> float:
        """``network.min_separation_m``, or the vehicles' own size when it is not given (m)."""
        given = self.network.min_separation_m
        return self.vehicle_size_m if given is None else given

    def _separation_holds(self) -> None:
        """``network.min_separation_m`` (never below the vehicles' size): every two vehicles start that
        far apart, and the workspace holds the relays that far apart (on a cubic lattice of that spacing)."""
        d, size = self.separation_m, self.vehicle_size_m
        if d < size - 1e-9:
            raise ValueError(f"network.min_separation_m: {d:g} m is closer than two vehicles can be without touching "
                             f"({size:.3g} m: twice the relays' largest footprint radius); allowed {size:.3g}-100 m, or "
                             "leave it out for that default")
        ws = self.controller.workspace
        room = math.prod(math.floor((hi - lo) / d + 1e-9) + 1 for lo, hi in zip(ws.min, ws.max, strict=True))
        if room < len(self.relay_list):
            raise ValueError(f"network.min_separation_m: controller.workspace holds {room} vehicles {d:g} m apart "
                             f"(a cubic lattice), fewer than the {len(self.relay_list)} relays")
        starts = {f"relays[{i}] ({r.name!r})": r.start for i, r in enumerate(self.relay_list)}
        starts |= {f"sources[{i}] ({s.name!r})": s.mission.start for i, s in enumerate(self.source_list)}
        names = list(starts)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                gap = math.dist(starts[a], starts[b])
                if gap < d:
                    raise ValueError(f"network.min_separation_m: {a} and {b} start {gap:.3g} m apart, closer than "
                                     f"the separation {d:g} m")

    @property
    def stochastic(self) -> bool:
        """Whether the seed changes anything: the perturbations', log-normal shadowing, or the
        energy detector's noise when the relay estimates its jammers."""
        return self.perturbations.stochastic or self.channel.propagation.random or self.estimates_jammers

    @property
    def estimates_jammers(self) -> bool:
        """Whether the relay estimates the jammers online instead of being told (``localization``)."""
        return any(j.localization == "estimated" for j in self.jammer_configs)

    @property
    def control_period_s(self) -> float:
        rate = self.sim.control_rate_hz
        return self.controller.ts_s if rate is None else 1.0 / rate

    @property
    def duration_s(self) -> float:
        if self.sim.duration_s is not None:
            return self.sim.duration_s
        return max(s.mission.duration_s for s in self.source_list)  # every source's mission

    def to_toml(self, mission_file: str | None = None, source_files: dict[str, str] | None = None,
                jammer_files: dict[str, str] | None = None) -> str:
        """The resolved scenario as TOML text (every default spelled out), arrays on one line, with
        only the mission source that flies (no waypoints beside a CSV); ``mission_file`` replaces
        the CSV's path, ``source_files`` (source name -> file) each ``[[sources]]`` mission's,
        ``jammer_files`` (jammer name -> file) each jammer's track (a run folder holds its own copies). A setting that
        changes nothing here (``config.applies``: dormant since a ``--set`` switched what applies) is left out: the
        text says what flies, and loads again."""
        data = self._plain_data()
        for field, *_ in dormant(self):
            node: Any = data
            parts = dotted(field)
            for part in parts[:-1]:
                node = node[int(part)] if part.isdigit() else node.get(part, {})
            if isinstance(node, dict):
                node.pop(parts[-1], None)
        if "mission" in data:
            _only_what_flies(data["mission"], self.mission, mission_file)
        for cfg, m in zip(self.sources or [], data.get("sources", []), strict=True):
            _only_what_flies(m["mission"], cfg.mission, (source_files or {}).get(cfg.name))
        tables = data.get("jammers") or ([data["jammer"]] if "jammer" in data else [])
        for jam, t in zip(self.jammer_configs, tables, strict=True):
            if jam.track_field and jam.name in (jammer_files or {}):
                t[jam.track_field] = (jammer_files or {})[jam.name]
        return compact_toml(data)

    def _plain_data(self) -> dict:
        """``model_dump`` as a file would say it: a network file without ``nodes.relay`` and
        ``[mission]`` (its ``[[relays]]`` and ``[[sources]]`` say them), nor ``nodes.bs`` beside
        ``[[base_stations]]``, a one-relay file without a
        default ``[network]``."""
        data = self.model_dump(exclude_none=True)
        if self.relays is not None:
            data["nodes"].pop("relay", None)
        if self.sources is not None:
            data.pop("mission", None)
        if self.base_stations is not None:
            data["nodes"].pop("bs", None)
        if not self.names_its_fleet and self.network == NetworkConfig():
            data.pop("network", None)
        if not self.injected:  # said only by a run flown with parts passed from Python
            data.pop("injected", None)
        return data

    def with_updates(self, updates: dict) -> Scenario:
        """A new scenario with dotted-key updates, e.g. ``{"controller.variant": "unconstrained"}``,
        validated as data and by the load checks registered with ``after_validation`` (the physics
        checks of ``assembly.checks``)."""
        data = self._plain_data()
        if self.mission.flown_file and "mission.waypoints" in updates:  # waypoints given: they fly, not the file
            for f in ("trajectory_csv", "trajectory_ulog", "trajectory_plan", "trajectory_gpx"):
                data["mission"].pop(f, None)
        if any(k == "base_stations" or k.startswith("base_stations.") for k in updates):  # they replace nodes.bs
            data.get("nodes", {}).pop("bs", None)
        for key, value in updates.items():
            node: Any = data
            *parents, leaf = key.split(".")
            try:
                for p in parents:
                    node = node[int(p)] if isinstance(node, list) else node.setdefault(p, {})
                if isinstance(node, list):
                    node[int(leaf)] = value
                elif not isinstance(node, dict):
                    raise TypeError
                else:
                    node[leaf] = value
            except (TypeError, ValueError, IndexError, AttributeError):
                raise ScenarioError(f"{key}: not a field of the scenario (a table or list index is missing or out of range)") from None
        sc = validate_config(data)
        for check in _AFTER_VALIDATION:
            check(sc)
        return sc


_BOUND_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal"}


_AFTER_VALIDATION: list[Callable[[Scenario], object]] = []


def after_validation(check: Callable[[Scenario], object]) -> None:
    """Register a check that ``Scenario.with_updates`` runs on the scenario it returns (raising
    ScenarioError): the physics checks register themselves so (``assembly.checks``), and the data
    layer never imports them."""
    if check not in _AFTER_VALIDATION:
        _AFTER_VALIDATION.append(check)


def _only_what_flies(m: dict, cfg: MissionConfig, file: str | None) -> None:
    """A mission table as its file says it: no waypoints beside a CSV or ULog (``file`` replaces
    its path), no ULog frame fields without a ULog."""
    if cfg.flown_file:
        m.pop("waypoints", None)
        if file is not None:
            m[cfg.flown_field] = file
    if not cfg.trajectory_ulog:
        m.pop("ulog_yaw_deg", None)
        m.pop("ulog_offset_m", None)


def _merged(base: dict, override: dict) -> dict:
    """``base`` with ``override``'s values over it, tables merged key by key."""
    out = dict(base)
    for k, v in override.items():
        out[k] = _merged(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def geo_origin_to_missions(data: dict) -> None:
    """``[geo] origin`` (where the scenario's local frame sits, WGS84) for every mission that reads a
    geographic file (``trajectory_plan`` / ``trajectory_gpx``) without its own ``geo_origin``, and every jammer's."""
    geo = data.get("geo")
    origin = geo.get("origin") if isinstance(geo, dict) else None
    if origin is None:
        return
    given = data.get("sources")
    sources: list = given if isinstance(given, list) else []
    jammers = [data.get("jammer")] + (data["jammers"] if isinstance(data.get("jammers"), list) else [])
    for m in [data.get("mission"), *(s.get("mission") for s in sources if isinstance(s, dict)), *jammers]:
        if isinstance(m, dict) and (m.get("trajectory_plan") or m.get("trajectory_gpx")) and m.get("geo_origin") is None:
            m["geo_origin"] = origin


WGS84_SUFFIX = "_wgs84"


def _wgs84_fields(node, path: str = "") -> list[tuple[dict, str, str]]:
    """Every ``<field>_wgs84`` key in the raw data: (its table, the key, its dotted place)."""
    out: list[tuple[dict, str, str]] = []
    if isinstance(node, dict):
        for key, value in node.items():
            where = f"{path}.{key}" if path else str(key)
            if isinstance(key, str) and key.endswith(WGS84_SUFFIX):
                out.append((node, key, where))
            else:
                out += _wgs84_fields(value, where)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out += _wgs84_fields(value, f"{path}[{i}]")
    return out


def _geodetic_point(value, where: str) -> tuple[float, float, float]:
    if not (isinstance(value, list | tuple) and len(value) == 3 and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise ScenarioError(f"{where}: [lat_deg, lon_deg, alt_m] (WGS84, three finite numbers), got {value!r}")
    lat, lon, alt = (float(v) for v in value)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ScenarioError(f"{where}: latitude {lat:g} must be in [-90, 90] deg and longitude {lon:g} in [-180, 180] deg")
    return lat, lon, alt


def wgs84_to_local(data: dict) -> list[tuple[str, list]]:
    """Every position written as ``<field>_wgs84 = [lat_deg, lon_deg, alt_m]`` (or a list of such points, or of timed
    waypoints ``[t_s, lat_deg, lon_deg, alt_m]``) replaced, in
    ``data``, by ``<field>`` in the local frame (m, east-north-up at ``[geo] origin``: PROJ's exact ENU, as the
    geographic mission files; ``models.geo.GeoFrame``); returns each resolved field (dotted) with its local value.
    ScenarioError naming the field: no ``[geo] origin``, both forms given, not a point, out of range."""
    found = _wgs84_fields(data)
    if not found:
        return []
    geo = data.get("geo")
    origin = geo.get("origin") if isinstance(geo, dict) else None
    if origin is None:
        raise ScenarioError(f"{found[0][2]}: a WGS84 position needs [geo] origin = [lat_deg, lon_deg, alt_m] (where the "
                            "scenario's local frame sits)")
    frame = GeoFrame(_geodetic_point(origin, "geo.origin"))
    resolved = []
    for table, key, where in found:
        base = key[: -len(WGS84_SUFFIX)]
        place = where[: -len(WGS84_SUFFIX)]
        if base in table:
            raise ScenarioError(f"{where}: give {base} (local, m) or {key} (WGS84), not both")
        value = table.pop(key)
        one = isinstance(value, list | tuple) and len(value) == 3 and not isinstance(value[0], list | tuple)
        rows = [value] if one else value
        if not isinstance(rows, list | tuple) or not rows or not all(isinstance(r, list | tuple) for r in rows):
            raise ScenarioError(f"{where}: [lat_deg, lon_deg, alt_m], or a list of such points or of timed ones "
                                f"[t_s, lat_deg, lon_deg, alt_m], got {value!r}")
        timed = [len(r) == 4 for r in rows]
        if any(timed) and not all(timed):
            raise ScenarioError(f"{where}: every point timed [t_s, lat_deg, lon_deg, alt_m] or none")
        geodetic = np.array([_geodetic_point(list(r[1:]) if len(r) == 4 else r, where if one else f"{where}[{i}]")
                             for i, r in enumerate(rows)])
        enu = frame.to_local(geodetic[:, 0], geodetic[:, 1], geodetic[:, 2])
        local = [[*([float(r[0])] if len(r) == 4 else []), *(float(c) for c in p)] for r, p in zip(rows, enu, strict=True)]
        table[base] = local[0] if one else local
        resolved.append((place, table[base]))
    return resolved


def buildings_to_obstacles(sc: Scenario) -> tuple[list[dict], dict]:
    """``[buildings]``'s footprints as prism obstacles (``config.obstacles.BuildingsConfig``) and what was done (the
    file, its footprints, those kept and left out, the prisms). ScenarioError naming the field or the file."""
    b = sc.buildings
    assert b is not None
    if sc.geo is None:
        raise ScenarioError("buildings: a GeoJSON footprint file needs [geo] origin = [lat_deg, lon_deg, alt_m] (where "
                            "the scenario's local frame sits)")
    try:
        footprints = read_footprints(b.geojson, GeoFrame(sc.geo.origin), height_property=b.height_property,
                                     levels_property=b.levels_property, level_height_m=b.level_height_m,
                                     default_height_m=b.default_height_m)
    except BuildingsError as exc:
        raise ScenarioError(f"buildings.geojson: {exc}") from None
    if b.material is not None and not generated_scene(sc):  # as an obstacle's own material (the table is consumed here)
        raise ScenarioError(refusal("buildings.material", OBSTACLE[0].where, b.material, None))
    ws = sc.controller.workspace
    points = [ws.min, ws.max, *(s.position for s in sc.base_station_list), *(r.start for r in sc.relay_list),
              *(j.position for j in sc.jammer_configs)]
    xy = np.array([p[:2] for p in points], float)
    lo, hi = xy.min(axis=0) - b.reach_m, xy.max(axis=0) + b.reach_m
    ground = sc.world.ground_z_m
    obstacles, kept = [], 0
    parts = Counter(f.index for f in footprints)  # a MultiPolygon feature: one footprint per polygon, each named apart
    seen: Counter = Counter()
    for f in footprints:
        part = seen[f.index]
        seen[f.index] += 1
        corners = np.array(f.outline)
        if np.any(corners.max(axis=0) < lo) or np.any(corners.min(axis=0) > hi):
            continue
        kept += 1
        pieces = convex_pieces(f.outline)
        for k, piece in enumerate(pieces):
            name = f"building{f.index}" + (f"p{part}" if parts[f.index] > 1 else "") + (f"_{k}" if len(pieces) > 1 else "")
            obstacles.append({"name": name, "kind": "prism",
                              "footprint_m": [list(c) for c in piece], "z_min_m": ground, "z_max_m": ground + f.height_m,
                              "margin_m": b.margin_m, "nlos_loss_db": b.nlos_loss_db}
                             | ({"material": b.material} if b.material is not None else {}))
    own = len(sc.obstacles or [])
    if own + len(obstacles) > MAX_OBSTACLES:
        raise ScenarioError(f"buildings.geojson: {b.geojson}: {kept} footprints within reach_m = {b.reach_m:g} m make "
                            f"{len(obstacles)} convex prisms, with the file's {own} obstacles more than the "
                            f"{MAX_OBSTACLES} the NMPC keeps out of: lower buildings.reach_m or cut the file")
    summary = {"file": b.geojson, "footprints": len(footprints), "kept": kept, "left_out": len(footprints) - kept,
               "prisms": len(obstacles)}
    return obstacles, summary


def validate_config(data: dict) -> Scenario:
    """The scenario ``data`` validated as data (fields, ranges, cheap cross-field checks); raises
    ScenarioError with one line per problem. ``assembly.parse_scenario`` adds the physics checks. Positions written at
    lat/lon (``<field>_wgs84``) are resolved to the local frame first (``wgs84_to_local``), kept in
    ``Scenario.wgs84_resolved``."""
    resolved: list = []
    if isinstance(data, dict) and (isinstance(data.get("geo"), dict) or _wgs84_fields(data)):  # copied only when needed
        data = copy.deepcopy(data)
        resolved = wgs84_to_local(data)
        geo_origin_to_missions(data)
    try:
        sc = Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_errors(exc, Scenario)) from None
    buildings: dict | None = None
    if sc.buildings is not None:  # the footprints become prisms: the scenario holds them, not the file's name
        prisms, buildings = buildings_to_obstacles(sc)
        data = {k: v for k, v in data.items() if k != "buildings"}
        data["obstacles"] = list(data.get("obstacles") or []) + prisms
        try:
            sc = Scenario.model_validate(data)
        except ValidationError as exc:
            raise ScenarioError(f"with the buildings of {buildings['file']}: " + format_errors(exc, Scenario)) from None
    sc._wgs84_resolved = resolved
    sc._buildings_resolved = buildings
    return sc
