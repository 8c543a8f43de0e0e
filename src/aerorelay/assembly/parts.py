"""The composition root: a validated ``Scenario`` -> the parts a mission is made of.

The only module that knows both the configuration (``config``) and the parts. ``models``, ``planning``,
``control`` and ``sim`` take parts (a vehicle, a radio scene, a path, settings dataclasses),
never a ``Scenario``. The vehicle is built once per mission (its hover-tilt limits are cached on
it) and shared by the planner, the controller, the plant and the bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..config import AntennaConfig, JammerConfig, Scenario, ScenarioError
from ..config.network import ANY_BASE_STATION, BaseStationConfig
from ..config.radio import NodeAntennaConfig
from ..control.network import LoopRelay
from ..control.nmpc import NmpcSettings
from ..control.ocp import OcpSpec
from ..control.relay import FailsafeSettings, RelayController
from ..control.relay_step import RelayStep, StaleSettings
from ..control.supervisor import SafetyEnvelope
from ..estimation.jammer_estimator import EstimatorSettings, JammerEstimator, Receiver
from ..models.antenna import (
    AntennaPattern,
    CosinePattern,
    DipolePattern,
    FlippedPattern,
    IsotropicPattern,
    NodePatterns,
    SinPowerPattern,
)
from ..models.axes import axis_cone
from ..models.battery import Battery
from ..models.jammer import AlwaysOn, Jammer, PeriodicOnOff
from ..models.mission import CirclePath, LinearPath, MinimumJerkPath, RepeatingPath, SourceTrajectory, source_trajectory
from ..models.propagation import PathGain, RmaAvPathGain, free_space_loss_db
from ..models.radio import Antenna, LinkBudget, Node, RadioScene
from ..models.raytrace import RayTracingUnavailable, check_scene
from ..models.vehicle import Multirotor
from ..planning import registry  # noqa: F401  (registers the built-in planners)
from ..planning.base import (
    CapacityPlannerSettings,
    GeneratorSettings,
    Planner,
    PlannerContext,
    PlannerSettings,
)
from ..planning.bound import BoundProblem, BoundResolution, CapacityBound, bound_key, cached_bound, compute_bound
from ..planning.bound_cost import (
    BoundCost,
    check_bound_cost,
    network_bound_cost,
    single_bound_cost,
    traced_bound_cost,
    traced_network_bound_cost,
)
from ..planning.capacity_planner import shaper_settings
from ..planning.fleet import FleetPlanner, NetworkPlannerContext, OneRelayPlanner
from ..planning.home import HomeSettings
from ..planning.keep_out import KeepOutPlanner
from ..planning.network_bound import (
    NETWORK_BOUND_VERSION,
    NetworkBound,
    NetworkBoundProblem,
    compute_network_bound,
    spliced,
)
from ..planning.traced_network_bound import compute_traced_network_bound
from ..sim.air import Air
from ..sim.closed_loop import ClosedLoop, SimSettings, plant_step_function
from ..sim.handover import HandoverRule
from ..sim.initial import start_poses
from ..sim.jammer_sensing import JammerSensing
from ..sim.perturbations import PerturbationSettings, large_scale_realization
from . import world
from .checks import check_physics
from .planners import comms_aware, planner_of, tracking
from .vehicle import build_vehicle

LAND_SPEED_M_S = 0.5  # a spare without a battery table lands at this speed (m/s; the battery table's default)
ROLE_NAMES = {"bs": "base_station", "source": "source", "relay": "relay"}


def build_jammer(cfg: JammerConfig) -> Jammer:
    """A jammer from its ``[jammer]`` / ``[[jammers]]`` table."""
    sched = AlwaysOn() if cfg.schedule == "always_on" else PeriodicOnOff(cfg.on_s, cfg.off_s)
    path: SourceTrajectory | None = cfg.track()  # a track file (CSV, .plan, GPX), else its circle or waypoints
    if path is None and cfg.path == "circle":
        assert cfg.center_m is not None and cfg.radius_m is not None and cfg.period_s is not None  # validated
        path = CirclePath(cfg.center_m, cfg.radius_m, cfg.period_s, cfg.clockwise)
    elif path is None and cfg.waypoints is not None:
        leg = LinearPath(cfg.waypoints) if cfg.path == "linear" else MinimumJerkPath(cfg.waypoints)
        path = RepeatingPath(leg) if cfg.repeat else leg
    pattern: AntennaPattern = IsotropicPattern(1.0)
    if cfg.pattern == "cosine":
        pattern = CosinePattern(cfg.g_max, cfg.exponent, cfg.back_lobe)
    boresight = np.array(cfg.boresight, float) / np.linalg.norm(cfg.boresight) if cfg.boresight is not None else np.array([0.0, 0.0, 1.0])
    return Jammer(position=np.array(cfg.position, float), power=cfg.peak_power_w, schedule=sched,
                  localization_delay=cfg.localization_delay_s, path=path, pattern=pattern, point_at=cfg.point_at,
                  boresight=boresight, name=cfg.name)


def jammer_table(j: Jammer) -> dict | None:
    """The ``[[jammers]]`` table that builds ``j`` again (``build_jammer``), or None when a table cannot say
    it (a schedule, path or pattern of a user's own class, a phase-shifted schedule, a scaled isotropic
    antenna): what a run flown with jammers passed from Python writes into its ``scenario.toml``."""
    t: dict = {"name": j.name, "position": [float(v) for v in j.position], "power_w": float(j.power),
               "localization_delay_s": float(j.localization_delay)}
    if isinstance(j.schedule, PeriodicOnOff) and j.schedule.phase_s == 0.0:
        t |= {"schedule": "on_off", "on_s": float(j.schedule.on_s), "off_s": float(j.schedule.off_s)}
    elif not isinstance(j.schedule, AlwaysOn):
        return None
    path, repeat = j.path, False
    if isinstance(path, RepeatingPath):
        path, repeat = path.path, True
    if isinstance(path, CirclePath) and not repeat:
        t |= {"path": "circle", "center_m": [float(v) for v in path.center], "radius_m": path.r, "period_s": path.period,
              "clockwise": path.clockwise}
    elif type(path) in (LinearPath, MinimumJerkPath):
        assert isinstance(path, LinearPath | MinimumJerkPath)
        t |= {"path": "linear" if isinstance(path, LinearPath) else "minimum_jerk", "repeat": repeat,
              "waypoints": [[float(tk), *map(float, pk)] for tk, pk in zip(path.t, path.p, strict=True)]}
    elif path is not None:
        return None
    if isinstance(j.pattern, CosinePattern):
        t |= {"pattern": "cosine", "g_max": j.pattern.g_max, "exponent": j.pattern.exponent, "back_lobe": j.pattern.back_lobe}
        t |= {"point_at": j.point_at} if j.point_at else {"boresight": [float(v) for v in j.boresight]}
    elif not (isinstance(j.pattern, IsotropicPattern) and j.pattern.g_bar == 1.0):
        return None
    return t


def relay_pattern(cfg: AntennaConfig) -> AntennaPattern:
    """The relay's pattern: a dipole (or sin^n) scaled by the directivity."""
    g = cfg.g_bar * cfg.directivity
    if cfg.pattern == "dipole":
        return DipolePattern(g)
    return SinPowerPattern(cfg.exponent, g)


