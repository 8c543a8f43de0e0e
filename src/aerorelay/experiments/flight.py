"""A flight's run folder (``aerorelay fly --out``): the rows ``sim.flight_record`` collected each
control period in OFFBOARD become the time series, metrics, figures and MCAP ``aerorelay run`` writes,
with the bridge's own log beside them (``flight.parquet``: every period, streaming included)."""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ..assembly.flight import build_controller
from ..assembly.parts import build_scene
from ..config import Scenario, ScenarioError
from ..control.network import Controller
from ..control.relay_step import RelayStep
from ..flight.airframes import Airframe
from ..flight.autopilot_loop import StepHook
from ..flight.mavlink import drain
from ..flight.mavlink_bridge import OffboardBridge, VehicleLink
from ..flight.mavlink_vehicle import MavlinkVehicle, VehicleSettings
from ..flight.sources import MavlinkSource
from ..models.mission import SourceTrajectory, source_trajectory
from ..models.state import P
from ..sim.flight_record import FlightRecorder, flight_column_type, flight_metrics, telemetry_metrics
from ..sim.units import metric_units
from ..store.outputs import new_sibling, swap_in
from ..store.run_folder import TIMESERIES_FILE, log_frame
from .run import RunResult, run_metrics

log = logging.getLogger(__name__)
FLIGHT_LOG = "flight.parquet"


def flown_relays(controller: Controller) -> dict[str, RelayStep]:
    """Every relay's part of the controller by name."""
    return {r.name: r.stepper for r in controller.controller.relays}


def recorder(sc: Scenario, controller: Controller) -> tuple[FlightRecorder, StepHook]:
    """A recorder of ``sc``'s flight and the transport's hook that feeds it (every relay's supervisor verdict and
    observer's estimate read from the controller each period)."""
    relays = flown_relays(controller)
    observed = any(r.observer is not None for r in relays.values())
    rec = FlightRecorder({n: r.vehicle for n, r in relays.items()}, build_scene(sc), observed=observed)

    def hook(t: float, xs, cmds, srcs, age: float) -> None:
        rec.record(t, xs, cmds, srcs, state_age_s=age,
                   violations={n: bool(r.controller.last_violations) for n, r in relays.items()},
                   a_ext={n: r.observer.estimate if r.observer is not None else None for n, r in relays.items()})
    return rec, hook


def flight_result(sc: Scenario, rec: FlightRecorder, stepper: Controller, wall_s: float, *,
                  aborted: str | None = None, views: Callable[[RunResult, Path], None] | None = None,
                  bridge_log: pd.DataFrame | None = None, lost_at: dict[str, float] | None = None) -> RunResult:
    """The flight as ``ar.simulate``'s result: its time series and metrics (``run_metrics`` plus the
    flight's own, ``sim.flight_record.flight_metrics``, and the telemetry the bridge did not trust,
    ``telemetry_metrics``); ``views`` writes figures and MCAP. ``lost_at``: relays that left the network in
    flight, when (s): in the metrics, ``relays.<name>.lost_at_s`` and ``lost_in_flight``."""
    relays = flown_relays(stepper)
    first = next(iter(relays.values()))
    mission = rec.mission(wall_s, controller=first.controller.nmpc.settings.fingerprint(),
                          fallback_episodes=sum(r.controller.fallback_episodes for r in relays.values()), aborted=aborted)
    mission.separation_unguarded = dict(stepper.controller.unguarded)
    df = log_frame(mission.log, rec.columns, {c: flight_column_type(c) for c in rec.columns if flight_column_type(c) is not float})
    metrics = run_metrics(sc, mission, {n: r.vehicle for n, r in relays.items()}, None, rec.scene) | \
        flight_metrics(mission.log, bridge_log) | telemetry_metrics(bridge_log)  # held periods as the bridge flew them
    if lost_at:
        metrics["lost_in_flight"] = [{"relay": n, "t_s": float(t)} for n, t in sorted(lost_at.items(), key=lambda kv: kv[1])]
        for n, t in lost_at.items():
            metrics["relays"][n]["lost_at_s"] = float(t)
    metrics["outage_threshold"] = sc.channel.outage
    metrics["unit_system"] = sc.channel.units
    metrics["units"] = metric_units(metrics, sc.channel.capacity_unit)
    return RunResult(sc, mission, df, metrics, None, views)


