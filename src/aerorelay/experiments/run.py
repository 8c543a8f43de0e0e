"""Fly a scenario: its parts (``build``), the closed loop, the metrics, optionally the bound; a
``RunResult`` with the time series and metrics that ``save`` writes as a run folder."""

from __future__ import annotations

import logging
import math
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from pydantic import ValidationError

from ..assembly.c_engine import close_c_engines, install_c_engines
from ..assembly.parts import bound_of, build, build_scene, jammer_table
from ..assembly.world import obstacles as obstacle_shapes
from ..config import JammerConfig, Scenario, ScenarioError
from ..control.network import NetworkController
from ..control.nmpc import NmpcSettings
from ..models.jammer import Jammer
from ..models.radio import RadioScene
from ..planning.base import Planner
from ..planning.bound import CapacityBound
from ..planning.network_bound import NetworkBound
from ..sim.baseline import direct_rate
from ..sim.closed_loop import MissionResult
from ..sim.exit_status import ExitStatus, exit_fields
from ..sim.log_schema import RELAY_STEP, SOURCE_STATE, VEHICLE_STATE, column_type
from ..sim.metrics import compute_metrics, loss_phases
from ..sim.units import metric_units
from ..store.outputs import writing
from ..store.run_folder import MISSION_CSV, add_optional, log_frame, publish_run, write_bound_files
from ..store.strict_json import NULL_REASONS
from .budget import check_flight_time


@dataclass
class RunResult:
    """One flown mission: ``timeseries`` (one row per control step, the parquet's columns),
    ``metrics`` (as ``metrics.json``), the capacity ``bound`` when computed, the raw ``mission``;
    ``views`` writes the run's figures and MCAP into its folder (``ar.simulate`` attaches the
    report's writer; a campaign's runs have none)."""

    scenario: Scenario
    mission: MissionResult
    timeseries: pd.DataFrame
    metrics: dict
    bound: CapacityBound | NetworkBound | None = None
    views: Callable[[RunResult, Path], None] | None = field(default=None, repr=False)

    def save(self, folder: str | Path, extra: Callable[[Path], None] | None = None, *, figures: bool = True,
             wait: bool = False) -> Path:
        """Write the run folder. Its essentials first, published at once: scenario.toml,
        timeseries.parquet, metrics.json and, for a CSV or ULog mission, the file's copy beside the
        scenario (``mission.csv`` / ``mission.ulg``, named relative to it), so ``aerorelay run
        FOLDER/scenario.toml`` re-flies it. Then what is optional (the bound's files; the figures and
        MCAP with ``figures`` when ``views`` is set, and what ``extra`` writes), each on its own: one
        that fails is named in metrics.json (``optional_outputs_failed``) and logged, and the run
        stays. One writer per folder (``store.outputs.writing``: OutputBusyError, or ``wait``)."""
        m = self.scenario.mission
        copy = m.copy_name  # mission.csv / .ulg / .plan / .gpx: the run folder flies again from its own copy
        sources = {s.name: (s.mission.flown_file, f"mission_{s.name}{Path(s.mission.copy_name or MISSION_CSV).suffix}")
                   for s in self.scenario.sources or [] if s.mission.flown_file}  # a fleet's: one copy per source
        tracks = {j.name: (getattr(j, j.track_field), f"jammer_{j.name}{Path(getattr(j, j.track_field)).suffix}")
                  for j in self.scenario.jammer_configs if j.track_field}  # each jammer's track file

        def with_mission(tmp: Path) -> None:
            if copy is not None and m.flown_file is not None:
                shutil.copyfile(m.flown_file, tmp / copy)
            for src, name in (*sources.values(), *tracks.values()):
                shutil.copyfile(src, tmp / name)

        def views(tmp: Path) -> None:
            if figures and self.views is not None:
                self.views(self, tmp)
            if extra is not None:
                extra(tmp)

        toml = self.scenario.to_toml(copy, {n: name for n, (_, name) in sources.items()}, {n: name for n, (_, name) in tracks.items()})
        with writing(folder, wait=wait) as out:
            publish_run(out, toml, self.timeseries, self.metrics, extra=with_mission)
            optional: dict[str, Callable[[Path], object]] = {}
            if self.bound is not None:
                bound = self.bound
                optional["bound"] = lambda tmp: write_bound_files(bound, tmp)
            if extra is not None or (figures and self.views is not None):
                optional["figures"] = views
            add_optional(out, optional, self.metrics)
        return Path(folder)


FIGURES_BYTES = 12_000_000  # the figures of one run (trajectory.html ~5.3 MB, PNGs)

