"""The record of a flight flown outside aerorelay's plant (``aerorelay fly``: a MAVLink autopilot,
the in-repo vehicle, RotorPy): one log row per control period in OFFBOARD, with the columns of
``aerorelay run``'s time series, so the same metrics, figures and MCAP come out of it.

A row holds what the relay's telemetry reported (position, velocity, attitude, body rates; the
rotor speeds are the ones commanded, which autopilots do not report), the source where the relay
knew it, the planner's reference and the NMPC's step, and the link **as the scene's model gives it
at the flown poses** (the relay's measured attitude tilts its antenna): no radio was measured. Steps
the stale-input failsafe flew (``hold``, ``land``) carry its target as the reference, no QP
(``qp_status`` is the mode) and zero rotor rates. Flight columns: ``flight_mode`` (nmpc, fallback,
hold, land), ``compute_ms`` (the step's computation, ms), ``deadline_met``, ``state_age_s`` (how old
the relay's state was, s); with the observer, ``a_ext_x/y/z`` (its estimate, m/s^2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..control.network import route_neighbours
from ..control.nmpc import StepInfo
from ..control.relay_step import Command
from ..control.relay_step import SourceState as KnownSource
from ..models.geometry import rotation_zyx
from ..models.mission import SourceState
from ..models.radio import RadioScene
from ..models.state import ETA, P
from ..models.vehicle import Multirotor
from ..planning.base import Reference
from .air import AXES
from .closed_loop import MissionResult
from .log_schema import column_type, gone_row, link_row, log_columns, relay_row, separation_min, source_row

FLIGHT_COLUMNS = ("flight_mode", "compute_ms", "deadline_met", "state_age_s")
FLIGHT_COLUMN_TYPES: dict[str, type] = {"flight_mode": str, "deadline_met": bool}


def flight_column_type(name: str) -> type:
    """A flight record's column's type: the flight's own columns', else the run log's (``sim.log_schema``)."""
    return FLIGHT_COLUMN_TYPES.get(name, column_type(name))


class FlightRecorder:
    """Collects a flight's rows (``record`` each control period in OFFBOARD); ``mission`` returns them
    as a ``MissionResult`` like ``ar.simulate``'s. ``vehicles``: every relay flown by name (one relay: the
    scene's relay); ``observed``: the NMPCs have an external-force observer. A row is every relay's."""

    def __init__(self, vehicles: Mapping[str, Multirotor], scene: RadioScene, *, observed: bool = False):
        self.vehicles, self.scene, self.observed = dict(vehicles), scene, observed
        self.relays = list(self.vehicles)
        self.relay = self.relays[0]  # the first relay (the one relay's)
        self.sources = [n.name for n in scene.nodes if n.role == "source"]
        self.neighbours = route_neighbours(scene)  # each relay's, while every relay is in the network
        self.source = self.sources[0]
        self._fixed = {n.name: scene.fixed_pose(n.name).position for n in scene.nodes if n.position is not None}
        self.observer_columns = {r: [f"{r}.a_ext_{a}" for a in AXES] for r in self.relays}  # as sim/air.py logs them
        self.columns = (log_columns({r: v.n_rotors for r, v in self.vehicles.items()}, self.sources, scene)
                        + list(FLIGHT_COLUMNS) + ([c for r in self.relays for c in self.observer_columns[r]] if observed else []))
        self.rows: list[dict] = []

    def record(self, t: float, xs: Mapping[str, np.ndarray], cmds: Mapping[str, Command],
                       sources: Mapping[str, KnownSource], *, state_age_s: float, violations: Mapping[str, bool],
                       a_ext: Mapping[str, np.ndarray | None] | None = None) -> None:
        """Step ``t`` of every relay (``xs``, ``cmds`` by name) and every source as the network knew it; the
        oldest relay state's age (s). ``flight_mode`` is the first relay's whose command was not flown by
        its NMPC, else ``nmpc`` (or ``fallback``); ``compute_ms`` the step's longest, ``deadline_met`` all."""
        src = {n: SourceState(np.asarray(s.p, float), np.asarray(s.v, float), np.asarray(s.a, float)) for n, s in sources.items()}
        eta_src = {n: s.attitude(self.vehicles[self.relay].gravity) for n, s in src.items()}
        flying = [r for r in self.relays if r in xs]
        left = [r for r in self.relays if r not in xs]  # a relay without a state has left the network
        scene = self.scene.without(left) if left else self.scene
        R = {r: rotation_zyx(xs[r][ETA]) for r in flying}
        poses = {r: scene.pose(r, xs[r][P], R[r]) for r in flying}
        poses |= {n: scene.pose(n, s.p, rotation_zyx(eta_src[n])) for n, s in src.items()}
        channel = scene.evaluate(t, poses)
        where = {**self._fixed, **{n: s.p for n, s in src.items()}, **{r: xs[r][P] for r in flying}}
        row: dict[str, object] = {"t": t}
        neighbours = route_neighbours(scene) if left else self.neighbours
        for r in self.relays:
            if r not in xs:
                row |= gone_row(r, self.vehicles[r].n_rotors)
                continue
            cmd = cmds[r]
            ref, info = cmd.reference, cmd.info
            if ref is None or info is None:  # the failsafe flew: its target is the reference, no QP
                ref = Reference(p_opt=cmd.position_m, p_ref=cmd.position_m, v_ref=cmd.velocity_m_s, a_ref=cmd.acceleration_m_s2)
                info = StepInfo(u=np.zeros(self.vehicles[r].n_rotors), ok=True, status=cmd.mode, prep_ms=0.0,
                                feedback_ms=cmd.compute_ms, slack_max=0.0)
            up, down = neighbours[r]
            row |= relay_row(r, xs[r], R[r], info, ref, where[up], where[down], violations[r] and cmd.mode in ("nmpc", "fallback"))
        for n in self.sources:
            row |= source_row(n, src[n].p, eta_src[n])
        row |= dict.fromkeys((c for c in self.columns if c.startswith(("sinr.", "se.", "capacity."))), math.nan)
        row |= link_row(scene, t, channel)
        self.columns += [c for c in row if c not in self.columns and c.startswith(("sinr.", "se.", "capacity."))]  # a hop taken
        # after a relay left the network
        row["separation_min"] = separation_min(np.array([*(xs[r][P] for r in flying), *(src[n].p for n in self.sources)]))
        modes = [cmds[r].mode for r in flying]
        row |= {"flight_mode": next((m for m in modes if m not in ("nmpc", "fallback")), modes[0]),
                "compute_ms": max(cmds[r].compute_ms for r in flying),
                "deadline_met": all(cmds[r].deadline_met for r in flying), "state_age_s": state_age_s}
        if self.observed:
            for r in flying:
                given = None if a_ext is None else a_ext.get(r)
                row |= dict(zip(self.observer_columns[r], np.zeros(3) if given is None else given, strict=True))
        if not self.rows and set(row) != set(self.columns):
            raise ValueError(f"flight record: columns {sorted(set(self.columns) ^ set(row))} not both declared and recorded")
        self.rows.append(row)

    def mission(self, wall_s: float, *, controller: str = "", fallback_episodes: int = 0,
                aborted: str | None = None) -> MissionResult:
        """The rows as a ``MissionResult`` (``sim_s`` the mission time flown). Raises ValueError when
        nothing was flown in OFFBOARD."""
        if not self.rows:
            raise ValueError("flight record: no control period was flown in OFFBOARD")
        log = {c: _column([r.get(c, math.nan) for r in self.rows], flight_column_type(c)) for c in self.columns}
        failures = sum(int(np.sum(~log[f"{r}.qp_ok"])) for r in self.relays)
        return MissionResult(log=log, wall_s=wall_s, sim_s=float(log["t"][-1] - log["t"][0]), qp_failures=failures,
                             controller=controller, fallback_episodes=fallback_episodes, aborted=aborted)