def node_patterns(cfg: AntennaConfig) -> NodePatterns:
    """Every node's pattern from ``[antenna]``; the trajectory generator's surrogate does not use
    them (eq. 12-13)."""
    dipole = relay_pattern(cfg)
    bs = {"dipole": dipole, "isotropic": IsotropicPattern(cfg.g_bar),
          "cosine": CosinePattern(cfg.bs_g_max, cfg.bs_exponent, cfg.bs_back_lobe)}[cfg.bs_pattern]
    return NodePatterns(relay=dipole, source=dipole if cfg.source_pattern == "dipole" else IsotropicPattern(cfg.g_bar),
                        bs=bs)


def own_pattern(cfg: NodeAntennaConfig | None, shared: AntennaConfig) -> AntennaPattern | None:
    """A vehicle's own pattern (``antenna = {...}`` on its relay or source; None: the shared one),
    dipoles scaled by ``[antenna] directivity`` as the shared ones are."""
    if cfg is None:
        return None
    pattern: AntennaPattern
    if cfg.pattern == "dipole":
        pattern = DipolePattern(cfg.g_bar * shared.directivity)
    elif cfg.pattern == "sin_power":
        pattern = SinPowerPattern(cfg.exponent, cfg.g_bar)
    elif cfg.pattern == "isotropic":
        pattern = IsotropicPattern(cfg.g_bar)
    else:
        pattern = CosinePattern(cfg.g_bar, cfg.exponent, cfg.back_lobe)
    return FlippedPattern(pattern) if cfg.down else pattern  # mounted down body z (axis = [0, 0, -1])


def _base_station_node(b: BaseStationConfig, shared: AntennaConfig, shared_pattern: AntennaPattern) -> Node:
    """A base station: its own antenna and axis (``[[base_stations]]``), else ``[antenna]``'s base station's."""
    axis = np.array(b.axis if b.axis is not None else shared.bs_antenna_axis(), float)
    return Node(b.name, "base_station", Antenna(own_pattern(b.antenna, shared) or shared_pattern, axis / np.linalg.norm(axis)),
                np.array(b.position, float))


def relay_node(sc: Scenario, name: str) -> Node:
    """Relay ``name``'s radio node: its own antenna, else ``[antenna]``'s (a spare's, for when it takes over)."""
    r = next(r for r in sc.relay_list if r.name == name)
    return Node(r.name, "relay", Antenna(own_pattern(r.antenna, sc.antenna) or node_patterns(sc.antenna).relay))


def build_scene(sc: Scenario, jammers: list[Jammer] | None = None) -> RadioScene:
    """The radio scene: base station 'bs' (fixed, its antenna axis ``antenna.bs_antenna_axis()``), source
    'source' (MRAV-2) and relay 'relay' (MRAV-1) or the fleet's sources and relays by name, antennas along
    body z; the routes (``[network]``); every jammer."""
    pat = node_patterns(sc.antenna)
    nodes = (*(_base_station_node(b, sc.antenna, pat.bs) for b in sc.base_station_list),
             *(Node(s.name, "source", Antenna(own_pattern(s.antenna, sc.antenna) or pat.source)) for s in sc.source_list),
             *(relay_node(sc, r.name) for r in sc.relay_list if not r.standby))
    ch = sc.channel
    jams = tuple(jammers) if jammers is not None else tuple(build_jammer(j) for j in sc.jammer_configs)
    stations = tuple(sc.base_station_names)
    # a route to "any" of several base stations serves from the first until the network's handover rule picks
    ends = tuple(stations if r[-1] == ANY_BASE_STATION and len(stations) > 1 else () for r in sc.route_list)
    routes = tuple(tuple(r[:-1]) + (stations[0] if r[-1] == ANY_BASE_STATION else r[-1],) for r in sc.route_list)
    scene = RadioScene(nodes, jams, LinkBudget(*ch.link_budget_values()), routes[0], path_gain(ch),
                       routes=routes if len(routes) > 1 else (), handover=ends if any(ends) else (),
                       schedule=sc.network.schedule, self_interference_db=sc.network.self_interference_db,
                       skips=tuple(r[1:-1] for r in routes) if sc.network.route_selection == "subsets" else ())
    if jammers is None and any(j.inr_db_at_relay_start is not None for j in sc.jammer_configs):
        scene = _powers_for_inr(scene, sc)
    return scene


def _powers_for_inr(scene: RadioScene, sc: Scenario) -> RadioScene:
    """The scene with each ``inr_db_at_relay_start`` jammer's peak power set so that its
    interference-to-noise ratio at the relay's start is that (level attitudes at t = 0, as
    ``aerorelay info`` evaluates it: the channel's interference per unit power, one jammer at a time)."""
    relay = scene.name_of("relay")  # the first relay: a fleet's INR is set at r1's start
    poses = start_poses(scene, sc.starts)  # every vehicle of the network at its start (a spare waits outside it)
    hop = next(k for k, (_, rx) in enumerate(scene.hops) if rx == relay)
    out = []
    for i, (j, cfg) in enumerate(zip(scene.jammers, sc.jammer_configs, strict=True)):
        if cfg.inr_db_at_relay_start is None:
            out.append(j)
            continue
        unit = np.zeros(len(scene.jammers))
        unit[i] = 1.0
        g = float(scene.evaluate(0.0, poses, jammer_powers=unit).interference[hop])
        if not g > 0:
            raise ScenarioError(f"{sc.jammer_field(i)}.inr_db_at_relay_start: jammer {j.name!r}: the relay's start is in a "
                                "null of the jammer-relay link (zero gain); give power_w instead")
        out.append(replace(j, power=10.0 ** (cfg.inr_db_at_relay_start / 10.0) * scene.budget.noise_power / g))
    return replace(scene, jammers=tuple(out))