log = logging.getLogger(__name__)


def log_bytes(sc: Scenario) -> int:
    """Bytes the mission's per-step log takes in memory (8 per value): every relay's, source's, hop's
    and route's columns (``sim.log_schema``)."""
    steps = int(sc.duration_s / sc.control_period_s) + 1
    columns = 1 + 3 + 3 * len(sc.jammer_configs)
    for i in range(len(sc.relay_list)):
        p = sc.platform_of(i)
        columns += len(VEHICLE_STATE) + len(RELAY_STEP) + 2 * (p.rotor_count if p.rotors is None else len(p.rotors))
    columns += len(SOURCE_STATE) * len(sc.source_list) + sum(2 * (len(r) - 1) + 1 for r in sc.route_list)
    return steps * columns * 8


def output_bytes(sc: Scenario, *, figures: bool) -> int:
    """Bytes a run folder of ``sc`` needs at most on disk: the log (its in-memory size bounds the
    parquet), the copy of a CSV or ULog mission file, and the figures when written."""
    files = [sc.mission.flown_file] + [s.mission.flown_file for s in sc.sources or []]
    copy = sum(Path(f).stat().st_size for f in files if f and Path(f).is_file())
    return log_bytes(sc) + copy + (FIGURES_BYTES if figures else 0)


