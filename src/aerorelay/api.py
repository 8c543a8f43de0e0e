"""The Python API: load a scenario, fly it, bound it, benchmark it, reproduce the paper.

    import aerorelay as ar
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"controller.mu": 0.3})
    result = ar.simulate(sc)            # result.timeseries (DataFrame), result.metrics (dict)
    result.save("runs/mine")            # the run folder `aerorelay run` writes, figures included
    bound = ar.bound(sc)                # the best link the physics allows (cached per geometry)

Parts can be passed instead of named in TOML: ``ar.simulate(sc, planner=MyPlanner())`` (any
object with ``update(PlannerInput) -> Reference``), ``jammers=[ar.Jammer(...)]`` or a whole
``scene=ar.RadioScene(...)`` with your own antenna patterns.
"""

from __future__ import annotations

import datetime
import json
import logging
import math
import os
import platform
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ._version import __version__
from .assembly import load_scenario
from .assembly.c_engine import refuse_c_engines
from .assembly.codegen import CController, Shadow, build_shared, flown_by_c, is_recording, record_calls, write_tree
from .assembly.codegen import bench_c as codegen_bench_c
from .assembly.flight import build_controller
from .assembly.load import parse_sets as _parse_sets
from .assembly.load import updated as _updated
from .assembly.parts import (
    bound_cost,
    bound_of,
    build,
    build_scene,
    build_source,
    check_bound_size,
    nmpc_settings,
)
from .assembly.planners import comms_aware
from .assembly.vehicle import build_vehicle
from .assembly.world import wind_field
from .config import Scenario, ScenarioError
from .control.bench import benchmark_closed_loop
from .control.network import Controller
from .control.nmpc import NmpcSettings
from .control.relay_step import StaleSettings
from .experiments import flight as _flight
from .experiments.budget import flight_seconds, left_out_notices, run_cost_s, within_budget
from .experiments.campaign import CampaignBusyError, CampaignResult, RunStatus, is_finished, load_manifest, run_campaign
from .experiments.chains import long_chain
from .experiments.design import BY as DESIGN_BY
from .experiments.design import design_runs
from .experiments.design import summarize as summarize_design
from .experiments.design import write_outputs as write_design
from .experiments.run import RunResult, check_not_injected, check_run_size, output_bytes
from .experiments.run import simulate as _simulate
from .experiments.study import Study, StudyError, expand, find_studies, read_studies
from .flight.airframes import Airframe, MissionFlyer, MultirotorAirframe, RotorpyQuadrotor, still_air
from .flight.mavlink import check_url
from .flight.mavlink_bridge import OffboardBridge
from .flight.mavlink_vehicle import MavlinkVehicle
from .flight.sources import MavlinkSource
from .models.generated_scene import outline
from .models.geo import GeoFrame
from .models.mission import SourceTrajectory, source_trajectory
from .models.obstacles import obstacle_model
from .models.vehicle import Multirotor
from .planning.bound import CapacityBound
from .planning.network_bound import NetworkBound
from .planning.plugins import load as load_plugins
from .planning.plugins import resolve as resolve_plugin
from .report.figures import fig_bound, fig_network_bound, write_run_figures
from .report.flight_export import EXPORT_FOLDER, missing_columns, vehicles, write_geojson, write_kml, write_plan, write_ulog
from .report.flight_export import FORMATS as EXPORT_FORMATS
from .report.flight_export import GEOGRAPHIC as EXPORT_GEOGRAPHIC
from .report.flight_export import write_csv as write_flight_csv
from .report.folders import read_metrics, read_scenario, read_timeseries
from .report.foxglove import LAYOUT_FILE, write_layout
from .report.html import render_report
from .report.mcap_export import MCAP_FILE, write_run_mcap
from .report.run_report import RUN_REPORT, render_run_report
from .report.summary import metric as _metric
from .report.summary import summarize
from .sim.initial import initial_link_budget
from .sim.initial import link_budget_lines as initial_link_budget_lines
from .sim.units import metric_unit as _metric_unit
from .sim.units import si as _si
from .store import strict_json
from .store.outputs import (
    OutputBusyError,
    OutputError,
    check_output_folder,
    check_own_file,
    folder_kind,
    is_own_folder,
    mark,
    new_sibling,
    swap_in,
    write_atomic,
    writing,
)
from .store.run_folder import BOUND_PARQUET, METRICS_FILE, SCENARIO_FILE, TIMESERIES_FILE, write_bound_files

Result = RunResult  # the one result class: ``ar.simulate`` attaches the figure and MCAP writer


def write_run_views(result: RunResult, tmp: Path) -> None:
    """The run's figures, ``run.mcap`` for Foxglove and its layout, written into the run folder ``tmp``."""
    bound = result.bound.frame() if result.bound is not None else None
    write_run_figures(result.timeseries, result.scenario, tmp, bound)
    write_run_mcap(result.timeseries, result.scenario, tmp / MCAP_FILE, bound)
    write_layout(result.timeseries.columns, result.scenario.channel.capacity_unit, tmp / LAYOUT_FILE)


def simulate(sc: Scenario, *, bound: bool = False, **parts) -> RunResult:
    """Fly ``sc``; ``bound=True`` also computes its capacity bound (efficiency in the metrics).
    Keyword parts (``planner``, ``jammers``, ``scene``, ``nmpc_settings``, ``progress``) replace the
    scenario's (see ``experiments.run.simulate``). ``save`` writes the run folder with the figures
    and ``run.mcap`` (``figures=False``: data files only)."""
    return _simulate(sc, with_bound=bound, views=write_run_views, **parts)