def check_buildable(sc: Scenario) -> Scenario:
    """The checks that need the scenario's parts, made when it is loaded, before any work: the radio
    scene builds (a jammer set by ``inr_db_at_relay_start`` must not sit in a null of the relay's
    start), and a fleet asks only for what a fleet flies. Raises ScenarioError naming the field;
    returns ``sc``."""
    build_scene(sc)
    planner_registered(sc)
    one_base_station_planners(sc)
    comms_aware_antennas(sc)
    ray_traced_scene(sc)
    return sc


def ray_traced_scene(sc: Scenario) -> None:
    """A ray-traced channel's scene loads (the ``rt`` extra installed, the scene's name or file known)."""
    prop = sc.channel.propagation
    if prop.model != "ray_traced":
        return
    try:
        check_scene("empty" if prop.scene == "obstacles" else str(prop.scene))  # the generated one is written at build
    except RayTracingUnavailable as exc:
        raise ScenarioError(f"channel.propagation.model: {exc}") from None
    except ValueError as exc:
        raise ScenarioError(f"channel.propagation.scene: {exc}") from None


def comms_aware_antennas(sc: Scenario) -> None:
    """The paper's comms-aware NMPC keeps each link off its relay's antenna axis (the misalignment terms,
    eq. 21-22): right for a doughnut (dipole, sin^n), wrong for a cosine or isotropic antenna; a relay
    with one of those is a named error there (it flies the capacity planner or the unconstrained NMPC)."""
    for i, r in enumerate(sc.relay_list):
        if r.antenna is not None and not r.antenna.doughnut and comms_aware(sc.relay_view(i)):
            raise ScenarioError(f"relays[{i}].antenna: a {r.antenna.pattern} antenna on relay {r.name!r} with the paper's "
                                "comms-aware NMPC, whose misalignment terms keep links off a doughnut antenna's axis; fly it "
                                "with controller.planner = 'capacity' or controller.variant = 'unconstrained'")


GENERATORS = ("trajectory_generator", "isotropic")  # planners that plan toward one base station's position


def one_base_station_planners(sc: Scenario) -> None:
    """The paper's generator (and baseline A) plan toward one base station: with routes that may hand
    over (``"any"``) or that end at different base stations, a named error (fly the capacity planner)."""
    ends = {r[-1] for r in sc.route_list}
    if not sc.has_route_choice and len(ends) == 1:
        return
    why = ("routes that end at 'any' base station" if sc.has_handover else
           "routes that may skip relays (network.route_selection = 'subsets')" if sc.has_route_choice else
           f"routes ending at {sorted(ends)}")
    field = sc.controller_field(0, ("planner",))  # a relay's own is refused in a network: written, it is the one relay's
    name = sc.planner
    if name in GENERATORS:
        raise ScenarioError(f"{field}: {name!r} plans toward one base station's position; with {why} fly "
                            "'capacity' (it scores every base station a route may end at)")


def planner_registered(sc: Scenario) -> None:
    """``controller.planner`` names a registered planner (``planning.base.PLANNERS``: the built-ins and any registered
    before loading) that can plan the scenario: a network's needs a network factory; a named error otherwise."""
    try:
        entry = planner_of(sc)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    if sc.shape.plans == "network" and entry.network is None:  # one relay flies either factory
        raise ScenarioError(f"controller.planner: {sc.planner!r} plans one relay (registered with register_planner); a "
                            f"network of {len(sc.relay_list)} relays and {len(sc.source_list)} sources needs a network "
                            "planner (register_network_planner under the same name), or pass the object to "
                            "ar.simulate(sc, planner=...) to fly the first relay with the others holding their starts")


def path_gain(ch) -> PathGain:
    """The deterministic large-scale path gain of ``[channel]`` / ``[channel.propagation]``."""
    prop = ch.propagation
    if prop.model == "rma_av":
        return RmaAvPathGain(carrier_hz=ch.carrier_hz)
    if prop.model in ("free_space", "ray_traced"):  # a traced channel is the plant's: the parts plan with free space
        return PathGain.free_space(ch.carrier_hz) if ch.physical else PathGain()
    loss = prop.reference_loss_db
    if loss is None:  # free space at d0
        loss = float(free_space_loss_db(prop.reference_distance_m, ch.carrier_hz)) if ch.physical else \
            20.0 * float(np.log10(prop.reference_distance_m))
    return PathGain.log_distance(prop.exponent, prop.reference_distance_m, loss)


def relay_start(sc: Scenario) -> np.ndarray:
    """The (first) relay's start, m (world)."""
    return np.array(sc.relay_list[0].start, float)


def build_source(sc: Scenario) -> SourceTrajectory:
    """MRAV-2's path (minimum-jerk waypoints, the user's CSV or a PX4 flight log)."""
    return source_trajectory(sc.source_list[0].mission)


def _workspace(sc: Scenario) -> tuple[np.ndarray, np.ndarray]:
    ws = sc.controller.workspace
    return np.array(ws.min, float), np.array(ws.max, float)


def ocp_spec(sc: Scenario, vehicle: Multirotor | None = None, neighbours: int = 0, p0_parameter: bool = False) -> OcpSpec:
    """The NMPC problem structure described by a scenario (``neighbours``: the other vehicles a
    fleet's relay keeps its separation from; ``p0_parameter``: its comms-aware terms look toward its
    next node on the route, a stage parameter, instead of the base station)."""
    c = sc.controller
    lo, hi = _workspace(sc)
    return OcpSpec(vehicle=vehicle or build_vehicle(sc.platform_of(0)), horizon=c.horizon, ts=c.ts_s, constrained=comms_aware(sc),
                   bs_position=_vec3(sc.first_station.position), workspace_min=_vec3(lo), workspace_max=_vec3(hi),
                   exact_input_rate=c.exact_input_rate, neighbours=neighbours, p0_parameter=p0_parameter,
                   disturbance=sc.wind is not None and sc.wind.observer, obstacles=len(sc.obstacle_list))