def save_flight(sc: Scenario, out: Path, bridge_log: pd.DataFrame | None, rec: FlightRecorder,
                stepper: Controller, wall_s: float, *, aborted: str | None = None,
                views: Callable[[RunResult, Path], None] | None = None, lost_at: dict[str, float] | None = None) -> RunResult | None:
    """Write the flight's run folder into ``out`` (with ``flight.parquet``, the bridge's log, when given);
    when the metrics fail, a folder with what there is (``flight.parquet`` and the rows recorded,
    ``timeseries.parquet``) so the flight is never lost; the error is logged and re-raised after it is written."""
    def with_log(tmp: Path) -> None:
        if bridge_log is not None:
            bridge_log.to_parquet(tmp / FLIGHT_LOG, index=False)
    try:
        result = flight_result(sc, rec, stepper, wall_s, aborted=aborted, views=views, bridge_log=bridge_log, lost_at=lost_at)
    except Exception:
        log.exception("the flight's metrics failed: writing its raw logs to %s", out)
        save_raw(Path(out), bridge_log, rec)
        raise
    result.save(out, extra=with_log)
    return result


def save_raw(out: Path, bridge_log: pd.DataFrame | None, rec: FlightRecorder) -> None:
    """``flight.parquet`` (when given) and the rows recorded (if any) as a run folder ``out``: what a
    flight leaves when it flew nothing in OFFBOARD or its metrics failed."""
    tmp = new_sibling(out)
    if bridge_log is not None:
        bridge_log.to_parquet(tmp / FLIGHT_LOG, index=False)
    if rec.rows:
        pd.DataFrame(rec.rows).to_parquet(tmp / TIMESERIES_FILE, index=False)
    swap_in(tmp, out, "run")


class Recording:
    """A flight being recorded (``aerorelay fly``, ``aerorelay ros``; one relay or a network): ``hook`` feeds the
    recorder; ``finish(bridge_log, aborted, lost_at)`` at the end, also on Ctrl-C, writes the run folder to
    ``out`` (raw logs when nothing was flown in OFFBOARD) and returns the flight's result (None when nothing was
    flown)."""

    def __init__(self, sc: Scenario, stepper: Controller, out: Path | None, *,
                 views: Callable[[RunResult, Path], None] | None = None):
        self.sc, self.stepper, self.out, self.views = sc, stepper, None if out is None else Path(out), views
        self.rec, self.hook = recorder(sc, stepper)
        self.wall0 = time.perf_counter()

    def finish(self, bridge_log: pd.DataFrame | None, aborted: str | None = None,
               lost_at: dict[str, float] | None = None) -> RunResult | None:
        wall = time.perf_counter() - self.wall0
        if not self.rec.rows:
            if self.out is not None:
                save_raw(self.out, bridge_log, self.rec)
            return None
        if self.out is None:
            return flight_result(self.sc, self.rec, self.stepper, wall, aborted=aborted, bridge_log=bridge_log, lost_at=lost_at)
        return save_flight(self.sc, self.out, bridge_log, self.rec, self.stepper, wall, aborted=aborted, views=self.views,
                           lost_at=lost_at)


def bridge_frame(rows: list[dict]) -> pd.DataFrame:
    """The bridge's log (one row per period: time, mode, arming, the vehicle's custom mode, the step's
    computation and deadline, the relay's position) as a DataFrame."""
    return pd.DataFrame([{k: v for k, v in r.items() if k != "x"} | ({} if r.get("x") is None else
                         dict(zip(("p_x", "p_y", "p_z"), r["x"][P], strict=True))) for r in rows])


