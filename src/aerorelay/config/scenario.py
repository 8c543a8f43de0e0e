"""The scenario as plain data: every table, the cheap cross-field checks (names, coincident nodes,
the relay's start in its workspace, whole plant steps per control period), TOML text, dotted-key
updates and the named error lines. What needs physics (hover, reachable alignment, propagation
geometry, the mission file against the ground) is checked in ``assembly.checks``.

Every field carries its unit in its name or docstring. Unknown fields are rejected. Defaults are
the paper's Table I values and the working spec's resolved choices (docs/concepts/spec.md), so an
empty ``[section]`` is valid.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pydantic import BaseModel, Field, ValidationError, model_validator

from .base import ScenarioError, Strict
from .controller import ControllerConfig
from .errors import format_errors
from .mission import MissionConfig
from .platform import PlatformConfig
from .radio import AntennaConfig, ChannelConfig, JammerConfig, NodesConfig
from .sections import BoundConfig, EstimationConfig, PerturbationConfig, SimConfig, WorldConfig
from .tomltext import compact_toml

MIN_NODE_SEPARATION_M = 0.1


def _numbered(jammer: Any, i: int) -> Any:
    """One of several ``[[jammers]]`` tables, named ``jammer<i+1>`` when it has no name."""
    if isinstance(jammer, dict) and "name" not in jammer:
        return {**jammer, "name": f"jammer{i + 1}"}
    if isinstance(jammer, BaseModel) and "name" not in jammer.model_fields_set:
        return jammer.model_copy(update={"name": f"jammer{i + 1}"})
    return jammer


class Scenario(Strict):
    """A complete, validated relay scenario."""

    name: str = Field("scenario", description="names the scenario in outputs and reports")
    description: str = Field("", description="free text, shown in reports")
    seed: int = Field(0, ge=0, description="seeds every random element (noise, fading, shadowing, the energy detector)")
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
        pts = {
            "nodes.bs": self.nodes.bs,
            "nodes.relay": self.nodes.relay,
            **{f"{self.jammer_field(i)}.position": j.position for i, j in enumerate(self.jammer_configs)},
            "mission.waypoints[0]": self.mission.start,
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
        ws = self.controller.workspace
        if not ws.contains(self.nodes.relay):
            raise ValueError(f"nodes.relay {self.nodes.relay} must lie inside controller.workspace [{ws.min}, {ws.max}]")
        steps = self.sim.plant_rate_hz * self.control_period_s
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise ValueError(
                f"the control period ({self.control_period_s} s) must be a whole number of plant steps "
                f"(sim.plant_rate_hz = {self.sim.plant_rate_hz})"
            )
        return self

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
        return self.sim.duration_s if self.sim.duration_s is not None else self.mission.duration_s

    def to_toml(self, mission_file: str | None = None) -> str:
        """The resolved scenario as TOML text (every default spelled out), arrays on one line, with
        only the mission source that flies (no waypoints beside a CSV); ``mission_file`` replaces
        the CSV's path (a run folder holds its own copy)."""
        data = self.model_dump(exclude_none=True)
        m = data["mission"]
        if self.mission.flown_file:
            m.pop("waypoints", None)
            if mission_file is not None:
                m["trajectory_ulog" if self.mission.trajectory_ulog else "trajectory_csv"] = mission_file
        if not self.mission.trajectory_ulog:
            m.pop("ulog_yaw_deg", None)
            m.pop("ulog_offset_m", None)
        return compact_toml(data)

    def with_updates(self, updates: dict) -> Scenario:
        """A new scenario with dotted-key updates, e.g. ``{"controller.variant": "unconstrained"}``,
        validated as data and by the load checks registered with ``after_validation`` (the physics
        checks of ``assembly.checks``)."""
        data = self.model_dump(exclude_none=True)
        if self.mission.flown_file and "mission.waypoints" in updates:  # waypoints given: they fly, not the file
            data["mission"].pop("trajectory_csv", None)
            data["mission"].pop("trajectory_ulog", None)
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


def validate_config(data: dict) -> Scenario:
    """The scenario ``data`` validated as data (fields, ranges, cheap cross-field checks); raises
    ScenarioError with one line per problem. ``assembly.parse_scenario`` adds the physics checks."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_errors(exc, Scenario)) from None