def _vec3(v) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def weight_parameters(sc: Scenario, spec: OcpSpec) -> dict[str, np.ndarray]:
    """The ``sw_*`` stage parameters: square roots of the weights in columns 0..N-1 and of the
    terminal weights in column N (0 for terms without a terminal part and for slacks)."""
    w: dict[str, float] = sc.controller.weights.model_dump()
    if tracking(sc):  # the tracking NMPC: [controller.capacity]'s position weights
        cap = sc.controller.capacity
        w.update(position=cap.position_weight, position_terminal=cap.position_weight_terminal)
    out = {}
    for t in spec.terms:
        stage = w[t.name]
        terminal = 0.0 if t.terminal is None else (w[f"{t.name}_terminal"] if t.own_terminal else stage)
        out[f"sw_{t.name}"] = np.sqrt(np.r_[np.full(spec.horizon, stage), terminal])
    for c in spec.soft_constraints:
        out[f"sw_slack_{c.name}"] = np.sqrt(np.r_[np.full(spec.horizon, sc.controller.q_slack), 0.0])
    return out


def nmpc_settings(sc: Scenario, **overrides) -> NmpcSettings:
    """The NMPC's solver settings for ``sc``: the defaults, with the capacity controller's QP
    iteration cap (``[controller.capacity] qp_iter_max``, ``qp_accept_tol``), then ``overrides``
    (``NmpcSettings`` fields; None values ignored)."""
    base: dict = {}
    if tracking(sc):
        cap = sc.controller.capacity
        base = {"iter_max": cap.qp_iter_max, "accept_tol": cap.qp_accept_tol}
    base.update({k: v for k, v in overrides.items() if v is not None})
    return NmpcSettings(**base)


def build_controller(sc: Scenario, vehicle: Multirotor, settings: NmpcSettings | None = None,
                     neighbours: int = 0, p0_parameter: bool = False, name: str = "") -> RelayController:
    """NMPC + fail-safe for the scenario's controller settings (``settings``: the solver's, else
    ``nmpc_settings(sc)``; ``neighbours``, ``p0_parameter``: a fleet relay's, as ``ocp_spec``) of relay ``name``."""
    spec = ocp_spec(sc, vehicle, neighbours, p0_parameter)
    fs = sc.controller.failsafe
    return RelayController(spec, weight_parameters(sc, spec), mu=sc.controller.mu,
                           failsafe=FailsafeSettings(failures_to_fallback=fs.failures_to_fallback,
                                                     successes_to_resume=fs.successes_to_resume,
                                                     workspace_margin_m=fs.workspace_margin_m),
                           settings=settings or nmpc_settings(sc), envelope=safety_envelope(sc, vehicle) if fs.supervisor else None,
                           obstacles=world.obstacles(sc), name=name)


def safety_envelope(sc: Scenario, vehicle: Multirotor) -> SafetyEnvelope:
    """The supervisor's envelope from ``[controller.failsafe]`` and the workspace box."""
    fs = sc.controller.failsafe
    lo, hi = _workspace(sc)
    return SafetyEnvelope.for_vehicle(vehicle, lo, hi, box_tolerance_m=fs.box_tolerance_m, max_tilt_deg=fs.max_tilt_deg,
                                      max_speed_m_s=fs.max_speed_m_s, max_body_rate_rad_s=fs.max_body_rate_rad_s,
                                      max_handovers=fs.max_safety_handovers, ground_z_m=sc.world.ground_z_m,
                                      obstacles=world.obstacles(sc, margin=False))


SOURCE_CLEARANCE_MARGIN_M = 0.0  # a goal keeps min_separation_m from the source (more changed the nominal flights)


def planner_context(sc: Scenario, vehicle: Multirotor, scene: RadioScene, source: SourceTrajectory) -> PlannerContext:
    """What a planner is built from: the relay's world view of the scene (no true jammer position or
    power: ``RadioScene.world_view``), MRAV-2's planned path, the vehicle, the workspace."""
    lo, hi = _workspace(sc)
    return PlannerContext(scene=scene.world_view(), source=source, vehicle=vehicle, workspace_min=lo, workspace_max=hi,
                          relay_start=relay_start(sc), duration_s=sc.duration_s, settings=planner_settings(sc),
                          surrogate_g_bar=sc.antenna.g_bar, obstacles=world.obstacles(sc),
                          source_clearance_m=sc.separation_m + SOURCE_CLEARANCE_MARGIN_M,
                          tracer=world.scoring_tracer(sc), traced_coherent=world.traced_coherent(sc))


def planner_settings(sc: Scenario) -> PlannerSettings:
    """The built-in planners' typed settings from ``[controller]`` and ``[controller.capacity]``."""
    c, cap = sc.controller, sc.controller.capacity
    return PlannerSettings(
        generator=GeneratorSettings(mu=c.mu, governor_speed_m_s=c.governor_speed_m_s, hessian_eig_floor=c.hessian_eig_floor,
                                    relative_floor=sc.hessian_floor == "relative"),
        capacity=CapacityPlannerSettings(
            speed_m_s=cap.speed_m_s, replan_every=replans_every(sc), leash_m=cap.leash_m, lookahead_s=cap.lookahead,
            axis_step_deg=cap.axis_step_deg, axis_rate_deg_s=cap.axis_rate_deg_s, margin_m=cap.margin_m,
            route_grid_m=cap.route_grid_m, route_dt_s=sc.route_dt_s, max_accel_m_s2=cap.max_accel_m_s2, brake_accel_m_s2=cap.brake_accel_m_s2,
            excursion_m=cap.excursion_m, excursion_std_m=cap.excursion_std_m, excursion_max_loss=cap.excursion_max_loss,
            yaw_rate_deg_s=cap.yaw_rate_deg_s, tilt_fraction=cap.tilt_fraction, boundary_axes=cap.boundary_axes,
            tracking_freq_rad_s=cap.tracking_freq_rad_s, scoring=cap.scoring))