def check_flyable(sc: Scenario) -> None:
    """A named error, before any vehicle is contacted, for what the MAVLink bridge cannot fly: jammers
    estimated from readings (no radio reaches the bridge; step ``ar.controller`` with ``readings=``)."""
    if sc.estimates_jammers:
        raise ScenarioError("jammer.localization: 'estimated' needs the relay's receiver readings, which no radio "
                            "hands the MAVLink bridge; step ar.controller(sc) with readings= (docs/guide/flying.md)")


LOCKSTEP_OFFBOARD_WITHIN_S = 5.0  # the bridge streams ~1.1 s before it asks; OFFBOARD later than this is an error


def free_udp_port() -> int:
    """A UDP port on localhost nobody listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def fly_lockstep(sc: Scenario, airframes: Mapping[str, Airframe], *, setpoint: str = "position",
                 duration_s: float | None = None, views: Callable[[RunResult, Path], None] | None = None,
                 telemetry_lost: Callable[[str, float], bool] | None = None,
                 source_airframes: Mapping[str, Airframe] | None = None) -> tuple[RunResult, pd.DataFrame]:
    """Fly ``sc``'s controller through the MAVLink bridge (``flight.mavlink_bridge.OffboardBridge``) on one in-repo
    vehicle per relay (``airframes`` by relay name, each its own UDP link on localhost and system id 1, 2, ...), in
    lockstep (one vehicle step per control period, telemetry every period): the bridge streams, arms, enters OFFBOARD,
    flies the mission (``duration_s``, default the scenario's) and hands back to a hold. With position setpoints the
    NMPC runs without ``[wind]``'s external-force observer, as ``aerorelay fly`` does (docs/guide/flying.md).
    ``telemetry_lost(relay, t)``: the relay's telemetry does not reach the bridge at bridge time ``t`` (a link
    dropped; its setpoints still reach the vehicle). ``source_airframes`` (e.g. ``flight.airframes.MissionFlyer`` by
    source name): those sources are further in-repo vehicles (system ids after the relays', each its own link), read
    as MAVLink systems; the others fly their mission files. Returns the flight as ``ar.simulate``'s result (the relays
    that left the network and when in ``lost_in_flight``; reported unsafe, ``aborted``, when a vehicle went below the
    ground or its state stopped being finite, or every vehicle left the flight) and the bridge's log."""
    check_flyable(sc)
    if setpoint not in ("position", "attitude"):
        raise ValueError(f"setpoint must be 'position' or 'attitude', got {setpoint!r}")
    relays = [r.name for r in sc.relay_list]
    missing, unknown = [n for n in relays if n not in airframes], [n for n in airframes if n not in relays]
    if missing or unknown:
        raise ValueError(f"fly_lockstep: one airframe per relay ({', '.join(relays)}), by name (ar.plant_airframes(sc)); "
                         + (f"none for {missing}" if missing else f"no relay {unknown}"))
    # an autopilot's thrust stays along body z; the observer destabilized a position cascade (docs/guide/flying.md)
    controller = build_controller(sc, observer=setpoint == "attitude", autopilot=True)
    rec, hook = recorder(sc, controller)
    T = controller.period
    ports = {n: free_udp_port() for n in relays}
    vehicles = {n: MavlinkVehicle(f"udpin:127.0.0.1:{ports[n]}", settings=VehicleSettings(telemetry_hz=1.0 / T), system=i + 1,
                                  airframe=airframes[n]) for i, n in enumerate(relays)}
    sources: dict[str, SourceTrajectory | MavlinkSource] = {s.name: source_trajectory(s.mission) for s in sc.source_list}
    source_vehicles = []
    for i, (name, frame) in enumerate((source_airframes or {}).items()):
        if name not in sources:
            raise ValueError(f"fly_lockstep: no source {name!r} ({', '.join(sources)})")
        port, system = free_udp_port(), len(vehicles) + 1 + i
        source_vehicles.append(MavlinkVehicle(f"udpin:127.0.0.1:{port}", settings=VehicleSettings(telemetry_hz=1.0 / T),
                                              system=system, airframe=frame))
        sources[name] = MavlinkSource(f"udpout:127.0.0.1:{port}", system=system)
    bridge = OffboardBridge({n: f"udpout:127.0.0.1:{p}" for n, p in ports.items()}, controller, sources, arm=True,
                            setpoint=setpoint, on_step=hook)
    everyone = [*vehicles.values(), *source_vehicles]
    if telemetry_lost is not None:
        for name, link in bridge.links.items():
            read = link._read

            def gated(t: float, read=read, name=name, link=link) -> None:
                if telemetry_lost(name, t):
                    drain(link.link)  # the messages are lost on the way
                else:
                    read(t)
            link._read = gated  # type: ignore[method-assign]
    duration = sc.duration_s if duration_s is None else duration_s
    wall0 = time.perf_counter()
    try:
        aborted = _in_lockstep(bridge, bridge.links, everyone, T, duration, lambda: next(
            (f"relay {n}: {why}" for n, a in airframes.items() if (why := _left_the_air(a, sc.world.ground_z_m))), None))
    finally:
        bridge.hand_back()
        for v in vehicles.values():
            v.step(T)
        for link in bridge.links.values():
            link.link.close()
        for src in bridge.sources.values():
            if isinstance(src, MavlinkSource):
                src.link.close()
        for v in everyone:
            v.link.close()
    log_df = bridge_frame(bridge.log)
    return flight_result(sc, rec, controller, time.perf_counter() - wall0, aborted=aborted or bridge.ended, views=views,
                         bridge_log=log_df, lost_at=controller.lost_at), log_df


