"""Settings that apply only in some scenarios, in one table (as acados' ``make_consistent``): a setting given a
value other than its default where it does not apply is refused by name, with where it would apply, instead of
being accepted and changing nothing (``assembly.load``: a file, or a ``--set``, that says it; a setting of the file
made dormant by a ``--set`` that switches what applies, e.g. a ray-traced file flown with ``--set
channel.propagation.model=free_space``, is named in a warning instead). A default is never refused, so a fully
resolved file (``aerorelay validate``, a run folder's ``scenario.toml``) loads again. Measured before this table
(2026-12-06, the schema audit of ``tests/reliability/test_no_dead_setting.py`` with the platform's fields): 44 of the
nominal preset's 95 section fields and 44 of the chain's 94 accepted a changed value and built the same parts; after
it, ``AERORELAY_AUDIT=1`` finds none outside its reviewed list (the platform's fields are not in it: they rebuild the
NMPC, 2-4 s each)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel


@dataclass(frozen=True)
class Applies:
    """``fields`` of a section apply where ``when(section, scenario)``; ``where`` says it (for the refusal)."""

    fields: tuple[str, ...]
    when: Callable[[Any, Any], bool]
    where: str


CHANNEL = (
    Applies(("bandwidth", "tx_power_w", "noise_power_w"), lambda c, sc: c.units == "normalized", "channel.units = 'normalized'"),
    Applies(("bandwidth_hz", "tx_power_dbm", "noise_figure_db", "temperature_k"), lambda c, sc: c.units == "physical",
            "channel.units = 'physical'"),
)
PROPAGATION = (
    Applies(("origin_m", "yaw_deg", "max_depth", "rays_per_source", "reflection", "diffraction", "scattering", "refraction",
             "paths_sum", "trace_period_s"), lambda p, sc: p.model == "ray_traced", "channel.propagation.model = 'ray_traced'"),
    Applies(("exponent", "reference_distance_m", "reference_loss_db"), lambda p, sc: p.model == "log_distance",
            "channel.propagation.model = 'log_distance'"),
    Applies(("building_material", "wall_thickness_m", "ground_material"), lambda p, sc: generated_scene(sc),
            "channel.propagation.model = 'ray_traced' with scene = 'obstacles'"),
)
OBSTACLE = (
    Applies(("material",), lambda o, sc: generated_scene(sc), "channel.propagation.model = 'ray_traced' with scene = "
            "'obstacles'"),
)


def generated_scene(sc) -> bool:
    """Whether the radio is traced in the scene generated from the obstacles."""
    p = sc.channel.propagation
    return p.model == "ray_traced" and p.scene == "obstacles"

ANTENNA = (
    Applies(("exponent",), lambda a, sc: a.pattern == "sin_power", "antenna.pattern = 'sin_power'"),
    Applies(("bs_g_max", "bs_exponent", "bs_back_lobe", "bs_tilt_deg", "bs_azimuth_deg"), lambda a, sc: a.bs_pattern == "cosine",
            "antenna.bs_pattern = 'cosine'"),
    Applies(("bs_axis",), lambda a, sc: a.bs_pattern != "cosine", "antenna.bs_pattern 'dipole' or 'isotropic' (a cosine "
            "base station points by bs_tilt_deg and bs_azimuth_deg)"),
)
JAMMER = (
    Applies(("path",), lambda j, sc: j.waypoints is not None or j.path == "circle", "it has waypoints (how it moves between "
            "them) or path = 'circle'"),
    Applies(("repeat",), lambda j, sc: j.waypoints is not None, "it has waypoints"),
    Applies(("center_m", "radius_m", "period_s", "clockwise"), lambda j, sc: j.path == "circle", "its path = 'circle'"),
    Applies(("on_s", "off_s"), lambda j, sc: j.schedule == "on_off", "its schedule = 'on_off'"),
    Applies(("localization_delay_s",), lambda j, sc: j.localization != "estimated", "its localization = 'oracle' (an "
            "estimated jammer is known when the estimator finds it)"),
    Applies(("power_w",), lambda j, sc: j.inr_db_at_relay_start is None and j.power_dbm is None,
            "neither power_dbm nor inr_db_at_relay_start sets its power"),
    Applies(("g_max", "exponent", "back_lobe", "point_at", "boresight"), lambda j, sc: j.pattern == "cosine",
            "its pattern = 'cosine'"),
)
ESTIMATION = (
    Applies(("*",), lambda e, sc: sc.estimates_jammers, "a jammer's localization = 'estimated'"),
)
BOUND = (
    Applies(("global_seconds", "global_gap", "branch_pairs", "branch_levels"), lambda b, sc: sc.shape.bound == "network"
            and sc.channel.propagation.model != "ray_traced", "a network's bound (more than one relay or route) on a "
            "channel that is not ray traced (one relay's bound is exact already; SCIP cannot trace rays, and the traced "
            "network bound does not branch)"),
    Applies(("global_gap",), lambda b, sc: b.global_seconds > 0, "bound.global_seconds > 0"),
)
GENERATORS = ("trajectory_generator", "isotropic")  # the paper's generator (baseline A: with mu = 1)
CONTROLLER = (
    Applies(("*",), lambda c, sc: bool(sc.relay_list), "the scenario has a relay (the controller flies relays; the direct "
            "link, relays = [], has none)"),
    Applies(("hessian_eig_floor", "hessian_floor"), lambda c, sc: sc.planner in GENERATORS,
            "controller.planner is the paper's generator ('trajectory_generator' or 'isotropic')"),
)
NETWORK = (
    Applies(("separation_neighbours",), lambda n, sc: sc.vehicle_count - 1 > n.separation_neighbours,
            "a relay has more other vehicles (relays and sources) than network.separation_neighbours"),
    Applies(("self_interference_db",), lambda n, sc: n.schedule == "full_duplex", "network.schedule = 'full_duplex'"),
)
WIND = (
    Applies(("gust_w20_m_s",), lambda w, sc: w.gusts, "wind.gusts = true (it sets the gusts' intensity)"),
)
MISSION = (
    Applies(("ulog_yaw_deg", "ulog_offset_m"), lambda m, sc: m.trajectory_ulog is not None, "a trajectory_ulog mission"),
)


def _sections(sc) -> Iterator[tuple[str, BaseModel, tuple[Applies, ...]]]:
    """Every section the table covers, with the field path a refusal names."""
    yield "channel", sc.channel, CHANNEL
    yield "channel.propagation", sc.channel.propagation, PROPAGATION
    yield "antenna", sc.antenna, ANTENNA
    for i, j in enumerate(sc.jammer_configs):
        yield sc.jammer_field(i), j, JAMMER
    yield "estimation", sc.estimation, ESTIMATION
    yield "bound", sc.bound, BOUND
    yield "controller", sc.controller, CONTROLLER
    yield "network", sc.network, NETWORK
    if sc.wind is not None:
        yield "wind", sc.wind, WIND
    for i, o in enumerate(sc.obstacles or []):
        yield f"obstacles[{i}]", o, OBSTACLE
    if sc.sources is None:
        yield "mission", sc.mission, MISSION
    for i, s in enumerate(sc.sources or []):
        yield f"sources[{i}].mission", s.mission, MISSION


def dormant(sc) -> list[tuple[str, str, Any, Any]]:
    """Every setting given a value other than its default where it does not apply: ``(field, where it would apply,
    value, default)``, the field as a refusal names it (``jammers[0].on_s``)."""
    out = []
    for path, section, table in _sections(sc):
        given = section.model_fields_set
        fields = type(section).model_fields
        for rule in table:
            if rule.when(section, sc):
                continue
            for name in (fields if rule.fields == ("*",) else rule.fields):
                if name in given:
                    value, default = getattr(section, name), fields[name].get_default(call_default_factory=True)
                    if value != default:
                        out.append((f"{path}.{name}", rule.where, value, default))
    return out


def dotted(field: str) -> list[str]:
    """A field as ``dormant`` names it (``jammers[0].on_s``) as dotted-key parts (``["jammers", "0", "on_s"]``)."""
    return field.replace("[", ".").replace("]", "").split(".")


def refusal(field: str, where: str, value: Any, default: Any) -> str:
    return (f"{field}: applies only where {where}; here it changes nothing (got {value!r}; its default {default!r}): "
            "remove it, or set what it needs")