def replans_every(sc: Scenario) -> int:
    """Control steps between the capacity planner's replans: ``replan_every``, and with traced scoring at least
    the channel's ``trace_period_s`` (one trace per replan), at most 50 steps."""
    cap = sc.controller.capacity
    if cap.scoring != "traced":
        return cap.replan_every
    return min(50, max(cap.replan_every, math.ceil(sc.channel.propagation.trace_period_s / sc.control_period_s - 1e-9)))


def build_planner(sc: Scenario, vehicle: Multirotor, scene: RadioScene, source: SourceTrajectory) -> Planner:
    """The one-relay planner named by ``controller.planner``."""
    factory = planner_of(sc).relay
    assert factory is not None  # build() flies a planner without a one-relay factory through its network factory
    return factory(planner_context(sc, vehicle, scene, source))


def sim_settings(sc: Scenario) -> SimSettings:
    p = sc.perturbations
    ch = sc.channel
    # the Rician K is SimSettings.fading_k_db (the closed loop puts it in)
    noise = PerturbationSettings(fading_model=ch.fading.model, shadow_std_db=ch.propagation.shadowing_std_db,
                                 decorrelation_m=ch.propagation.decorrelation_m, carrier_hz=ch.carrier_hz)
    return SimSettings(period_s=sc.control_period_s, duration_s=sc.duration_s, plant_rate_hz=sc.sim.plant_rate_hz,
                       seed=sc.seed, csi_noise_m=p.csi_noise_m,
                       process_noise_v=p.process_noise_v, process_noise_w=p.process_noise_w, fading_k_db=p.fading_k_db,
                       senses_jammer_state=sc.controller.senses_jammer_state, channel_noise=noise,
                       handover=HandoverRule(sc.network.handover_margin_db, sc.network.handover_dwell_s))


@dataclass
class Parts:
    """Everything a mission is made of, built once from a scenario: the radio scene, every relay (its
    vehicle, stepper, plant), every source's path, the network's planner, the simulation's settings, the
    jammer estimator, the air; ``relay_planner``: the one-relay planner the network's flies, if any."""

    scenario: Scenario
    scene: RadioScene
    relays: list[LoopRelay]
    sources: dict[str, SourceTrajectory]
    planner: FleetPlanner | None  # None: no relay to plan (the direct link)
    settings: SimSettings
    separation_m: float = 0.0
    sensing: JammerSensing | None = None
    air: Air | None = None  # [wind]: the wind, each relay's plant with drag, its observer
    relay_planner: Planner | None = None
    planner_name: str = "planner"  # the registered name (controller.planner), or the object's passed from Python

    def relay(self, name: str) -> LoopRelay:
        """Relay ``name``'s parts (its vehicle, stepper, plant, ...): a KeyError naming the relays otherwise."""
        for r in self.relays:
            if r.name == name:
                return r
        raise KeyError(f"no relay {name!r}; the relays: {', '.join(r.name for r in self.relays)}")

    def closed_loop(self) -> ClosedLoop:
        return ClosedLoop(scene=self.scene, relays=self.relays, sources=self.sources, planner=self.planner,
                          settings=self.settings, separation_m=self.separation_m, losses=self.scenario.losses,
                          replanner=self.replanner, sensing=self.sensing, air=self.air, planner_name=self.planner_name,
                          blockage=world.blockage(self.scenario), traced=world.traced_channel(self.scenario))

    def replanner(self, scene: RadioScene, positions, t0: float) -> FleetPlanner:
        """The planner of the network ``scene`` flies now (relays lost or gone home, spares in their places), its
        references starting where its relays are (``positions``, m, world) at ``t0`` (s)."""
        names = [n.name for n in scene.nodes if n.role == "relay"]
        routes = [[*r[:-1], ANY_BASE_STATION if e else r[-1]] for r, e in zip(scene.all_routes, scene.route_ends, strict=True)]
        sc = self.scenario.network_of(names, routes)
        kept = {n: np.asarray(positions[n], float) for n in names}
        return network_planner(sc, scene, self.relays, kept, t0)