def _column(values: list, kind: type) -> np.ndarray:
    return np.array(values, dtype=object if kind is str else kind)


NOT_MISSION_MODES = ("stream", "wait", "ended")  # a bridge log's periods before the mission, waiting, after a relay left


def flight_metrics(log: dict, bridge_log=None) -> dict:
    """A flight's own metrics: the share of control periods the stale-input failsafe held or landed, the share that
    missed their deadline, the step's computation time (ms) and the relay state's age (s). The held and landed shares
    come from the bridge's log when there is one (``flight.parquet``: one row per relay and period, its mode, over each
    relay's mission periods, not streaming, waiting or ended): a held vehicle's periods are flown by its autopilot, not
    recorded as the controller's rows, and counting those rows alone read 191 held periods of 324 as 0; else from
    the controller's rows (a flight stepped without a bridge)."""
    mode = np.asarray(log["flight_mode"], dtype=object)
    ms = np.asarray(log["compute_ms"], float)
    age = np.asarray(log["state_age_s"], float)
    if bridge_log is not None and "mode" in bridge_log and len(bridge_log):
        bridge = bridge_log["mode"].astype(str).to_numpy()
        in_mission = ~np.isin(bridge, NOT_MISSION_MODES)
        if in_mission.any():
            mode = bridge[in_mission]
    return {"hold_fraction": float(np.mean(mode == "hold")), "land_fraction": float(np.mean(mode == "land")),
            "deadline_missed_fraction": float(np.mean(~np.asarray(log["deadline_met"], bool))),
            "compute_ms": {"mean": float(ms.mean()), "p99": float(np.percentile(ms, 99)), "max": float(ms.max())},
            "state_age_max_s": float(age.max())}


def telemetry_metrics(bridge_log) -> dict:
    """From a bridge's log (one row per period with the reason its telemetry was not trusted, empty
    when it was): ``telemetry_rejected_periods`` and the first ``telemetry_rejected_reason`` (none: "")."""
    if bridge_log is None or "rejected" not in bridge_log:
        return {}
    why = [r for r in bridge_log["rejected"].fillna("") if r]
    return {"telemetry_rejected_periods": len(why), "telemetry_rejected_reason": why[0] if why else ""}
