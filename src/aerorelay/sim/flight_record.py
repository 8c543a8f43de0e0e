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

import numpy as np

from ..control.nmpc import StepInfo
from ..flight.stepper import Command
from ..flight.stepper import SourceState as KnownSource
from ..models.geometry import rotation_zyx
from ..models.mission import SourceState
from ..models.radio import RadioScene
from ..models.vehicle import Multirotor
from ..planning.base import Reference
from .air import AXES
from .closed_loop import MissionResult
from .log_schema import column_type, link_row, log_columns, relay_row, separation_min, source_row

FLIGHT_COLUMNS = ("flight_mode", "compute_ms", "deadline_met", "state_age_s")
FLIGHT_COLUMN_TYPES: dict[str, type] = {"flight_mode": str, "deadline_met": bool}


def flight_column_type(name: str) -> type:
    """A flight record's column's type: the flight's own columns', else the run log's (``sim.log_schema``)."""
    return FLIGHT_COLUMN_TYPES.get(name, column_type(name))


class FlightRecorder:
    """Collects a flight's rows (``record`` each control period in OFFBOARD); ``mission`` returns them
    as a ``MissionResult`` like ``ar.simulate``'s. ``observed``: the NMPC has an external-force observer."""

    def __init__(self, vehicle: Multirotor, scene: RadioScene, *, observed: bool = False):
        self.vehicle, self.scene, self.observed = vehicle, scene, observed
        self.relay, self.source, bs = (scene.name_of(role) for role in ("relay", "source", "base_station"))
        self._p0 = scene.fixed_pose(bs).position
        self.observer_columns = [f"{self.relay}.a_ext_{a}" for a in AXES]  # the observer's estimate, as sim/air.py logs it
        self.columns = (log_columns({self.relay: vehicle.n_rotors}, [self.source], scene) + list(FLIGHT_COLUMNS)
                        + (self.observer_columns if observed else []))
        self.rows: list[dict] = []

    def record(self, t: float, x: np.ndarray, cmd: Command, source: KnownSource, *, state_age_s: float,
               violation: bool = False, a_ext: np.ndarray | None = None) -> None:
        """Step ``t`` (s, the mission's clock): the relay's measured state ``x`` (m, rad ZYX, m/s, rad/s,
        the commanded rotor speeds in Hz), the command, the source as the relay knew it."""
        src = SourceState(np.asarray(source.p, float), np.asarray(source.v, float), np.asarray(source.a, float))
        eta2 = src.attitude(self.vehicle.gravity)
        R1 = rotation_zyx(x[3:6])
        channel = self.scene.evaluate(t, {self.relay: self.scene.pose(self.relay, x[0:3], R1),
                                          self.source: self.scene.pose(self.source, src.p, rotation_zyx(eta2))})
        ref, info = cmd.reference, cmd.info
        if ref is None or info is None:  # the failsafe flew: its target is the reference, no QP
            ref = Reference(p_opt=cmd.position_m, p_ref=cmd.position_m, v_ref=cmd.velocity_m_s, a_ref=cmd.acceleration_m_s2)
            info = StepInfo(u=np.zeros(self.vehicle.n_rotors), ok=True, status=cmd.mode, prep_ms=0.0,
                            feedback_ms=cmd.compute_ms, slack_max=0.0)
        row = {"t": t, **relay_row(self.relay, x, R1, info, ref, src.p, self._p0, violation and cmd.mode in ("nmpc", "fallback"))}
        row |= source_row(self.source, src.p, eta2) | link_row(self.scene, t, channel)
        row["separation_min"] = separation_min(np.array([x[0:3], src.p]))
        row |= {"flight_mode": cmd.mode, "compute_ms": cmd.compute_ms, "deadline_met": cmd.deadline_met,
                "state_age_s": state_age_s}
        if self.observed:
            row |= dict(zip(self.observer_columns, np.zeros(3) if a_ext is None else a_ext, strict=True))
        if not self.rows and set(row) != set(self.columns):
            raise ValueError(f"flight record: columns {sorted(set(self.columns) ^ set(row))} not both declared and recorded")
        self.rows.append(row)

    def mission(self, wall_s: float, *, controller: str = "", fallback_episodes: int = 0,
                aborted: str | None = None) -> MissionResult:
        """The rows as a ``MissionResult`` (``sim_s`` the mission time flown). Raises ValueError when
        nothing was flown in OFFBOARD."""
        if not self.rows:
            raise ValueError("flight record: no control period was flown in OFFBOARD")
        log = {c: _column([r[c] for r in self.rows], flight_column_type(c)) for c in self.columns}
        return MissionResult(log=log, wall_s=wall_s, sim_s=float(log["t"][-1] - log["t"][0]),
                             qp_failures=int(np.sum(~log[f"{self.relay}.qp_ok"])), controller=controller,
                             fallback_episodes=fallback_episodes, aborted=aborted)


def _column(values: list, kind: type) -> np.ndarray:
    return np.array(values, dtype=object if kind is str else kind)


def flight_metrics(log: dict) -> dict:
    """A flight's own metrics: the share of control periods the stale-input failsafe held or landed,
    the share that missed their deadline, the step's computation time (ms) and the relay state's age (s)."""
    mode = np.asarray(log["flight_mode"], dtype=object)
    ms = np.asarray(log["compute_ms"], float)
    age = np.asarray(log["state_age_s"], float)
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