def build(sc: Scenario, *, planner: Planner | None = None, scene: RadioScene | None = None,
          jammers: list[Jammer] | None = None, nmpc_settings: NmpcSettings | None = None,
          stale: StaleSettings | None = None, observers: bool = False) -> Parts:
    """The parts of ``sc``, for any number of relays and sources; ``planner``, ``scene`` or ``jammers``
    given here replace the ones the scenario names (objects with the same interface: see
    ``planning.base``, ``models.radio``; a planner given for a network plans its first relay, the others
    holding their starts). Every relay's step holds and lands by ``stale`` (default: on the world's ground) and, with
    ``observers`` and ``[wind]``, has its own external-force observer (a controller stepped from outside: the
    simulation's air observes in the loop instead). The scenario's physics checks run first (once per content:
    ``assembly.checks``)."""
    check_physics(sc)
    scene = scene or build_scene(sc, jammers)
    network = sc.shape.neighbours
    # every relay keeps min_separation_m from the other vehicles, the paper's one relay from its source too: the
    # verdict checks it (a planner's goal alone left the tracking lag: 1.01 m of 1.05 on a sector base station); a
    # row for each of the nearest network.separation_neighbours, whatever the network's size
    others = min(sc.vehicle_count - 1, sc.network.separation_neighbours) if sc.separation_m > 0 else 0
    relays, platforms = [], {}
    for i, r in enumerate(sc.relay_list):
        view = sc.relay_view(i)
        vehicle = build_vehicle(view.platform)
        platforms[r.name] = (vehicle, view.platform)
        controller = build_controller(view, vehicle, nmpc_settings, others,
                                      p0_parameter=(network or sc.has_handover) and comms_aware(view), name=r.name)
        stepper = RelayStep(vehicle=vehicle, controller=controller, period_s=sc.control_period_s,
                            stale=stale or StaleSettings(ground_z_m=sc.world.ground_z_m),
                            observer=world.observer(sc, vehicle) if observers else None, engine=view.controller.backend)
        bat = view.platform.battery
        battery = None if bat is None else Battery(bat.capacity_wh * 3600.0 * bat.usable_fraction, bat.reserve_fraction,
                                                   bat.avionics_w)
        cap = planner_settings(view).capacity
        # home, on the workspace's floor below its start; a spare also flies to a relay's place at its return speed (the
        # capacity planner's speed without a battery)
        home = None if (bat is None or not bat.go_home) and not r.standby else HomeSettings(
            landing_m=(r.start[0], r.start[1], float(view.controller.workspace.min[2])),
            return_speed_m_s=bat.return_speed_m_s if bat is not None else cap.speed_m_s,
            land_speed_m_s=bat.land_speed_m_s if bat is not None else LAND_SPEED_M_S,
            shaper=shaper_settings(cap, 0.0, vehicle.gravity))
        relays.append(LoopRelay(name=r.name, vehicle=vehicle, stepper=stepper, start=np.array(r.start, float), battery=battery,
                                plant=plant_step_function(vehicle, sc.sim.plant_rate_hz, sc.control_period_s), home=home,
                                spare=relay_node(sc, r.name) if r.standby else None))
    sources = {s.name: source_trajectory(s.mission) for s in sc.source_list}
    starts = {r.name: r.start for r in relays if r.spare is None}  # the network's relays (a spare waits outside it)
    relay_planner = None
    entry = planner_of(sc)
    fleet: FleetPlanner | None
    # a planner object passed in, or one relay flown by a planner with a one-relay factory: that planner flies relay 0
    if not relays:  # the direct link: no relay to plan (a planner setting is refused: config.applies' CONTROLLER)
        if planner is not None:
            raise ScenarioError("relays: none: a planner passed from Python plans relays, and this scenario has none")
        fleet = None
    elif planner is not None or (not network and entry.relay is not None):
        first = relays[0]
        route = next(r for r in sc.route_list if first.name in r)
        source = route[route.index(first.name) - 1]  # its upstream node: the paper's MRAV-2 for one relay
        if source not in sources:
            raise ScenarioError(f"relays[0]: a one-relay planner flies the first relay, {first.name!r}, as the paper's relay "
                                f"between a source and the base station; its upstream node {source!r} is a relay: list a "
                                "relay next to a source first")
        view = sc.relay_view(0)
        one: Planner = planner if planner is not None else build_planner(view, first.vehicle, scene, sources[source])
        relay_planner = one
        fleet = OneRelayPlanner(one, first.name, source,
                                              {n: p for n, p in starts.items() if n != first.name})
        if sc.obstacles:  # every planner's references kept outside the obstacles' margins
            fleet = KeepOutPlanner(fleet, world.obstacles(sc))
    else:
        fleet = network_planner(sc, scene, relays, starts)
    sensing = build_sensing(sc, scene, sources) if sc.estimates_jammers and scene.jammers else None
    name = "none (no relay)" if not relays else sc.planner if planner is None else f"{type(planner).__name__} (passed from Python)"
    return Parts(sc, scene, relays, sources, fleet, sim_settings(sc), sc.separation_m, sensing, world.air(sc, platforms),
                 relay_planner, name)


SEARCH_MARGIN_M = 10.0  # the default search box: the nodes' box widened by this horizontally, 5 m up, from the ground


def search_box(sc: Scenario, sources: dict[str, SourceTrajectory]) -> tuple[np.ndarray, np.ndarray]:
    """Where the estimator looks for jammers (m, world): ``[estimation] search_min_m/max_m``, or the box around the
    base stations, the relays' starts and the sources' paths widened by 10 m (5 m up, z >= 0), and the workspace.
    (Half the nodes' extent wider, it let the nominal's estimate settle 24 m off in a far corner of the larger box.)
    An estimate found at its edge is not trusted and says which setting to widen (``estimation.jammer_estimator``)."""
    est = sc.estimation
    if est.search_min_m is not None:
        return np.array(est.search_min_m, float), np.array(est.search_max_m, float)
    rows: list[np.ndarray] = [*(np.asarray(b.position, float) for b in sc.base_station_list),
                              *(np.array(r.start, float) for r in sc.relay_list)]
    pts = np.vstack(rows + [path.state(t).p for path in sources.values() for t in np.linspace(0.0, sc.duration_s, 50)])
    lo, hi = pts.min(axis=0) - SEARCH_MARGIN_M, pts.max(axis=0) + SEARCH_MARGIN_M
    lo[2], hi[2] = max(0.0, pts[:, 2].min() - SEARCH_MARGIN_M), pts[:, 2].max() + 0.5 * SEARCH_MARGIN_M
    ws = sc.controller.workspace
    return np.minimum(lo, ws.min), np.maximum(hi, ws.max)


def build_sensing(sc: Scenario, scene: RadioScene, sources: dict[str, SourceTrajectory]) -> JammerSensing:
    """Every relay's (and the base station's, with ``use_bs``) energy detector and the one jammer
    estimator their readings feed, whose estimate every planner shares."""
    est = sc.estimation
    names = [r.name for r in sc.relay_list if not r.standby] + (sc.base_station_names if est.use_bs else [])
    receivers = [Receiver(name=n, pattern=scene.node(n).antenna.pattern, noise_w=scene.budget.noise_power,
                          fixed=scene.node(n).position is not None)
                 for n in names]
    lo, hi = search_box(sc, sources)
    settings = EstimatorSettings(search_min=lo, search_max=hi, n_samples=est.n_samples, aggregate_steps=est.aggregate_steps,
                                 grid_m=est.grid_m, forget_s=est.forget_s, model_error_db=est.model_error_db,
                                 axis_error_deg=est.axis_error_deg, jammer_speed_m_s=est.jammer_speed_m_s,
                                 confident_std_m=est.confident_std_m, confirm_s=est.confirm_s)
    estimator = JammerEstimator(len(scene.jammers), receivers, scene.path_gain, settings, sc.control_period_s)
    return JammerSensing(scene, estimator, names, n_samples=est.n_samples, bias_db=est.bias_db, seed=sc.seed)


