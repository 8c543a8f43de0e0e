"""Fly a scenario: its parts (``build``), the closed loop, the metrics, optionally the bound; a
``RunResult`` with the time series and metrics that ``save`` writes as a run folder."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..control.nmpc import NmpcSettings
from ..models.jammer import Jammer
from ..models.radio import RadioScene
from ..planning.base import Planner
from ..planning.bound import CapacityBound
from ..sim.closed_loop import MissionResult, log_columns
from ..sim.metrics import compute_metrics
from ..store.run_folder import MISSION_CSV, MISSION_ULOG, log_frame, publish_run
from .build import build, scenario_bound
from .schema import Scenario, ScenarioError


@dataclass
class RunResult:
    """One flown mission: ``timeseries`` (one row per control step, the parquet's columns),
    ``metrics`` (as ``metrics.json``), the capacity ``bound`` when computed, the raw ``mission``."""

    scenario: Scenario
    mission: MissionResult
    timeseries: pd.DataFrame
    metrics: dict
    bound: CapacityBound | None = None

    def save(self, folder: str | Path, extra: Callable[[Path], None] | None = None) -> Path:
        """Write the run folder (scenario.toml, timeseries.parquet, metrics.json, bound files). It holds
        everything to fly the run again: a CSV mission is copied beside the scenario as
        ``mission.csv`` and named relative to it, so ``aerorelay run FOLDER/scenario.toml`` re-flies it."""
        m = self.scenario.mission
        copy = MISSION_ULOG if m.trajectory_ulog else MISSION_CSV if m.trajectory_csv else None

        def with_mission(tmp: Path) -> None:
            if copy is not None and m.flown_file is not None:
                shutil.copyfile(m.flown_file, tmp / copy)
            if extra is not None:
                extra(tmp)

        toml = self.scenario.to_toml(copy)
        publish_run(Path(folder), toml, self.timeseries, self.metrics, bound=self.bound, extra=with_mission)
        return Path(folder)


FIGURES_BYTES = 12_000_000  # the figures of one run (trajectory.html ~5.3 MB, PNGs)


def log_bytes(sc: Scenario) -> int:
    """Bytes the mission's per-step log takes in memory (8 per value)."""
    steps = int(sc.duration_s / sc.control_period_s) + 1
    n_rotors = sc.platform.rotor_count if sc.platform.rotors is None else len(sc.platform.rotors)
    return steps * len(log_columns(n_rotors)) * 8


def check_run_size(sc: Scenario) -> None:
    """A named error, before any work, when the log would not fit in half of this machine's memory."""
    need = log_bytes(sc)
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > total // 2:
        most = (total // 2) / need * sc.duration_s
        raise ScenarioError(f"sim.duration_s: {sc.duration_s:g} s needs {need / 1e9:.1f} GB for its log, more than half of "
                            f"this machine's {total / 1e9:.0f} GB; at most about {most:.0f} s here")


def run_metrics(sc: Scenario, mission: MissionResult, vehicle, bound: CapacityBound | None) -> dict:
    """``metrics.json`` of a mission (with its efficiency against the bound, when given)."""
    m = compute_metrics(mission.log, vehicle=vehicle, period_s=sc.control_period_s, outage_threshold=sc.channel.outage_threshold,
                        mu=sc.controller.mu, wall_s=mission.wall_s, sim_s=mission.sim_s,
                        workspace_min=sc.controller.workspace.min, workspace_max=sc.controller.workspace.max,
                        box_tolerance_m=sc.controller.failsafe.box_tolerance_m)
    m["controller"] = mission.controller
    m["fallback_episodes"] = mission.fallback_episodes
    if bound is not None:  # how far from what the physics allows (planning/bound.py)
        m["capacity_efficiency_mean"] = m["c_mean"] / float(bound.path_mean.mean())
        m["capacity_efficiency_min"] = m["c_min"] / float(bound.path_maxmin.min())
        # against the flyable path (exactly <= max_speed; a lower estimate of the best path)
        m["capacity_efficiency_mean_flyable"] = m["c_mean"] / float(bound.flyable_mean.mean())
        m["capacity_efficiency_min_flyable"] = m["c_min"] / float(bound.flyable_maxmin.min())
        m["bound"] = bound.summary()
    return m


def simulate(sc: Scenario, *, planner: Planner | None = None, scene: RadioScene | None = None,
             jammers: list[Jammer] | None = None, nmpc_settings: NmpcSettings | None = None, with_bound: bool = False,
             progress: Callable[[int, int], None] | None = None,
             bound_progress: Callable[[int, int], None] | None = None) -> RunResult:
    """Fly ``sc`` (parts given here replace the scenario's: a planner object, a radio scene, a
    list of jammers); ``with_bound``: also compute (or load) the capacity bound."""
    check_run_size(sc)
    parts = build(sc, planner=planner, scene=scene, jammers=jammers, nmpc_settings=nmpc_settings)
    mission = parts.closed_loop().run(progress)
    injected = parts.scene if (scene is not None or jammers is not None) else None
    bound = scenario_bound(sc, bound_progress, parts.vehicle, injected) if with_bound else None
    base = log_columns(parts.vehicle.n_rotors)  # then the random channel terms and the jammer estimate, when any
    df = log_frame(mission.log, base + [c for c in mission.log if c not in base])
    return RunResult(sc, mission, df, run_metrics(sc, mission, parts.vehicle, bound), bound)