def controller(sc: Scenario, *, nmpc_settings: NmpcSettings | None = None, stale: StaleSettings | None = None,
               observer: bool = True, autopilot: bool = False) -> Controller:
    """The scenario's controller stepped from outside, for any network: ``ctrl.step(t, {relay: state}, {source:
    SourceState})`` each control period returns ``{relay: Command}`` (rotor speeds and autopilot setpoints, world ENU,
    body FLU; ``aerorelay.flight.frames`` converts to NED/FRD), the relays' plans exchanged inside
    (``control.network.Controller``, the same type for any number of relays). One relay and one source stepped as the
    paper's problem: ``ctrl.one_relay().step(t, relay_state, source)`` returns its ``Command`` (the explicit adapter,
    ``control.network.OneRelay``). Every relay's telemetry is
    checked, stale inputs hold, then land (``stale``, every relay's). Stepped over aerorelay's plant it flies exactly
    what ``simulate`` flies, in wind too (docs/guide/flying.md). ``observer=False`` leaves out ``[wind]``'s
    external-force observer (for an autopilot's position loop: see the guide); ``autopilot=True`` plans for the vehicle
    an autopilot flies (thrust along body z: a tilted platform's rotors untilted in the NMPC's model), for its
    setpoints."""
    ctrl = build_controller(sc, nmpc_settings=nmpc_settings, stale=stale, observer=observer, autopilot=autopilot)
    return ctrl


def sitl(sc: Scenario, url: str, duration_s: float | None = None, airframe: Airframe | None = None, *,
         source: bool = False, relay: str | None = None) -> None:
    """Run the in-repo MAVLink vehicle (``flight.mavlink_vehicle``: PX4's offboard subset, not PX4) on
    ``url`` in real time, flying ``airframe`` (default: an ideal point mass at the scenario's relay start;
    ``flight.airframes.RotorpyQuadrotor``: RotorPy's quadrotor). ``source``: instead, the inspection drone
    flying the scenario's mission as MAVLink system 2 (for ``fly``'s ``source_url``). ``relay``: a network's
    relay by name: the vehicle starts at its start as MAVLink system ``1 + its index`` (one process per relay)."""
    if source:
        MavlinkVehicle(url, system=2, airframe=MissionFlyer(build_source(sc))).run_realtime(duration_s=duration_s)
        return
    i = relay_index(sc, relay)
    MavlinkVehicle(url, position=sc.relay_list[i].start, airframe=airframe, system=i + 1).run_realtime(duration_s=duration_s)


def relay_index(sc: Scenario, relay: str | None) -> int:
    """The index of relay ``relay`` in the scenario (None: the first); a ValueError naming the relays otherwise."""
    names = [r.name for r in sc.relay_list]
    if relay is None:
        return 0
    if relay not in names:
        raise ValueError(f"--relay {relay!r}: the scenario's relays are {', '.join(names)}")
    return names.index(relay)


def plant_airframe(sc: Scenario, relay: str | None = None) -> Airframe:
    """aerorelay's own plant for the scenario's relay platform (the tilted hexarotor by default) under a
    multirotor autopilot's cascade at the relay's start (``flight.airframes.MultirotorAirframe``: its
    thrust stays along body z, as an autopilot flies it); ``relay``: a network's relay by name (None: the first)."""
    i = relay_index(sc, relay)
    return MultirotorAirframe(build_vehicle(sc.platform_of(i)), sc.relay_list[i].start)


def plant_airframes(sc: Scenario) -> dict[str, Airframe]:
    """``plant_airframe`` for every relay of the scenario by name, each its own platform at its own start."""
    return {r.name: MultirotorAirframe(build_vehicle(sc.platform_of(i)), r.start) for i, r in enumerate(sc.relay_list)}


def rotorpy_airframe(sc: Scenario, params: dict | None = None, relay: str | None = None) -> Airframe:
    """RotorPy's quadrotor (``params``: a RotorPy parameter dict, default its Hummingbird, as
    ``scenarios/rotorpy_hummingbird.toml`` models it) at the scenario's relay start (``relay``: a network's relay
    by name), in its ``[wind]`` (the same mean, gusts and seed as ``simulate``'s); needs ``pip install 'aerorelay[rotorpy]'``."""
    wind = wind_field(sc)
    return RotorpyQuadrotor(sc.relay_list[relay_index(sc, relay)].start, params, wind=wind if wind is not None else still_air)


def fly_lockstep(sc: Scenario, airframe: Airframe | Mapping[str, Airframe], *, setpoint: str = "position",
                 duration_s: float | None = None,
                 telemetry_lost: Callable[[str, float], bool] | None = None,
                 source_airframes: Mapping[str, Airframe] | None = None) -> tuple[RunResult, pd.DataFrame]:
    """Fly the scenario's controller through the MAVLink bridge on the in-repo vehicles, one per relay, over UDP on
    localhost in lockstep (``experiments.flight.fly_lockstep``): ``airframe`` maps every relay's name to its vehicle's
    airframe (``plant_airframes(sc)``, ``rotorpy_airframe(sc)``, ``flight.airframes.PointMass``); one airframe is the
    one relay's. Returns the flight as ``simulate``'s result (``save`` writes the run folder with figures and MCAP)
    and the bridge's log (docs/guide/flying.md). With position setpoints the NMPC runs without ``[wind]``'s
    external-force observer, as ``fly`` does. ``telemetry_lost(relay, t)`` drops a relay's telemetry at bridge time
    ``t``; ``source_airframes`` (``flight.airframes.MissionFlyer`` by source name) flies those sources as further
    MAVLink systems the bridge reads."""
    return _flight.fly_lockstep(sc, _by_relay(sc, airframe, "airframe", "ar.plant_airframes(sc)"), setpoint=setpoint,
                                duration_s=duration_s, views=write_run_views, telemetry_lost=telemetry_lost,
                                source_airframes=source_airframes)


def _by_relay(sc: Scenario, given, what: str, hint: str) -> dict:
    """``given`` by relay name: a mapping as it is, one value for the scenario's one relay (a ValueError for a network)."""
    if isinstance(given, Mapping):
        return dict(given)
    names = [r.name for r in sc.relay_list]
    if len(names) != 1:
        raise ValueError(f"a network needs one {what} per relay, {{relay name: {what}}} ({hint}); its relays: {', '.join(names)}")
    return {names[0]: given}