def bound_problem(sc: Scenario, vehicle: Multirotor | None = None, scene: RadioScene | None = None) -> BoundProblem:
    """The bound of the run: its scene, and the run's own large-scale realization (shadowing field,
    LoS states) where the channel has one, the same the plant flies through (same seed)."""
    sc = sc.relay_view(0)
    lo, hi = _workspace(sc)
    scene = scene or build_scene(sc)
    noise = sim_settings(sc).channel_noise or PerturbationSettings()
    realization = large_scale_realization(scene, noise, sc.seed)
    return BoundProblem(scene, build_source(sc), vehicle or build_vehicle(sc.platform_of(0)), lo, hi, relay_start(sc),
                        sc.duration_s, bound_resolution(sc), sc.channel.outage, realization if realization.active else None,
                        world.obstacles(sc), tracer=world.map_tracer(sc), traced_coherent=world.traced_coherent(sc))


def bound_cost(sc: Scenario) -> BoundCost:
    """What the scenario's bound (a fleet's network bound; on a ray-traced channel, its traced map's) will cost:
    ``planning.bound_cost``'s estimate."""
    lo, hi = _workspace(sc)
    b = sc.bound
    rays = sc.channel.propagation.rays_per_source
    traced = sc.channel.propagation.model == "ray_traced"
    if sc.shape.bound == "network":
        relays = {r.name for r in sc.relay_list}
        hops = {frozenset(h) for route in sc.route_list for h in zip(route, route[1:], strict=False) if set(h) <= relays}
        fixed_ends = len(sc.source_list) + len(sc.jammer_configs)
        if traced:
            return traced_network_bound_cost(lo, hi, sc.bound_grid_m, sc.bound_dt_s, sc.duration_s, len(relays),
                                             len(hops), fixed_ends, rays)
        stations = len(sc.base_station_list)  # a route to "any" is bounded at each base station: every combination
        combinations = math.prod(stations if r[-1] == ANY_BASE_STATION else 1 for r in sc.route_list)
        return network_bound_cost(lo, hi, sc.bound_grid_m, sc.bound_dt_s, sc.duration_s, len(relays), len(hops), combinations,
                                  global_seconds=b.global_seconds, branch_levels=b.branch_levels,
                                  branch_pairs=b.branch_pairs)
    axes = len(axis_cone(build_vehicle(sc.platform_of(0)).hover_tilt_limit, np.radians(b.axis_step_deg)))
    if traced:
        return traced_bound_cost(lo, hi, sc.bound_grid_m, sc.bound_dt_s, sc.duration_s, axes, rays)
    return single_bound_cost(lo, hi, sc.bound_grid_m, sc.bound_dt_s, sc.duration_s, axes)


def check_bound_size(sc: Scenario) -> None:
    """``planning.bound_cost``: a named error (BoundTooLarge, a ScenarioError naming the ``[bound]``
    field) before any work when the scenario's bound (a fleet's network bound) would need more than
    half of this machine's memory or longer than ``bound.max_minutes``."""
    if sc.channel.propagation.model == "ray_traced" and sc.has_route_choice:
        raise ScenarioError("bound: routes that may end at several base stations ('any') or skip relays "
                            "(network.route_selection) are bounded on the analytic channel only; the traced map's bound "
                            "takes fixed routes (name the end, 'fixed'), or fly with --no-bound")
    check_bound_cost(bound_cost(sc), max_minutes=sc.bound.max_minutes, grid_field="bound.grid_m", dt_field="bound.dt_s")


def bound_resolution(sc: Scenario) -> BoundResolution:
    """The bound's typed resolution from ``[bound]``."""
    b = sc.bound
    return BoundResolution(grid_m=sc.bound_grid_m, dt_s=sc.bound_dt_s, axis_step_deg=b.axis_step_deg, max_speed_m_s=b.max_speed_m_s,
                           max_accel_m_s2=b.max_accel_m_s2)


def _bound_key_tables(sc: Scenario, data: dict) -> dict:
    """``data``'s ``bound`` (and ``network``) tables in the cache key's layout from before one spelling per setting
    (``bound.grid_m`` / ``dt_s`` were the one relay's, ``network_grid_m`` / ``network_dt_s`` a network's;
    ``network.planner`` and ``route_dt_s`` were in ``[network]``): a bound cached then keeps its key."""
    bound = data["bound"]
    one, net = (sc.bound_grid_m, sc.bound_dt_s), (2.0, 2.0)
    networks = sc.shape.bound == "network"
    if networks:
        one, net = (0.5, 0.5), (sc.bound_grid_m, sc.bound_dt_s)
    bound.update(grid_m=one[0], dt_s=one[1], network_grid_m=net[0], network_dt_s=net[1])
    if "network" in data:
        data["network"]["route_dt_s"] = sc.route_dt_s if networks else 2.0
        data["network"]["planner"] = sc.planner if networks else "equidistant"
        for name in ("schedule", "self_interference_db"):  # in the key below when they change the rate
            data["network"].pop(name, None)
    if sc.network.schedule != "tdma":  # the schedule changes the rate: the bound of each is its own
        data["schedule"] = {"schedule": sc.network.schedule, "self_interference_db": sc.network.self_interference_db}
    return data


def scenario_bound_key(sc: Scenario) -> str:
    """Everything the bound depends on (not the controller, except its workspace box)."""
    sc = sc.relay_view(0)
    fleet = {"relays", "sources", "network"} if sc.names_its_fleet else set()  # a file with nodes.relay keeps its key
    fleet |= {"base_stations", "network"} if sc.base_stations is not None else set()  # a file with nodes.bs keeps its key
    data = _bound_key_tables(sc, world.bound_key_data(sc, sc.model_dump(include={"platform", "antenna", "channel", "nodes", "jammer",
                                                                               "jammers", "mission", "bound"} | fleet)))
    data["bound"].pop("max_minutes", None)  # a limit on the work, not what the bound is
    data["workspace"] = sc.controller.workspace.model_dump()
    data["duration_s"] = sc.duration_s
    if sc.channel.propagation.random:  # the bound searches the run's own realization
        data["seed"] = sc.seed
    return bound_key(data | world.scene_key(sc))