def check_run_size(sc: Scenario) -> None:
    """A named error, before any work, when the log would not fit in half of this machine's memory or the flight
    would take longer than ``sim.max_minutes`` (``experiments.budget.check_flight_time``)."""
    check_flight_time(sc)
    need = log_bytes(sc)
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > total // 2:
        most = (total // 2) / need * sc.duration_s
        raise ScenarioError(f"sim.duration_s: {sc.duration_s:g} s needs {need / 1e9:.1f} GB for its log, more than half of "
                            f"this machine's {total / 1e9:.0f} GB; at most about {most:.0f} s here")


def mark_aborted(m: dict, mission: MissionResult) -> None:
    """A mission that stopped before its end is unsafe whatever the steps flown show: ``aborted`` and the
    reason added to ``m``, its exit fields with its own status first (``exit_status`` of the loop or the
    flight: a non-finite plant state, or ended early), then the safety verdict's."""
    if mission.aborted is None:
        return
    m["aborted"], m["unsafe"] = mission.aborted, True
    m["unsafe_reason"] = "; ".join(r for r in (m["unsafe_reason"], f"aborted: {mission.aborted}") if r)
    first = ExitStatus(mission.exit_status) if mission.exit_status else ExitStatus.ENDED_EARLY
    m |= exit_fields([first, *(ExitStatus(v) for v in m.get("exit_statuses", []) if v != ExitStatus.COMPLETE.value)])


def failed_metrics(mission: MissionResult, exc: Exception) -> dict:
    """The metrics of a flight whose metrics could not be computed: its step count, and unsafe with why
    (its safety cannot be shown); the run folder still holds its time series."""
    why = f"its metrics could not be computed ({type(exc).__name__}: {exc}); its time series is kept"
    return {"steps": len(mission.log["t"]), "unsafe": True, "unsafe_reason": why, "metrics_failed": why,
            "controller": mission.controller, "aborted": mission.aborted, **exit_fields([ExitStatus.METRICS_FAILED])}


def relay_workspaces(sc: Scenario) -> dict[str, tuple[tuple, tuple, float]]:
    """Each relay's own workspace and box tolerance (its ``[relays.controller]``, else ``[controller]``'s), as its
    NMPC flies it and the verdict checks it."""
    out = {}
    for i, r in enumerate(sc.relay_list):
        c = sc.relay_view(i).controller
        out[r.name] = (tuple(c.workspace.min), tuple(c.workspace.max), c.failsafe.box_tolerance_m)
    return out


def run_metrics(sc: Scenario, mission: MissionResult, relays: dict, bound: CapacityBound | NetworkBound | None,
                scene: RadioScene | None = None) -> dict:
    """``metrics.json`` of a mission flown by ``relays`` (name -> vehicle) in ``scene`` (the truth: its jammers; None:
    the scenario's), with
    its efficiency against the bound when given (``single_efficiency``, ``network_efficiency``) and against the direct
    link with ``sim.baseline = "direct"`` (``direct_baseline``)."""
    m = compute_metrics(mission.log, relays=relays, sources=[s.name for s in sc.source_list], period_s=sc.control_period_s,
                        outage_threshold=sc.channel.outage, mu=sc.controller.mu, wall_s=mission.wall_s, sim_s=mission.sim_s,
                        min_separation_m=sc.separation_m, workspaces=relay_workspaces(sc), ground_z_m=sc.world.ground_z_m,
                        losses=sc.losses, obstacles=obstacle_shapes(sc, margin=False),
                        fallback_fraction_max=sc.verdict.fallback_fraction_max)
    m["controller"] = mission.controller
    m["fallback_episodes"] = mission.fallback_episodes
    for name, steps in mission.separation_unguarded.items():
        if name in m["relays"]:
            m["relays"][name]["separation_unguarded_steps"] = int(steps)
    m["separation_unguarded_steps"] = int(sum(mission.separation_unguarded.values()))  # the fleet's (sim.metrics.FLEET_SUM)
    mark_aborted(m, mission)
    if sc.sim.baseline == "direct":
        direct_baseline(m, direct_rate(scene or build_scene(sc), mission.log))
    if isinstance(bound, NetworkBound):
        network_efficiency(m, bound)
    elif bound is not None:
        single_efficiency(m, bound)
    return m


def direct_baseline(m: dict, direct: np.ndarray) -> None:
    """The direct link's rate at every step (``sim.baseline``): its minimum and mean (``c_min_direct``,
    ``c_mean_direct``) and the run's over them (``c_min_over_direct``, ``c_mean_over_direct``; None with the reason
    where the direct link's is 0: a jammer on the base station)."""
    m["c_min_direct"], m["c_mean_direct"] = float(direct.min()), float(direct.mean())
    reasons = {}
    for key, num, den, what in (("c_min_over_direct", m["c_min"], m["c_min_direct"], "the direct link's minimum"),
                                ("c_mean_over_direct", m["c_mean"], m["c_mean_direct"], "the direct link's mean")):
        m[key], why = efficiency(num, den, what)
        if why:
            reasons[key] = why
    if reasons:
        m[NULL_REASONS] = {**m.get(NULL_REASONS, {}), **reasons}


def single_efficiency(m: dict, bound: CapacityBound) -> None:
    """One relay's efficiency against its capacity bound (``planning/bound.py``): against the best path's
    (``capacity_efficiency_*``, the studies' keys), the flyable path's, and one key per denominator."""
    add_efficiencies(m, bound.summary(), (
        ("capacity_efficiency_mean", m["c_mean"], bound.path_mean.mean(), "the best-mean path's mean"),
        ("capacity_efficiency_min", m["c_min"], bound.path_maxmin.min(), "the best-minimum path's minimum"),
        # against the flyable path (exactly <= max_speed; a lower estimate of the best path)
        ("capacity_efficiency_mean_flyable", m["c_mean"], bound.flyable_mean.mean(), "the flyable mean path's mean"),
        ("capacity_efficiency_min_flyable", m["c_min"], bound.flyable_maxmin.min(), "the flyable max-min path's minimum"),
        # one name per denominator, the same for every fleet size (the legacy keys above keep the studies reading)
        *efficiency_rows(m, "path", bound.path_mean.mean(), bound.path_maxmin.min(), "the best path's"),
        *efficiency_rows(m, "static", bound.static.mean(), bound.static.min(), "the static bound's"),
        *efficiency_rows(m, "flyable", bound.flyable_mean.mean(), bound.flyable_maxmin.min(), "the flyable path's")))


def efficiency_rows(m: dict, bound_name: str, best_mean: float, best_min: float, what: str) -> list[tuple]:
    """``efficiency_mean_vs_<bound>`` and ``efficiency_min_vs_<bound>``: the run's mean and minimum rate
    over that bound's mean and minimum (one key per denominator, for one relay and for fleets)."""
    return [(f"efficiency_mean_vs_{bound_name}", m["c_mean"], best_mean, f"{what} mean"),
            (f"efficiency_min_vs_{bound_name}", m["c_min"], best_min, f"{what} minimum")]


def add_efficiencies(m: dict, summary: dict, rows) -> None:
    """Each ``(key, value, best, what)`` of ``rows`` as ``m[key] = value / best`` (None, with its reason
    under ``null_reasons``, when undefined: ``efficiency``); the bound's ``summary`` under ``bound``."""
    reasons: dict[str, str] = {}
    for key, num, den, what in rows:
        m[key], why = efficiency(num, float(den), what)
        if why:
            reasons[key] = why
    m["bound"] = summary
    if reasons:
        m[NULL_REASONS] = {**m.get(NULL_REASONS, {}), **reasons}


def network_efficiency(m: dict, bound: NetworkBound) -> None:
    """A fleet's efficiency against its network bound: the run's mean and minimum rate over the static
    upper bound's (``capacity_efficiency_*``), over the refined configuration's (``*_achieved``) and
    over the flyable fleet path's (``*_flyable``, without losses) and over the upper path bound's mean
    (``capacity_efficiency_mean_path``, ``efficiency_mean_vs_path``, without losses);
    with relays lost, before the first loss and from the last on, against the bound of the fleet
    flying then (``*_before_loss``, ``*_after_loss``)."""
    rows = [("capacity_efficiency_mean", m["c_mean"], bound.static.mean(), "the static bound's mean"),
            ("capacity_efficiency_min", m["c_min"], bound.static.min(), "the static bound's minimum"),
            ("capacity_efficiency_mean_achieved", m["c_mean"], bound.achieved.mean(), "the refined configuration's mean"),
            ("capacity_efficiency_min_achieved", m["c_min"], bound.achieved.min(), "the refined configuration's minimum")]
    rows += [*efficiency_rows(m, "static", bound.static.mean(), bound.static.min(), "the static bound's"),
             *efficiency_rows(m, "achieved", bound.achieved.mean(), bound.achieved.min(), "the refined configuration's")]
    losses, summary = m.get("losses", []), bound.summary()
    if "flyable" in summary and not losses:  # against the flyable fleet path (a lower estimate of the best path)
        rows += [("capacity_efficiency_mean_flyable", m["c_mean"], summary["flyable"]["mean"], "the flyable fleet path's mean"),
                 ("capacity_efficiency_min_flyable", m["c_min"], summary["flyable"]["min"], "the flyable fleet path's minimum"),
                 *efficiency_rows(m, "flyable", summary["flyable"]["mean"], summary["flyable"]["min"], "the flyable fleet path's")]
    if "path_mean" in summary and not losses:  # against the upper path bound (no flyable fleet beats its mean)
        rows += [("capacity_efficiency_mean_path", m["c_mean"], summary["path_mean"]["mean"], "the upper path bound's mean"),
                 ("efficiency_mean_vs_path", m["c_mean"], summary["path_mean"]["mean"], "the upper path bound's mean")]
    if losses:
        for label, part in loss_phases(bound.t, [loss["t_s"] for loss in losses]).items():
            if f"c_mean_{label}" in m and part.any():
                summary[f"static_{label}"] = {"mean": float(bound.static[part].mean()), "min": float(bound.static[part].min())}
                rows += [(f"capacity_efficiency_mean_{label}", m[f"c_mean_{label}"], bound.static[part].mean(),
                          f"the static bound's mean {label.replace('_', ' ')}"),
                         (f"capacity_efficiency_min_{label}", m[f"c_min_{label}"], bound.static[part].min(),
                          f"the static bound's minimum {label.replace('_', ' ')}")]
    add_efficiencies(m, summary, rows)


def efficiency(value: float, best: float, what: str) -> tuple[float | None, str | None]:
    """``value / best``, or None with the reason when the ratio is undefined (``best`` zero, negative
    or not finite: e.g. a jammer over the base station for a moment makes the best minimum 0)."""
    if not (math.isfinite(best) and best > 0.0 and math.isfinite(value)):
        return None, f"undefined: {what} is {best:g} (the run's value {value:g})"
    return value / best, None


def simulate(sc: Scenario, *, planner: Planner | None = None, scene: RadioScene | None = None,
             jammers: list[Jammer] | None = None, nmpc_settings: NmpcSettings | None = None, with_bound: bool = False,
             progress: Callable[[int, int], None] | None = None,
             bound_progress: Callable[[int, int], None] | None = None,
             views: Callable[[RunResult, Path], None] | None = None,
             install: Callable[[NetworkController], None] | None = None) -> RunResult:
    """Fly ``sc`` (parts given here replace the scenario's: a planner object, a radio scene, a
    list of jammers); ``with_bound``: also compute (or load) the capacity bound; ``views``: what writes
    the figures and MCAP when the result is saved; ``install``: given the network's controller before the flight (a
    relay's step backend: ``control.relay_step.StepBackend``, e.g. ``aerorelay codegen``'s recorder or C flight). ``sc`` is validated
    again first (a field changed after loading must pass every cross-field check too; the parts'
    own checks, e.g. an ``inr_db_at_relay_start`` jammer in a null, raise when ``build`` makes them)."""
    sc.with_updates({})  # validated as data and with physics again (the parts' own checks raise when built)
    check_run_size(sc)
    given = {k: v for k, v in (("planner", planner), ("scene", scene), ("jammers", jammers)) if v is not None}
    check_not_injected(sc, given)
    said = jammers_said(sc, jammers) if jammers is not None and scene is None else None
    if said is not None:  # the jammers as [[jammers]] tables: the run folder's scenario.toml flies them again
        sc, jammers = said, None
        given.pop("jammers")
    parts = build(sc, planner=planner, scene=scene, jammers=jammers, nmpc_settings=nmpc_settings)
    injected = parts.scene if (scene is not None or jammers is not None) else None
    # the bound before the flight: a bound that fails then costs no flight (cached per geometry)
    bound: CapacityBound | NetworkBound | None = None
    if with_bound:
        bound = bound_of(sc, bound_progress, scene=injected)
    loop = parts.closed_loop()
    engines = install_c_engines(sc, loop.control)  # relays flying their C library (controller.backend = "c")
    if install is not None:
        install(loop.control)
    try:
        mission = loop.run(progress)
    finally:
        close_c_engines(loop.control, engines)
    df = log_frame(mission.log, loop.columns + [c for c in mission.log if c not in loop.columns],
                   {c: column_type(c) for c in mission.log if column_type(c) is not float})
    try:
        metrics = run_metrics(sc, mission, {r.name: r.vehicle for r in parts.relays}, bound, parts.scene)
    except Exception as exc:  # nothing computed after a flight may lose it: the time series is kept, the run unsafe
        log.exception("the run's metrics failed; its time series is kept")
        metrics = failed_metrics(mission, exc)
    metrics |= loop.control.check.metrics()  # every planner's references: how often clipped or held, and why first
    for name, relay in metrics.get("relays", {}).items():
        relay |= loop.control.check.relay_metrics(name)
    if sc.obstacles:  # how often a reference was moved out of an obstacle's margin (every planner: planning.keep_out)
        metrics["reference_kept_out_steps"] = loop.control.kept_out_steps
    metrics["outage_threshold"] = sc.channel.outage  # the resolved threshold, in the capacity's unit
    metrics["unit_system"] = sc.channel.units
    if given:  # what the scenario file cannot say: named in it and in the metrics, so the folder does not fly another run
        metrics["injected"] = injected_parts(given)
        sc = sc.model_copy(update={"injected": metrics["injected"]})
    try:
        metrics["units"] = metric_units(metrics, sc.channel.capacity_unit)
    except KeyError as exc:  # a metric without a unit must not lose the flight either
        log.exception("the run's metrics have no unit table; its time series is kept")
        metrics |= failed_metrics(mission, exc) | {"units": {}}
    return RunResult(sc, mission, df, metrics, bound, views)


def jammers_said(sc: Scenario, jammers: list[Jammer]) -> Scenario | None:
    """``sc`` with ``jammers`` (objects passed from Python) as its ``[[jammers]]`` tables (``jammer_table``; each
    keeps the scenario's ``localization``), validated; None when a table cannot say one of them (they are then
    named as injected)."""
    tables = [jammer_table(j) for j in jammers]
    if not tables or any(t is None for t in tables):
        return None
    localization = sc.jammer_configs[0].localization if sc.jammer_configs else "oracle"
    try:
        configs = [JammerConfig(**(t | {"localization": localization})) for t in tables if t is not None]
        out = sc.model_copy(update={"jammer": None, "jammers": configs})
        out.with_updates({})  # every cross-field check, as a file would get
    except (ValidationError, ScenarioError):
        return None
    return out


def injected_parts(given: dict) -> list[str]:
    """What parts passed from Python were (``planner: MidpointPlanner``, ``jammers: j1, j2``, ``scene: ...``)."""
    out = []
    for kind, part in given.items():
        if kind == "jammers":
            out.append("jammers: " + ", ".join(j.name for j in part))
        elif kind == "scene":
            out.append(f"scene: a RadioScene with nodes {', '.join(n.name for n in part.nodes)} and jammers "
                       f"{', '.join(j.name for j in part.jammers) or 'none'}")
        else:
            out.append(f"{kind}: {type(part).__name__}")
    return out


def check_not_injected(sc: Scenario, given: dict | None = None) -> None:
    """A scenario written by a run flown with parts passed from Python (``injected``) does not fly again
    from its file alone: a named error unless parts are given again."""
    if sc.injected and not given:
        raise ScenarioError(f"injected: this scenario was flown with parts passed from Python ({'; '.join(sc.injected)}) that "
                            "its file cannot say; flying the file alone would fly another run: pass them again "
                            "(ar.simulate(sc, planner=..., scene=..., jammers=...)) or remove the injected field")