def fly(sc: Scenario, url: str | Mapping[str, str], *, arm: bool = False, setpoint: str = "position",
        duration_s: float | None = None, out: Path | None = None,
        source_url: str | Mapping[str, str] | None = None, source_system: int | None = None,
        source_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[RunResult | None, pd.DataFrame]:
    """Fly the scenario's controller on MAVLink autopilots in OFFBOARD (``flight.mavlink_bridge``), one per relay:
    ``url`` by relay name (one URL: the one relay's), each its own link and system; wait for every heartbeat, stream,
    arm only with ``arm``, hand back to a hold at the end or on Ctrl-C. A vehicle whose telemetry stops holds, then
    lands and leaves the network (the others re-plan); the run folder's metrics name it and when (``lost_in_flight``).
    Returns the flight as ``simulate``'s result (None when no period was flown in OFFBOARD) and the bridge's log (a row
    per relay per period). ``out``: the run folder ``aerorelay run`` writes (time series, metrics, figures, run.mcap)
    plus ``flight.parquet``, written even when the flight is interrupted (``experiments.flight``); it is checked before
    any vehicle is contacted. ``source_url``: sources as MAVLink systems, by source name (one URL: the one source's,
    ``source_system`` its system id, None any, its local origin at ``source_origin``, m ENU in the scenario's world);
    the others from their mission files. With position setpoints the NMPC runs without ``[wind]``'s external-force
    observer (beside an autopilot's position loop it lost RotorPy's quadrotor in a 5 m/s wind: docs/decisions.md)."""
    _flight.check_flyable(sc)
    urls = _by_relay(sc, url, "MAVLink URL", "--mavlink NAME=URL")
    for name, u in urls.items():
        check_mavlink_url(u, f"--mavlink {name}=" if isinstance(url, Mapping) else "--mavlink")
    known = [s.name for s in sc.source_list]
    if source_url is not None and not isinstance(source_url, Mapping):
        if len(known) != 1:
            raise ValueError(f"--source-mavlink: the scenario has sources {', '.join(known)}: give NAME=URL for each")
        source_url = {known[0]: source_url}
    if (source_system is not None or source_origin != (0.0, 0.0, 0.0)) and len(source_url or {}) != 1:
        raise ValueError("--source-system / --source-origin: for one source read with --source-mavlink (source_url)")
    for name, u in (source_url or {}).items():
        if name not in known:
            raise ValueError(f"--source-mavlink {name}=: the scenario's sources are {', '.join(known)}")
        check_mavlink_url(u, f"--source-mavlink {name}=")
    if out is not None:
        check_output_folder(out, "run")
    # the observer destabilized a position cascade; an autopilot's thrust stays along body z (the guide)
    ctrl = build_controller(sc, observer=setpoint == "attitude", autopilot=True)
    sources: dict[str, SourceTrajectory | MavlinkSource] = {s.name: source_trajectory(s.mission) for s in sc.source_list}
    sources |= {name: MavlinkSource(u, system=source_system, origin_enu=source_origin) for name, u in (source_url or {}).items()}
    bridge = OffboardBridge(urls, ctrl, sources, arm=arm, setpoint=setpoint)
    bridge.connect()
    recording = _flight.Recording(sc, ctrl, out, views=write_run_views)  # the flight's wall time starts once the vehicles answered
    bridge.on_step = recording.hook
    aborted = None
    try:
        bridge.run(sc.duration_s if duration_s is None else duration_s)
        aborted = bridge.ended
        if aborted is None and not bridge.loop.started:  # e.g. a --source-mavlink that never answered: exit 0 before
            aborted = f"the mission never started: {bridge.loop.waiting or 'the vehicles never all took OFFBOARD'}"
    except KeyboardInterrupt:
        aborted = "interrupted (Ctrl-C): the vehicles were asked to hold"
        raise
    finally:
        df = _flight.bridge_frame(bridge.log)
        result = recording.finish(df, aborted, lost_at=ctrl.lost_at)
    if result is None and aborted is not None:  # not one period flown: said, not a flight reported done (exit 0 before)
        raise ValueError(f"nothing was flown: {aborted}" + (f" (the bridge's log is in {out})" if out is not None else ""))
    return result, df


def ros(sc: Scenario, spin: Callable, duration_s: float | None = None, *, out: Path | None = None,
        topics: Mapping[str, str] | None = None):
    """Run the scenario's controller as one ROS 2 node (``spin``: ``flight.ros_node.spin``, the optional extra,
    imported by the caller) until ``duration_s``, each relay and source under its name as topic namespace
    (``topics``: another namespace by name); ``out``: the flight's run folder (as ``fly`` writes it, without
    ``flight.parquet``), written on Ctrl-C too. Returns the node and the flight's result (its metrics say whether it was
    safe; which relays left the network and when, ``lost_in_flight``; None when nothing was flown)."""
    if out is not None:
        check_output_folder(out, "run")
    ctrl = build_controller(sc, autopilot=True)  # its setpoints are for an autopilot: thrust along body z
    recording = _flight.Recording(sc, ctrl, out, views=write_run_views)
    aborted, node, result = None, None, None
    try:
        node = spin(ctrl, build_scene(sc), duration_s, on_step=recording.hook, topics=topics)
    except KeyboardInterrupt:
        aborted = "interrupted (Ctrl-C)"
        raise
    finally:
        result = recording.finish(None, aborted, lost_at=ctrl.lost_at)
    return node, result


def derived_values(sc: Scenario) -> list[str]:
    """Values the scenario derives rather than states, one line each beside the field they replace:
    a jammer's power set from ``inr_db_at_relay_start`` (the file's ``power_w`` is then not used)."""
    scene = build_scene(sc)
    out = []
    for i, (cfg, jam) in enumerate(zip(sc.jammer_configs, scene.jammers, strict=True)):
        if cfg.inr_db_at_relay_start is not None:
            out.append(f"{sc.jammer_field(i)}.power_w: {jam.power:.6g} W ({10 * math.log10(jam.power):.1f} dBW), derived from "
                       f"inr_db_at_relay_start = {cfg.inr_db_at_relay_start:g} dB (the power_w below is not used)")
    return out


def list_studies(folder: str | Path, *, quick: bool = False) -> list[tuple[str, str, int | None]]:
    """``(name, title, runs)`` of every study in ``folder`` (runs as ``reproduce`` would make them); a study that
    cannot be expanded here (a run needs an extra, a scenario is refused) is listed with why and ``runs`` None, a
    file that is no study with its file name and why: one bad file does not hide the others."""
    folder = Path(folder)
    studies, broken = read_studies(folder)
    out: list[tuple[str, str, int | None]] = []
    for st in studies:
        try:
            out.append((st.name, st.title, len(expand(st, folder.resolve().parent, quick=quick))))
        except (StudyError, ScenarioError, ImportError) as exc:
            out.append((st.name, f"cannot run here: {exc}", None))
    return out + [(path.name, f"not a study: {why}", None) for path, why in broken.items()]


def check_mavlink_url(url: str, option: str = "MAVLink URL") -> None:
    """A named error (ValueError naming ``option``) for a MAVLink URL that cannot be opened as meant
    (``flight.mavlink.check_url``: its form, the port's range, a port to listen on that is in use)."""
    check_url(url, option)


def bound(sc: Scenario, progress: Callable[[int, int], None] | None = None) -> CapacityBound | NetworkBound:
    """The scenario's capacity bounds (static and path), computed once per geometry and cached; a
    fleet's network bound (``planning/network_bound.py``: static upper bound and the refined
    configuration) for a fleet."""
    return bound_of(sc, progress)


def vehicle(sc: Scenario) -> Multirotor:
    """The relay's vehicle model (``[platform]``): allocation, hover speeds, tilt limits."""
    return build_vehicle(sc.platform_of(0))


def relay_summaries(sc: Scenario) -> list[dict[str, object]]:
    """Every relay's own platform, limits and antenna, as it flies (``aerorelay info``): its name, rotor count and
    layout, largest rotor-axis tilt (deg), allocation rank, hover speeds (Hz) and shaft power (W), its reference speed
    limit (m/s, ``controller.capacity.speed_m_s``; the paper's generator governs at ``governor_speed_m_s``), its antenna
    and whether it is a spare."""
    out: list[dict[str, object]] = []
    for i, r in enumerate(sc.relay_list):
        platform_cfg, ctrl = sc.platform_of(i), sc.controller_of(i)
        veh = build_vehicle(platform_cfg)
        F, M = veh.allocation()
        hover = veh.hover_speeds()
        own = r.antenna
        antenna = (f"{own.pattern} (its own, g_bar {own.g_bar:g}, axis body {'-z: down' if own.down else '+z: up'})"
                   if own is not None
                   else f"{sc.antenna.pattern} (shared)")
        out.append({"name": r.name, "platform": r.platform if isinstance(r.platform, str) else
                    ("its own table" if r.platform is not None else "shared"),
                    "rotors": veh.n_rotors, "layout": "custom layout" if platform_cfg.rotors is not None else "star layout",
                    "max_axis_tilt_deg": float(np.degrees(np.arccos(np.clip(veh.axes[:, 2], -1.0, 1.0))).max()),
                    "allocation_rank": int(np.linalg.matrix_rank(np.vstack([F, M]))),
                    "hover_hz": [float(h) for h in hover], "hover_shaft_power_w": float(veh.shaft_power(hover)),
                    "speed_m_s": ctrl.capacity.speed_m_s, "governor_speed_m_s": ctrl.governor_speed_m_s,
                    "antenna": antenna, "spare": r.standby})
    return out


def bound_estimate(sc: Scenario):
    """What the scenario's capacity bound would cost here if not cached (``planning.bound_cost.BoundCost``: cells,
    instants, relays, combinations of base-station ends, bytes held, estimated seconds)."""
    return bound_cost(sc)


def link_budget(sc: Scenario) -> dict[str, float]:
    """SINRs, capacity, alignment and interference-to-noise ratios at the initial geometry of the paper's
    two hops (one route: source -> relay -> base station; a network's budget, hop by hop, is ``link_budget_lines``)."""
    if not sc.has_two_hops:  # the paper's Gamma_21 and Gamma_10 are of two hops
        raise ScenarioError("link_budget: a network's start is given hop by hop by link_budget_lines")
    return initial_link_budget(build_scene(sc), sc.relay_list[0].start, sc.source_list[0].mission.start)


def link_budget_lines(sc: Scenario) -> list[tuple[str, str]]:
    """The initial link budget line by line in the scenario's units (``aerorelay info``)."""
    return initial_link_budget_lines(build_scene(sc), sc.starts, physical=sc.channel.physical)


def bench(sc: Scenario, settings: NmpcSettings | None = None, *, ipopt_points: int = 3) -> dict:
    """Time the controller on a mission (``control.bench.benchmark_closed_loop``): each relay's preparation,
    feedback and IPOPT at a few states, the planner's step and the network's."""
    refuse_c_engines(sc, "aerorelay bench times Python's controller (bench --backend c times the C library beside it)")
    warm = (sc.without_relays(frozenset()) if sc.losses else sc).with_updates({"sim.duration_s": 0.1})  # compile / load first
    build(warm, nmpc_settings=settings).closed_loop().run()
    res = benchmark_closed_loop(build(sc, nmpc_settings=settings).closed_loop(), ipopt_points=ipopt_points)
    res["machine"] = f"{platform.machine()} {platform.processor() or ''} python {platform.python_version()}".strip()
    kinds = sorted({"comms-aware NMPC" if comms_aware(sc.relay_view(i)) else "tracking NMPC" for i in range(len(sc.relay_list))})
    n = len(sc.relay_list)
    res["scenario"] = f"{sc.name} ({n} relay{'s' * (n != 1)}, {sc.planner} planner, {', '.join(kinds)})"
    return res


def bench_chains(base: str | Path, relays: list[int], length_m: float, *, updates: dict | None = None,
                 settings_of: Callable[[Scenario], NmpcSettings] | None = None, rounds: int = 1,
                 say: Callable[[str], None] = lambda s: None) -> dict:
    """``bench`` on generated long chains (``experiments.chains.long_chain``) of each count in ``relays`` over
    ``length_m`` (m), the base file's settings with ``updates``: every relay's step (mean and p99, ms; its brake-law
    and failed-QP shares), the fleet's step on one computer and on a computer per relay. Each relay's mean step over
    the one-relay chain's of the same round (``relay_step_over_one``) says whether a relay's cost grows with the
    network. ``rounds``: the counts flown in turn this many times (timings drift over minutes: compare within a
    round), ``out["rounds"][i][str(k)]``. Chains are built first (bad input fails before any flight)."""
    chains = {k: long_chain(base, k, length_m, updates=updates) for k in relays}
    out: dict = {"length_m": length_m, "rounds": []}
    for i in range(rounds):
        out["rounds"].append(_bench_round(chains, length_m, settings_of, f"round {i + 1} of {rounds}: " if rounds > 1 else "", say))
    out["machine"] = f"{platform.machine()} {platform.processor() or ''} python {platform.python_version()}".strip()
    return out


def _bench_round(chains: dict[int, Scenario], length_m: float, settings_of, label: str, say) -> dict:
    """One round of ``bench_chains``: each chain benched in turn."""
    out: dict = {}
    for k, sc in chains.items():
        say(f"{label}chain of {k} relay{'s' * (k != 1)} over {length_m:g} m: {sc.duration_s:g} s of flight")
        res = bench(sc, settings_of(sc) if settings_of else None, ipopt_points=0)
        flown = {n: r for n, r in res["relays"].items() if "step_ms" in r}
        out[str(k)] = {
            "relays": {n: {"step_ms": r["step_ms"], "fallback_fraction": r["fallback_fraction"],
                           "qp_failure_fraction": r["qp_failure_fraction"], "qp_iterations": r["qp_iterations"]}
                       for n, r in flown.items()},
            "relay_step_mean_ms": float(np.mean([r["step_ms"]["mean"] for r in flown.values()])),
            "relay_step_worst_mean_ms": float(max(r["step_ms"]["mean"] for r in flown.values())),
            "relay_step_worst_p99_ms": float(max(r["step_ms"]["p99"] for r in flown.values())),
            "fallback_fraction_max": float(max(r["fallback_fraction"] for r in flown.values())),
            "qp_failure_fraction_max": float(max(r["qp_failure_fraction"] for r in flown.values())),
            "planner_ms": res["planner_ms"], "fleet_step_one_computer_ms": res["fleet_step_one_computer_ms"],
            "fleet_step_own_computers_ms": res["fleet_step_own_computers_ms"], "wall_s": res["wall_s"], "sim_s": res["sim_s"],
            "scenario": res["scenario"]}
    if "1" in out:
        one = out["1"]["relay_step_mean_ms"]
        for c in out.values():
            c["relay_step_over_one"] = c["relay_step_worst_mean_ms"] / one
    return out


def bench_c(sc: Scenario, settings: NmpcSettings | None = None, *, rounds: int = 3,
            say: Callable[[str], None] = lambda s: None) -> dict:
    """The first relay's controller step timed in Python and as the C tree of ``codegen`` on the same mission,
    alternating, ``rounds`` times, pinned to one core (``assembly.codegen.bench_c``)."""
    res = codegen_bench_c(sc, settings, rounds=rounds, say=say)
    res["machine"] = f"{platform.machine()} {platform.processor() or ''} python {platform.python_version()}".strip()
    res["scenario"] = f"{sc.name} (relay {sc.relay_list[0].name}, {sc.planner} planner)"
    return res


def export(run_dir: str | Path, fmt: str = "mcap", *, relay: str | None = None,
           origin: tuple[float, float, float] | None = None) -> list[Path]:
    """Write a run folder's flight in ``fmt``: ``mcap`` (``run.mcap`` with Foxglove's schemas, into the folder), or
    ``csv``, ``plan``, ``geojson``, ``kml``, ``ulog`` into its ``export/`` (``report.flight_export``: per relay, or
    every vehicle's track; ``relay``: that relay only). ``origin`` ``(lat_deg, lon_deg, alt_m)``: where the run's local
    frame sits on the earth (default: its scenario's ``[geo] origin``); ``plan``, ``geojson`` and ``kml`` need one.
    Every check (the folder, the format, the relay, the origin) runs before anything is written. Returns the files."""
    d = Path(run_dir)
    if fmt not in ("mcap", *EXPORT_FORMATS):
        raise ValueError(f"--format: one of mcap, {', '.join(EXPORT_FORMATS)}; got {fmt!r}")
    if not is_own_folder(d, "run"):
        raise OutputError(f"{d}: not an aerorelay run folder (no {SCENARIO_FILE} + {METRICS_FILE})")
    sc, _, df = read_scenario(d), read_metrics(d), read_timeseries(d)
    if fmt == "mcap":
        if relay is not None or origin is not None:
            raise ValueError("--relay and --origin apply to csv, plan, geojson, kml and ulog; run.mcap holds the whole run")
        write_layout(df.columns, sc.channel.capacity_unit, d / LAYOUT_FILE)  # the panels name this run's series
        bound = pd.read_parquet(d / BOUND_PARQUET) if (d / BOUND_PARQUET).is_file() else None
        return [write_run_mcap(df, sc, d / MCAP_FILE, bound)]
    relays = [r.name for r in sc.relay_list]
    if relay is not None and relay not in relays:
        raise ValueError(f"--relay: no relay {relay!r} in this run ({', '.join(relays)})")
    gone = missing_columns(df, [relay] if relay is not None else [*relays, *(s.name for s in sc.source_list)])
    if gone:
        raise OutputError(f"{d / TIMESERIES_FILE}: the columns {', '.join(gone[:6])}{' ...' if len(gone) > 6 else ''} "
                          "are missing: not a whole run's time series (nothing was written)")
    who = vehicles(df, relays, [s.name for s in sc.source_list])  # the vehicles that flew (a spare that waited: none)
    if relay is not None and relay not in who:
        raise OutputError(f"--relay: {relay!r} never flew in this run (a spare that waited, or its columns are missing): "
                          "nothing to export")
    where = origin if origin is not None else (tuple(sc.geo.origin) if sc.geo is not None else None)
    if where is not None and not (len(where) == 3 and -90.0 <= where[0] <= 90.0 and -180.0 <= where[1] <= 180.0
                                  and math.isfinite(where[2])):
        raise ValueError(f"--origin: lat in [-90, 90] deg, lon in [-180, 180] deg, a finite altitude (m); got {where}")
    if where is None and fmt in EXPORT_GEOGRAPHIC:
        raise ValueError(f"--format {fmt} needs the run's place on the earth: [geo] origin in its scenario, or --origin "
                         "lat_deg,lon_deg,alt_m")
    frame = GeoFrame(where) if where is not None else None
    out = d / EXPORT_FOLDER
    if out.is_symlink() or (os.path.lexists(out) and not out.is_dir()):  # never written through, never replaced
        raise OutputError(f"{out}: {'a symbolic link' if out.is_symlink() else 'a file'} is in the way of the run "
                          "folder's export folder: move it away (nothing was written)")
    out.mkdir(exist_ok=True)
    chosen = [relay] if relay is not None else [n for n, role in who.items() if role == "relay"]
    if not chosen:
        raise OutputError(f"{d}: no relay of this run flew: nothing to export")
    if fmt == "csv":
        return [write_flight_csv(df, n, frame, out / f"{n}.csv") for n in (chosen if relay else list(who))]
    if fmt == "plan":
        return [write_plan(df, n, frame, out / f"{n}.plan") for n in chosen if frame is not None]
    if fmt == "ulog":
        return [write_ulog(df, n, frame, out / f"{n}.ulg", __version__) for n in chosen]
    tracks = {n: who[n] for n in chosen} if relay is not None else who
    assert frame is not None
    outlines = [(str(o.name), *outline(obstacle_model(o, margin=False))) for o in sc.obstacle_list]  # the buildings too
    if fmt == "geojson":
        return [write_geojson(df, tracks, frame, out / "tracks.geojson", outlines)]
    start = datetime.datetime.fromtimestamp((d / SCENARIO_FILE).stat().st_mtime, datetime.UTC).isoformat()
    return [write_kml(df, tracks, frame, out / "tracks.kml", start, outlines)]


@dataclass
class Reproduction:
    """What ``reproduce`` did: the studies and runs, the campaign's outcome, the summary it wrote."""

    studies: list[Study]
    runs: list
    campaign: CampaignResult
    summary: dict
    report: Path


log = logging.getLogger(__name__)
CAMPAIGN_FILE = "campaign.json"  # which studies a campaign folder holds, and whether in quick mode


def _write_report(chosen: list[Study], specs: list, out: Path, meta: dict) -> dict:
    manifest = load_manifest(out)
    meta = {**meta, "runs_total": len(specs), "runs_finished": sum(is_finished(out, s) for s in specs),
            "runs_failed": sum(manifest.get(s.key, {}).get("status") == RunStatus.FAILED for s in specs),
            "runs_unsafe": sum(manifest.get(s.key, {}).get("status") == RunStatus.UNSAFE for s in specs),
            "runs_compute_s": sum(manifest.get(s.key, {}).get("wall_s") or 0.0 for s in specs),
            "controller": NmpcSettings().fingerprint()}
    summary = summarize(chosen, specs, out, {"campaign": meta})
    write_atomic(out / "summary.json", strict_json.dumps(summary, indent=1, default=str))
    write_atomic(out / "report.html", render_report(summary, chosen, specs, out, manifest))
    return summary


def _campaign_info(out: Path) -> dict:
    """Studies and quick mode of a campaign folder: its campaign.json, or (older folders) the study
    names in its manifest and the mode in its summary.json."""
    try:
        return json.loads((out / CAMPAIGN_FILE).read_text())
    except (OSError, ValueError):
        pass
    studies = sorted({r["study"] for r in load_manifest(out).values() if "study" in r})
    if not studies:
        raise StudyError(f"{out}: no campaign here (no {CAMPAIGN_FILE}, no runs in manifest.json): run aerorelay reproduce first")
    try:
        quick = bool(json.loads((out / "summary.json").read_text())["campaign"]["quick"])
    except (OSError, ValueError, KeyError, TypeError):
        quick = False
    return {"studies": studies, "quick": quick}


def default_studies_dir() -> Path:
    """``experiments/`` in the working directory, else the repository's own."""
    here = Path("experiments")
    return here if here.is_dir() else Path(__file__).resolve().parents[2] / "experiments"


def report_run(run_dir: str | Path) -> Path:
    """Render ``report.html`` of one run folder (its metrics with units, safety verdict, figures)."""
    d = Path(run_dir)
    if folder_kind(d) != "run" or not (d / METRICS_FILE).is_file():
        raise OutputError(f"{d}: not an aerorelay run folder (no {SCENARIO_FILE} + {METRICS_FILE})")
    write_atomic(d / RUN_REPORT, render_run_report(d))
    return d / RUN_REPORT


def report(out: str | Path, *, studies_dir: str | Path | None = None) -> dict:
    """Render ``report.html`` and ``summary.json`` of a campaign folder from whatever runs are
    finished (partial studies marked as such); the summary is returned. The studies are read from
    ``studies_dir``, else from the folder the campaign was run with (its campaign.json), else
    ``experiments/``."""
    out = Path(out)
    info = _campaign_info(out)
    folder = Path(studies_dir or info.get("studies_dir") or default_studies_dir())
    chosen = find_studies(folder, info["studies"])
    specs = [r for st in chosen for r in expand(st, folder.resolve().parent, quick=info["quick"])]
    if info.get("runs") is not None:  # a budgeted campaign: the runs it chose
        keep = set(info["runs"])
        specs = [s for s in specs if s.key in keep]
    meta = {"version": __version__, "date": datetime.datetime.now().isoformat(timespec="seconds"), "quick": info["quick"],
            "runs_ran": 0, "runs_skipped": 0, "wall_s": 0.0, "notices": info.get("notices", [])}
    return _write_report(chosen, specs, out, meta)


def reproduce(studies: list[str] | None = None, *, out: str | Path, quick: bool = False, studies_dir: str | Path = "experiments",
              scheduler: str | None = None, workers: int | None = None, progress=None, on_start=None,
              wait: bool = False, budget_s: float | None = None, plugins: Sequence[str] = ()) -> Reproduction:
    """Run the named studies (default: all in ``studies_dir``) as a campaign on dask (resuming a
    previous one in ``out``), then write ``report.html`` and ``summary.json``. ``on_start(n_runs,
    n_studies)`` is called once the studies are expanded. ``budget_s``: keep only the runs whose
    estimated wall time fits (``experiments.budget``; the others are named in the notices and in
    the report as left out). ``plugins``: modules (or ``.py`` files) of users' planners, imported here and by every
    worker before its first run (``planning.plugins``)."""
    folder, out = Path(studies_dir), Path(out)
    found = tuple(resolve_plugin(p) for p in plugins)  # every one named before any work
    load_plugins(found)
    chosen = find_studies(folder, studies or None)
    notices: list[str] = []
    specs = [replace(r, plugins=found)
             for st in chosen for r in expand(st, folder.resolve().parent, quick=quick, notices=notices)]
    selected = None
    if budget_s is not None:
        choice = within_budget(specs, budget_s, workers or os.cpu_count() or 1)
        specs, selected = choice.kept, [s.key for s in choice.kept]
        notices += left_out_notices(choice, budget_s)
    for n in notices:
        log.warning("%s", n)
    if on_start is not None:
        on_start(len(specs), len(chosen))
    if workers is not None and workers < 1:
        raise ValueError(f"--workers: must be >= 1, got {workers}")
    check_output_folder(out, "campaign")
    date = datetime.datetime.now().isoformat(timespec="seconds")
    out.mkdir(parents=True, exist_ok=True)
    mark(out, "campaign")
    write_atomic(out / CAMPAIGN_FILE, strict_json.dumps({"studies": [st.name for st in chosen], "quick": quick,
                                                          "studies_dir": str(folder.resolve()), "runs": selected,
                                                          "notices": notices}))
    try:
        res = run_campaign(specs, out, scheduler=scheduler, n_workers=workers, progress=progress, wait=wait)
    except KeyboardInterrupt:  # the runs that finished are reported before the interrupt goes on
        _write_report(chosen, specs, out, {"version": __version__, "date": date, "quick": quick, "interrupted": True})
        raise
    meta = {"version": __version__, "date": date, "quick": quick, "runs_ran": res.ran, "runs_skipped": res.skipped,
            "wall_s": res.wall_s, "notices": notices}
    summary = _write_report(chosen, specs, out, meta)
    return Reproduction(chosen, specs, res, summary, out / "report.html")


def design(sc: Scenario, out: str | Path, *, relays: Sequence[int] = (1, 2, 3), schedules: Sequence[str] = ("tdma",),
           bound: bool = True, by: str = "c_mean", scheduler: str | None = None, workers: int | None = None,
           progress=None, on_start=None, wait: bool = False) -> dict:
    """How many relays ``sc``'s mission needs and under which schedule (``experiments.design``): for each count in
    ``relays`` and each of ``schedules``, capacity-seeking relays the tool places, flown with their bound and the
    direct link, as a campaign in ``out`` (resumable; on dask: ``scheduler`` or ``workers`` local ones);
    ``on_start(n_runs, estimate_s)`` before the first run (the estimated wall time on the workers, ``experiments.budget``),
    ``progress(done, total, record)`` after each. Writes ``design.json``, ``design.png`` and ``recommended.toml`` (the
    best flown by ``by``, ``c_mean`` or ``c_min``); returns ``design.json``'s content. Every point is validated before
    any work."""
    runs = design_runs(sc, list(relays), list(schedules), bound=bound)
    if by not in DESIGN_BY:
        raise ValueError(f"--by: {by!r}: one of {', '.join(DESIGN_BY)}")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers: must be >= 1, got {workers}")
    specs = [r.spec for r in runs]
    out = Path(out)
    check_output_folder(out, "campaign")
    n = workers or os.cpu_count() or 1
    if on_start is not None:
        seen: set[str] = set()
        on_start(len(specs), sum(run_cost_s(s, seen) for s in specs) / min(n, len(specs)))
    run_campaign(specs, out, scheduler=scheduler, n_workers=workers, progress=progress, wait=wait)
    summary = summarize_design(out, runs, by)
    write_design(out, runs, summary, sc.channel.capacity_unit)
    return summary


# ---------------------------------------------------------------- what the command line calls
parse_sets = _parse_sets  # "--set" items -> dotted keys and values (ScenarioError naming a malformed one)
si = _si  # a value with its unit and an SI prefix (310 kbit/s)
metric_unit = _metric_unit
metric = _metric  # a dotted metric of a metrics dict


def updated(sc: Scenario, updates: dict) -> Scenario:
    """``sc`` with dotted-key updates, validated like a scenario file, its parts' checks included."""
    return _updated(sc, updates) if updates else sc


def solver_settings(sc: Scenario, **overrides) -> NmpcSettings:
    """The NMPC's solver settings of ``sc`` with ``NmpcSettings`` fields overridden (None: kept)."""
    return nmpc_settings(sc, **overrides)


def check_run(sc: Scenario, out: str | Path, *, figures: bool = True, bound: bool = False) -> None:
    """Every check a run makes before flying: its log fits the machine's memory, with ``bound`` the
    scenario's bound fits it and ``bound.max_minutes`` (ScenarioError), and ``out`` can take the run
    folder with room for it (OutputError)."""
    check_run_size(sc)
    check_not_injected(sc)
    if bound:
        check_bound_size(sc)
    check_output_folder(out, "run", need_bytes=output_bytes(sc, figures=figures))


def codegen(sc: Scenario, out: str | Path, *, record: str | Path | None = None, fly: bool = False,
            planner: bool = True, offboard: bool = False, relay: str | None = None, prefix: str = "ar") -> dict:
    """Write the C tree of relay ``relay``'s controller into ``out`` (``assembly.codegen.write_tree``: a new or empty
    folder; ``relay`` None: the scenario's only relay, a network's is named), every C name beginning with ``prefix``
    (``ar_step``: ``<prefix>_step``; one per relay's tree to link several into one program). ``record`` and ``fly``
    stand the tree in for that relay's controller (a network's other relays fly Python's).
    ``record``: fly ``sc`` and record that controller's steps there (``ar_replay.c``'s events) and the Python
    controller's brake-law flags and commands beside (``<record>.expected``). ``fly``: build the tree's shared library
    and fly ``sc`` with its commands (the Python controller beside it on the same inputs), the flight's metrics and the
    largest difference from Python's commands in the summary and in ``out/fly.json``. ``planner``: the paper's planner
    in the tree where the relay flies it (``ar_plan``: then ``record`` keeps what it was given and ``fly`` flies its
    stage parameters). ``offboard``: the tree of the vehicle an autopilot flies, with the example that flies a MAVLink
    vehicle in OFFBOARD through the library (``tools/offboard.c``, ``make offboard``; not with ``record`` or ``fly``,
    which fly aerorelay's own plant). Returns the tree's summary."""
    if record is not None or fly:  # the tree stands in for Python's controller, the reference it is compared with
        refuse_c_engines(sc, "codegen --record / --fly compare the tree with Python's controller flying the relay")
    if offboard and (record is not None or fly):
        raise ValueError("codegen: --offboard writes the controller of the vehicle an autopilot flies (thrust along body "
                         "z); --record and --fly fly aerorelay's own plant with the scenario's: write them as two trees")
    if record is not None:  # the recording and its two sidecars: new, or an earlier recording of this program's
        for f in (Path(record), Path(f"{record}.expected"), Path(f"{record}.params")):
            check_own_file(f, "--record", is_recording, "a recording of controller steps")
    tree = write_tree(sc, Path(out), planner=planner, offboard=offboard, relay=relay, prefix=prefix)
    summary: dict = {"folder": str(tree.folder), "files": tree.files, "nx": tree.nx, "nr": tree.nr,
                     "n_params": tree.n_params, "horizon": tree.horizon, "planner": tree.planner,
                     "no_planner_because": tree.no_planner_because, "relay": tree.relay, "prefix": tree.prefix}
    flown: dict = {}

    def fly_c(s: Scenario, install=None) -> RunResult:
        controller = CController(build_shared(tree), tree)
        shadow = Shadow(planned=tree.planner)
        flying = flown_by_c(controller, shadow)

        def both(control) -> None:  # the recorder first (it steps Python's controller), the C flight around it
            if install is not None:
                install(control)
            flying(control)

        try:
            r = simulate(s, bound=False, install=both)
        finally:
            controller.close()
        m = r.metrics
        flown.update({k: m.get(k) for k in ("c_min", "c_mean", "unsafe", "unsafe_reason", "steps", "fallback_episodes",
                                            "safety_violations")},
                     simd=tree.simd, c_steps=shadow.steps, c_fallback_steps=shadow.fallback_steps,
                     max_difference=shadow.max_difference, fallback_disagreements=shadow.fallback_disagreements,
                     planned_in_c=shadow.planned, max_parameter_difference=shadow.max_parameter_difference)
        return r

    fly_or_simulate = fly_c if fly else (lambda s, install=None: simulate(s, bound=False, install=install))
    if record is not None:
        summary["recorded"] = int(len(record_calls(sc, Path(record), simulate=fly_or_simulate, relay=tree.relay,
                                                   fly=tree.planner)))
    elif fly:
        fly_c(sc)
    if fly:
        summary["flown"] = flown
        (tree.folder / "fly.json").write_text(json.dumps(flown, indent=2, default=float) + "\n")
    return summary


def flight_estimate(sc: Scenario) -> tuple[float, int]:
    """A flight's estimated wall time here (s, its bound left out) and the traces it takes (``experiments.budget``);
    above ``sim.max_minutes`` the run is refused before any work (``check_run``)."""
    return flight_seconds(sc)


def check_output(out: str | Path, kind: str) -> None:
    """``out`` can take this program's ``kind`` of output (run, bound, campaign): OutputError otherwise."""
    check_output_folder(out, kind)


def write_bound(sc: Scenario, out: str | Path, progress: Callable[[int, int], None] | None = None) -> dict:
    """The bound of ``sc`` written as a bound folder (bound.json, bound.parquet, bound.png), one
    writer at a time (OutputBusyError); returns bound.json's summary."""
    with writing(out) as folder:
        b = bound(sc, progress)
        tmp = new_sibling(folder)
        summary = write_bound_files(b, tmp)
        (fig_network_bound if isinstance(b, NetworkBound) else fig_bound)(b.frame(), sc).savefig(tmp / "bound.png", dpi=110)
        swap_in(tmp, folder, "bound")
    return summary


def strict_json_text(data, indent: int = 2) -> str:
    """``data`` as strict JSON (no NaN / Infinity: null, with the reason under ``null_reasons``)."""
    return strict_json.dumps(data, indent=indent)


def is_run_folder(folder: str | Path) -> bool:
    """Whether ``folder`` is one run's folder (not a campaign's or a bound's)."""
    return folder_kind(Path(folder)) == "run"


def run_metrics_file(run_dir: str | Path) -> Path:
    """A run folder's metrics.json."""
    return Path(run_dir) / METRICS_FILE


def finished_runs(out: str | Path) -> int:
    """How many runs of a campaign folder are recorded done."""
    return sum(r.get("status") == RunStatus.DONE for r in load_manifest(Path(out)).values())


output_lock = writing  # hold a run or bound folder's one-writer lock (OutputBusyError when another process writes it)

__all__ = ["CampaignBusyError", "OutputBusyError", "OutputError", "Result", "Scenario", "ScenarioError",
           "StudyError", "bench", "bound", "check_output", "check_run", "default_studies_dir", "export",
           "finished_runs", "is_run_folder", "link_budget", "link_budget_lines", "load_scenario", "metric",
           "metric_unit", "output_lock", "parse_sets", "report", "report_run", "reproduce", "run_metrics_file", "si",
           "simulate", "solver_settings", "strict_json_text", "updated", "write_bound"]