def network_bound_problem(sc: Scenario, lost: frozenset[str] = frozenset()) -> NetworkBoundProblem:
    """A fleet's network bound (without the relays ``lost``): its true scene, every source's path,
    every relay's hover tilt limit, the workspace box, ``[bound]``'s network grid and time step, the
    network's separation."""
    b = sc.bound
    lo, hi = _workspace(sc)
    vehicles = {r.name: build_vehicle(sc.platform_of(i)) for i, r in enumerate(sc.relay_list)}
    return NetworkBoundProblem(
        build_scene(sc).without(lost), {s.name: source_trajectory(s.mission) for s in sc.source_list},
        {name: v.hover_tilt_limit for name, v in vehicles.items() if name not in lost and name not in sc.standby_names},
        lo, hi, sc.duration_s,
        BoundResolution(grid_m=sc.bound_grid_m, dt_s=sc.bound_dt_s, axis_step_deg=b.axis_step_deg,
                        max_speed_m_s=b.max_speed_m_s, max_accel_m_s2=b.max_accel_m_s2),
        next(iter(vehicles.values())).gravity if vehicles else sc.platform.gravity_m_s2, sc.channel.outage, sc.separation_m,
        {r.name: np.asarray(r.start, float) for r in sc.relay_list if r.name not in lost and not r.standby},
        world.obstacles(sc), branch_levels=b.branch_levels, branch_pairs=b.branch_pairs, global_seconds=b.global_seconds,
        global_gap=b.global_gap)


def network_bound(sc: Scenario, progress=None) -> NetworkBound:
    """A fleet's network bound, computed once per geometry and cached; with relays lost in flight
    (``relays.lost_at_s``), from each loss on the bound of the smaller fleet (each fleet's bound cached
    on its own: the loss times are not in its key)."""
    check_bound_size(sc)
    stations = {"base_stations"} if sc.base_stations is not None else set()  # a file with nodes.bs keeps its key
    data = _bound_key_tables(sc, world.bound_key_data(sc, sc.model_dump(include={"relays", "sources", "network", "antenna", "channel",
                                                                               "nodes", "jammer", "jammers", "bound", "platform"}
                                                                      | stations)))
    for r in data.get("relays") or []:
        r.pop("lost_at_s", None)
    data["network"].pop("planner")  # the fleet's planner does not change the bound: its planners share one
    data["bound"].pop("max_minutes", None)  # a limit on the work, not what the bound is
    data |= {"workspace": sc.controller.workspace.model_dump(), "duration_s": sc.duration_s,
             "kind": f"network {NETWORK_BOUND_VERSION}"} | world.scene_key(sc)
    compute = compute_network_bound
    tracer = world.map_tracer(sc)
    if tracer is not None:  # on the traced map of the cubes' centres
        coherent = world.traced_coherent(sc)

        def compute(pb, progress=None):
            return compute_traced_network_bound(pb, tracer, coherent, progress)
    fleets = [(0.0, frozenset[str]()), *sc.losses]
    parts = []
    for i, (t, lost) in enumerate(fleets):
        key = bound_key(data | ({"lost": sorted(lost)} if lost else {}))

        def step(k, n, i=i):
            if progress is not None:
                progress(i * n + k, len(fleets) * n)

        parts.append((t, cached_bound(network_bound_problem(sc, lost), key, step, compute=compute, kind=NetworkBound)))
    return parts[0][1] if len(parts) == 1 else spliced(parts)


def bound_of(sc: Scenario, progress=None, vehicle: Multirotor | None = None,
             scene: RadioScene | None = None) -> CapacityBound | NetworkBound:
    """The scenario's capacity bound, cached per geometry: a network's (every relay's cubes at once, a min-sum over its
    routes) or the one relay's (its grid and axes, exactly its path bound): the physics of the two bounds differs.
    ``vehicle``/``scene``: the one relay's, passed in (a scene passed in is not in the cache key)."""
    if sc.shape.bound == "network":
        return network_bound(sc, progress)
    return scenario_bound(sc, progress, vehicle, scene)


def scenario_bound(sc: Scenario, progress=None, vehicle: Multirotor | None = None, scene: RadioScene | None = None) -> CapacityBound:
    """The scenario's capacity bound, computed once per geometry and cached (a scene passed in is
    not part of the cache key: its bound is computed afresh)."""
    check_bound_size(sc)
    pb = bound_problem(sc, vehicle, scene)
    if scene is not None:
        return compute_bound(pb, progress)
    return cached_bound(pb, scenario_bound_key(sc), progress)



def network_planner(sc: Scenario, scene: RadioScene, relays: list[LoopRelay], starts: dict[str, np.ndarray],
                    t0: float = 0.0) -> FleetPlanner:
    """The network's planner named by ``controller.planner``, built from the scene's world view, its
    references starting at ``starts`` (m, world) at ``t0`` (s) and kept outside the obstacles' margins, each relay
    inside its own workspace (the pre-flight route inside the box around them all)."""
    boxes = {r.name: _workspace(sc.relay_view(i)) for i, r in enumerate(sc.relay_list) if r.name in starts}
    lo = np.min([b[0] for b in boxes.values()], axis=0) if boxes else _workspace(sc)[0]
    hi = np.max([b[1] for b in boxes.values()], axis=0) if boxes else _workspace(sc)[1]
    ctx = NetworkPlannerContext(scene=scene.world_view(), routes=sc.route_list, starts=starts,
                                vehicles={r.name: r.vehicle for r in relays if r.name in starts},
                                bs_position=np.asarray(sc.first_station.position, float), workspace_min=lo, workspace_max=hi,
                                settings=planner_settings(sc), surrogate_g_bar=sc.antenna.g_bar, separation_m=sc.separation_m,
                                obstacles=world.obstacles(sc),
                                sources={s.name: source_trajectory(s.mission) for s in sc.source_list},
                                duration_s=sc.duration_s, t0_s=t0, route_dt_s=sc.route_dt_s, route=sc.network.route,
                                tracer=world.scoring_tracer(sc), traced_coherent=world.traced_coherent(sc),
                                relay_settings={r.name: planner_settings(sc.relay_view(i))
                                                for i, r in enumerate(sc.relay_list) if r.name in starts}, boxes=boxes)
    factory = planner_of(sc).network
    assert factory is not None  # planner_registered refused a network's planner without a network factory
    planner = factory(ctx)
    return KeepOutPlanner(planner, world.obstacles(sc)) if sc.obstacles else planner