def _in_lockstep(bridge: OffboardBridge, links: Mapping[str, VehicleLink], vehicles: list[MavlinkVehicle],
                 period: float, duration: float, left_the_air: Callable[[], str | None]) -> str | None:
    """The handshake (each vehicle answers once it has heard its link), then per control period one step of every
    in-repo vehicle and one bridge tick, until ``duration`` (s) of mission has flown, the bridge has ended the
    flight or a vehicle left the air; returns why it stopped early (``left_the_air``), None otherwise. TimeoutError
    when a vehicle does not answer or OFFBOARD is not entered within ``LOCKSTEP_OFFBOARD_WITHIN_S``."""
    t, heard = 0.0, set[str]()
    while len(heard) < len(links):
        for n, link in links.items():
            if n not in heard:
                link.announce()
        for v in vehicles:
            v.step(period)
        heard |= {n for n, link in links.items() if n not in heard and link.heard_vehicle()}
        t += period
        if len(heard) < len(links) and t > LOCKSTEP_OFFBOARD_WITHIN_S:
            raise TimeoutError(f"lockstep: the in-repo vehicles of {sorted(set(links) - heard)} did not answer the bridge's heartbeat")
    while bridge.mission_t0 is None or t - bridge.mission_t0 < duration - 1e-9:
        for v in vehicles:
            v.step(period)
        bridge.tick(t)
        t += period
        if bridge.mission_t0 is None and t > LOCKSTEP_OFFBOARD_WITHIN_S:
            raise TimeoutError(f"lockstep: the vehicles did not all enter OFFBOARD within {LOCKSTEP_OFFBOARD_WITHIN_S:g} s")
        aborted = left_the_air()
        if aborted or bridge.ended:
            return aborted
    return None


def _left_the_air(airframe: Airframe, ground_z_m: float) -> str | None:
    if not (np.all(np.isfinite(airframe.p)) and np.all(np.isfinite(airframe.v))):
        return "the vehicle's state stopped being finite"
    if airframe.p[2] < ground_z_m:
        return f"the vehicle went below the ground (z = {airframe.p[2]:.2f} m)"
    return None
