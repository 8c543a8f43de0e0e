"""The closed loop of a relay network, for any number of relays and sources (one relay is a network
of one): every relay steps through its ``RelayStep`` (stage parameters, NMPC, supervisor,
fail-safe) on the references of the network's planner (a one-relay planner flies through
``planning.fleet.OneRelayPlanner``), every source flies its mission, and one world step follows:
each relay's RK4 plant (``plant_step_function``, input held over the control period, drag in the
wind), the radio scene's true channel with every vehicle's attitude (a source's follows its
acceleration), the random channel terms, blockage and the jammer estimator's readings.

A relay lost in flight (``losses``) is gone from then on: every route through it skips it, the
planner is rebuilt for the smaller network from where the others are, and its columns read NaN
(``qp_status`` "lost"). One log row per control step in the one vocabulary (``sim.log_schema``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import closing
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from ..control.network import LoopRelay, NetworkController
from ..control.nmpc import StepInfo
from ..models.drag import drag_acceleration
from ..models.geometry import rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.radio import ChannelState, RadioScene
from ..models.state import ETA, ROTORS, P, V
from ..models.streams import generator, stream
from ..models.vehicle import Multirotor
from ..planning.fleet import FleetPlanner
from ..planning.home import PLACE_CLEARANCE_M, HomeFlight, PlaceFlight, beside, extra_time_s, transit_time_s
from .air import Air
from .blockage import Blockage
from .exit_status import ExitStatus
from .handover import Handover, HandoverRule, route_columns, route_values
from .jammer_sensing import JammerSensing
from .log_schema import (
    gone_row,
    link_row,
    log_columns,
    new_log,
    record_row,
    relay_row,
    separation_min,
    source_row,
    steps_flown,
)
from .networks import every_link, possible_networks
from .perturbations import LinkPerturbations, PerturbationSettings
from .realtime import full_collections_paused
from .traced import TracedChannel

BENCH_POINT_EVERY = 500  # control steps between two states kept for `aerorelay bench`'s full IPOPT solves
BENCH_POINT_OFFSET = 250  # the first one kept, mid-way into the first interval


def step_count(duration_s: float, period_s: float) -> int:
    """Control steps of a mission of ``duration_s`` at ``period_s`` (both ends included)."""
    return int(math.floor(duration_s / period_s + 1e-9)) + 1


def plant_step_function(veh: Multirotor, plant_rate_hz: float, period_s: float, drag: np.ndarray | None = None) -> ca.Function:
    """CasADi function ``(x, u, d) -> x`` advancing one control period with RK4 sub-steps.

    ``d = (a_dist (m/s^2, world), alpha_dist (rad/s^2, body))`` is a process disturbance held
    over the period. With ``drag`` (``c`` per body axis, kg/m: ``models.drag``) the function is
    ``(x, u, d, w) -> x`` and the drag in the wind ``w`` (m/s, world, held over the period) acts at
    every sub-step.
    """
    n_sub = int(round(plant_rate_hz * period_s))
    dt = 1.0 / plant_rate_hz
    x, u, d = ca.SX.sym("x", veh.nx), ca.SX.sym("u", veh.n_rotors), ca.SX.sym("d", 6)
    wind = ca.SX.sym("w", 3)

    def f(xx):
        dx = veh.dynamics(xx, u)
        a = d[:3] if drag is None else d[:3] + drag_acceleration(xx[ETA], xx[V], wind, drag, veh.mass)
        return dx + ca.vertcat(ca.SX(3, 1), ca.SX(3, 1), a, d[3:], ca.SX(veh.n_rotors, 1))

    xk = x
    for _ in range(n_sub):
        k1 = f(xk)
        k2 = f(xk + 0.5 * dt * k1)
        k3 = f(xk + 0.5 * dt * k2)
        k4 = f(xk + dt * k3)
        xk = xk + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("plant_step", [x, u, d] if drag is None else [x, u, d, wind], [xk])


@dataclass(frozen=True, kw_only=True)
class SimSettings:
    """How a mission is flown: control period and length (s), plant rate (Hz), the relay's start
    (m), the seed, and the disturbances unknown to the controller (CSI noise m, process noise
    m/s^2 and rad/s^2, Rician K in dB or None); ``senses_jammer_state``: the planner plans with the
    power actually radiated (0 while a jammer is OFF) instead of the nominal one."""

    period_s: float
    duration_s: float
    plant_rate_hz: float
    seed: int = 0
    csi_noise_m: float = 0.0
    process_noise_v: float = 0.0
    process_noise_w: float = 0.0
    fading_k_db: float | None = None
    senses_jammer_state: bool = False
    # fading model, shadowing and carrier of the plant's random channel terms (sim/perturbations.py)
    channel_noise: PerturbationSettings | None = None
    handover: HandoverRule = HandoverRule()  # which base station serves a route that may end at several

    def link_perturbations(self, scene: RadioScene) -> LinkPerturbations:
        """The plant's random channel terms on ``scene``'s links (the fading's K from ``fading_k_db``)."""
        noise = self.channel_noise or PerturbationSettings()
        return LinkPerturbations(scene, replace(noise, k_db=self.fading_k_db), period_s=self.period_s, seed=self.seed)


@dataclass(kw_only=True)
class MissionResult:
    """Per-step log (dict of equal-length arrays) and run facts."""

    log: dict
    wall_s: float
    sim_s: float
    qp_failures: int
    controller: str = ""  # NmpcSettings.fingerprint() of the controller that flew it
    fallback_episodes: int = 0
    aborted: str | None = None  # why the flight stopped early (the log holds the steps flown), None: flown to the end
    exit_status: str | None = None  # sim.exit_status.ExitStatus value of an early stop (None: flown to the end)
    # per relay, the steps a vehicle came near beyond its separation rows (control.network.separation_rows)
    separation_unguarded: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class StepTiming:
    """Per control step: preparation and feedback phases (ms), IPM iterations, planner (ms)."""

    prep_ms: float
    feedback_ms: float
    qp_iters: int
    planner_ms: float
    estimator_ms: float = 0.0


@dataclass(frozen=True)
class BenchPoint:
    """A state the controller met, to time a full solve at (``control.bench``)."""

    x: np.ndarray
    u_prev: np.ndarray
    P: np.ndarray
    guess: np.ndarray | None


def known_jammers(scene: RadioScene, t: float, senses_state: bool, csi_noise_m: float = 0.0,
                  rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The jammers as a relay (or a fleet) told of them knows them at ``t``: positions ``(nJ, 3)`` (m,
    world; with ``csi_noise_m`` of noise per axis from ``rng``) and the powers it plans with (W: 0
    before a jammer's localization ``tau_E``, then the nominal power, or the one radiated now when the
    controller senses the schedule). One view for the one-relay loop, the fleet loop and the step API."""
    noise = [rng.normal(0.0, csi_noise_m, 3) for _ in scene.jammers] if csi_noise_m > 0 and rng is not None else None
    positions = np.array([j.position_at(t) + (noise[i] if noise is not None else 0.0)
                          for i, j in enumerate(scene.jammers)]).reshape(-1, 3)
    return positions, np.array([j.planned_power(t, senses_state) for j in scene.jammers])



def process_streams(seed: int, relays: Sequence[str]) -> dict[str, np.random.Generator]:
    """Each relay's process-noise stream: the first relay draws the run's ``process`` stream (the one
    relay's since streams were named), each further relay a child of it of its own."""
    children = stream(seed, "process").spawn(max(len(relays) - 1, 0))
    return {name: generator(seed, "process") if i == 0 else np.random.default_rng(children[i - 1])
            for i, name in enumerate(relays)}


class ClosedLoop:
    """Flies a network (one relay and one source, or a fleet): ``run(progress)`` returns a MissionResult."""

    def __init__(self, *, scene: RadioScene, relays: list[LoopRelay], sources: dict[str, SourceTrajectory],
                 planner: FleetPlanner | None, settings: SimSettings, separation_m: float = 0.0,
                 losses: Sequence[tuple[float, frozenset[str]]] = (),
                 replanner: Callable[[RadioScene, Mapping[str, np.ndarray], float], FleetPlanner] | None = None,
                 sensing: JammerSensing | None = None, air: Air | None = None, blockage: Blockage | None = None,
                 traced: TracedChannel | None = None, planner_name: str = "planner"):
        """``planner_name``: how the check of its references names the planner (``planning.base.ReferenceCheck``).
        ``losses``: ``(t, every relay lost by then)`` in time order (s); ``replanner(scene, positions, t0)``
        builds the planner of the network ``scene`` from its relays' positions (m, world) at ``t0`` (s);
        ``relays``: a spare (``LoopRelay.spare``) waits outside ``scene`` until it takes a relay's place;
        ``sensing``: the jammers estimated from the receivers' readings, one estimate every planner shares;
        ``traced``: the plant's links ray traced (their gains instead of eq. 6-7's; the controllers never see it)."""
        if losses and replanner is None:
            raise ValueError("ClosedLoop: relays are lost in flight (losses) but no replanner builds the smaller network's planner")
        if any(r.plant is None for r in relays) and air is None:
            raise ValueError("ClosedLoop: every relay needs its plant step (LoopRelay.plant)")
        self.scene, self.relays, self.sources, self.settings = scene, relays, sources, settings
        self.losses = list(losses)
        # the controller side of each step: the network's planner, every relay's stage parameters and NMPC
        self.control = NetworkController(scene=scene, relays=relays, planner=planner, period_s=settings.period_s,
                                         separation_m=separation_m, replanner=replanner, planner_name=planner_name)
        self.sensing, self.air = sensing, air
        self.blockage = blockage if blockage is not None and blockage.active else None  # obstacles that block radio
        # the networks it may fly: after each scheduled loss, and with any relay that may fly home out of it
        homing = [r.name for r in relays if r.home is not None and r.battery is not None]
        scheduled: list[frozenset[str]] = [frozenset()] + [lost for _, lost in self.losses]
        self.spares = {r.name: r.spare for r in relays if r.spare is not None}
        self.networks = possible_networks(scene, scheduled, homing, self.spares)
        later = [h for net in self.networks for h in net.hops]
        self.columns = log_columns({r.name: r.vehicle.n_rotors for r in relays}, list(sources), scene, later)
        # the plant's random channel terms on every link the network takes, before and after each loss (each its
        # own draw, shadowing along each link's own geometry), unknown to the planners and NMPCs; logged per link
        # (sim/perturbations.py); each step the links of the network flying then are applied
        self.perturbations = settings.link_perturbations(every_link(scene, self.networks))
        self._links_now = self.perturbations.layout(scene)  # the fading links of the network flying now
        self.columns += self.perturbations.columns
        if self.blockage is not None:
            self.nlos_columns = list(dict.fromkeys(c for s in (scene, *self.networks)
                                                   for c in self.blockage.columns(s)))
            self.columns += self.nlos_columns
        self.traced = traced
        if traced is not None:
            self.traced_columns = list(dict.fromkeys(c for s in (scene, *self.networks)
                                                     for c in traced.columns(s)))
            self.columns += self.traced_columns
        if sensing is not None:
            self.columns += sensing.columns
        if air is not None:
            self.columns += air.wind_columns() + [c for r in relays for c in air.columns(r.name, f"{r.name}.")]
        # each relay with a battery: its state of charge at the step's start and whether it reached its reserve
        self.battery_columns = [c for r in relays if r.battery is not None for c in (f"{r.name}.soc", f"{r.name}.battery_reserve")]
        # and, when it may fly home, whether it has turned home (it has then left the network)
        self.battery_columns += [f"{n}.going_home" for n in homing]
        # each spare: whether it waits, whether it flies to a relay's place, and whose (its name once it took it)
        self.battery_columns += [c for n in self.spares for c in (f"{n}.waiting", f"{n}.ferrying", f"{n}.replaces")]
        self.columns += self.battery_columns
        # what the network knows: the sources and the jammers with CSI noise (one stream); each relay's process noise its own
        self.csi_rng = generator(settings.seed, "csi")
        self.hover_w = {r.name: float(r.vehicle.shaft_power(r.vehicle.hover_speeds())) for r in relays}  # W, for the way home
        self.process_rngs = process_streams(settings.seed, [r.name for r in relays])
        self.gravity = self.control.gravity
        self.stations = self.control.stations  # every base station's position (m, world)
        # a route that may change (its end among several base stations, the relays carrying it): which serves it,
        # decided each step from the true rates
        self.handover = Handover(settings.handover) if scene.route_choice else None
        self.handover_columns = list(dict.fromkeys(c for net in (scene, *self.networks) for c in route_columns(net)))
        self.columns += self.handover_columns
        # per step: the planner's time (ms); per relay: its controller's timings and states kept for the bench
        self.planner_ms: list[float] = []
        self.timings: dict[str, list[StepTiming]] = {r.name: [] for r in relays}
        self.bench_points: dict[str, list[BenchPoint]] = {r.name: [] for r in relays}

    def _known_sources(self, truth: dict) -> dict:
        """Every source as the network knows it over its optical link: its position with CSI noise (m),
        its velocity and acceleration."""
        noise = self.settings.csi_noise_m
        if noise <= 0:
            return truth
        return {n: replace(s, p=s.p + self.csi_rng.normal(0.0, noise, 3)) for n, s in truth.items()}

    def _known_jammers(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The jammers as the network knows them: its estimate (from the readings up to the last step) or
        the oracle's after tau_E with CSI noise; positions (m), powers to plan with (W), std (m or None)."""
        st = self.settings
        if self.sensing is not None:
            return self.sensing.estimate.planner_view(st.senses_jammer_state)
        return (*known_jammers(self.scene, t, st.senses_jammer_state, st.csi_noise_m, self.csi_rng), None)

    def _process_noise(self, relay: str) -> np.ndarray:
        """One relay's process noise for a step: accelerations (m/s^2, world) and angular accelerations
        (rad/s^2, body), from its own stream."""
        st = self.settings
        rng = self.process_rngs[relay]
        return np.concatenate([rng.normal(0.0, st.process_noise_v, 3), rng.normal(0.0, st.process_noise_w, 3)])

    def _energy_home(self, r: LoopRelay, p: np.ndarray) -> float:
        """What relay ``r`` at ``p`` (m) needs to get home and land (J; ``models.battery``)."""
        assert r.home is not None and r.battery is not None
        home = np.asarray(r.home.landing_m, float)
        return r.battery.energy_home_j(float(np.linalg.norm(p[0:2] - home[0:2])), float(p[2] - home[2]), self.hover_w[r.name],
                                       r.home.return_speed_m_s, r.home.land_speed_m_s, extra_time_s(r.home))

    def _go_home(self, t: float, drawn: dict[str, float], x: dict[str, np.ndarray], flying: Mapping[str, np.ndarray],
                 homing: dict[str, HomeFlight], gone: frozenset[str], ferrying: dict[str, tuple[str, PlaceFlight]]) -> None:
        """Each relay in the network whose battery's energy left is what getting home needs plus the reserve
        (``models.battery``) turns home: it leaves the network and flies home to land; a spare flying to its place
        takes it on every route (``ferrying``: spare -> (relay, flight)); the network re-plans."""
        turned = []
        for r in self.relays:
            if r.home is None or r.battery is None or r.name not in flying or r.name in homing:
                continue
            p = x[r.name][P]
            if r.battery.must_go_home(drawn[r.name], self._energy_home(r, p)):
                homing[r.name] = HomeFlight(r.home, p, x[r.name][V])
                turned.append(r.name)
        if not turned:
            return
        for spare in [s for s in ferrying if s in homing]:  # a spare whose own battery sent it home before it took over
            del ferrying[spare]
        self._recompose(gone | set(homing), frozenset(turned), x, ferrying, t)

    def _recompose(self, leave: frozenset[str], leaving: frozenset[str], x: dict[str, np.ndarray],
                   ferrying: dict[str, tuple[str, PlaceFlight]], t0: float) -> None:
        """The relays ``leave`` are out of the network from now on; each spare flying to the place of one of
        ``leaving`` takes it on every route (``RadioScene.handed_to``); the network's planner rebuilt at ``t0`` (s)."""
        net = self.control.scene
        for spare, (relay, _) in list(ferrying.items()):
            if relay in leaving and relay in net.node_names:
                net = net.handed_to(relay, self.spares[spare])
                del ferrying[spare]
        self.control.recompose(net.without(leave), {n: xs[P].copy() for n, xs in x.items()}, t0)
        self.scene = self.control.scene
        self._links_now = self.perturbations.layout(self.scene)

    def _launch(self, drawn: dict[str, float], x: dict[str, np.ndarray], waiting: set[str],
                ferrying: dict[str, tuple[str, PlaceFlight]]) -> None:
        """A waiting spare launches for a relay of the network that will have to fly home before the spare could
        reach it: when the relay's energy left, less what hovering draws over the spare's flight to it
        (``planning.home.transit_time_s``, plus speeding up, braking and settling), is what getting home needs plus
        the reserve. The nearest waiting spare goes; it flies beside the relay (``PlaceFlight``) until it takes over."""
        taken = {leaving for leaving, _ in ferrying.values()}
        for r in self.relays:
            if not waiting:
                return
            if r.home is None or r.battery is None or r.name in taken or r.name not in self.scene.node_names:
                continue
            p = x[r.name][P]
            spare = min((s for s in self.relays if s.name in waiting), key=lambda s: float(np.linalg.norm(s.start - p)))
            assert spare.home is not None  # every spare has its way to a place (assembly.parts)
            transit = transit_time_s(spare.start, p, x[r.name][V], spare.home.return_speed_m_s,
                                     self.control.separation_m + PLACE_CLEARANCE_M) + extra_time_s(spare.home)
            if r.battery.must_go_home(drawn[r.name] + r.battery.draw(self.hover_w[r.name], transit), self._energy_home(r, p)):
                waiting.discard(spare.name)
                ferrying[spare.name] = (r.name, PlaceFlight(spare.home, spare.start, np.zeros(3)))
                taken.add(r.name)

    def _ferry_references(self, period: float, x: dict[str, np.ndarray], ferrying: dict[str, tuple[str, PlaceFlight]]) -> dict:
        """Each spare flying to its relay: a reference beside that relay (``beside``), the separation and 1 m away."""
        out = {}
        for spare, (leaving, flight) in ferrying.items():
            goal = beside(x[leaving][P], x[spare][P], self.control.separation_m + PLACE_CLEARANCE_M)
            out[spare] = flight.reference(period, x[spare][P], x[spare][V], goal)
        return out

    def _hand_over(self, t: float, state: ChannelState, poses, gains, link_gains) -> tuple[ChannelState, dict]:
        """The handover rule on this step's true rates (``state``, the channel at ``poses`` with the plant's
        ``gains`` / ``link_gains``): a route that changes (its base station, the relays carrying it) is served by its
        new route from this step on; the serving routes and every candidate's rate logged."""
        assert self.handover is not None
        routes = self.handover.decide(t, self.scene, state)
        if routes is not None:
            self.control.hand_over(routes)
            self.scene = self.control.scene
            state = self.scene.evaluate(t, poses, fading=gains, link_gains=link_gains, ends="serving")
        return state, dict.fromkeys(self.handover_columns, math.nan) | route_values(self.scene, state)

    @property
    def planner(self):
        return self.control.planner

    def _relay_step(self, k: int, r: LoopRelay, x: np.ndarray, ref, predicted: dict, lost: frozenset[str]):
        """Relay ``r``'s control step at ``x`` on the reference ``ref``: its stage parameters, its NMPC's input
        (a bench point kept every ``BENCH_POINT_EVERY`` steps, its timings)."""
        params = self.control.parameters(r, ref, predicted, lost, self.air.estimate(r.name) if self.air else None)
        if k % BENCH_POINT_EVERY == BENCH_POINT_OFFSET:  # samples for benchmarking a full solve at the same points
            nmpc = r.controller.nmpc
            self.bench_points[r.name].append(BenchPoint(x.copy(), r.stepper.u.copy(), params.copy(),
                                                        nmpc.guess() if nmpc.initialized else None))
        info = r.stepper.act(x, params)
        self.timings[r.name].append(StepTiming(info.prep_ms, info.feedback_ms, info.qp_iters, self.planner_ms[-1],
                                               self.sensing.last_ms if self.sensing else 0.0))
        return info

    def _relay_steps(self, k: int, relays: list[LoopRelay], x: dict, refs: dict, predicted: dict,
                     lost: frozenset[str]) -> dict[str, StepInfo]:
        """Every flying relay's control step of period ``k`` (``_relay_step``), on the controller's threads."""
        def one(r: LoopRelay) -> StepInfo:
            return self._relay_step(k, r, x[r.name], refs[r.name], predicted, lost)
        return dict(zip((r.name for r in relays), self.control.each(one, relays), strict=True))

    def run(self, progress=None) -> MissionResult:
        st = self.settings
        period = st.period_s
        n_steps = step_count(st.duration_s, period)
        x = {r.name: r.vehicle.hover_state(r.start) for r in self.relays}
        drawn = {r.name: 0.0 for r in self.relays if r.battery is not None}  # energy drawn so far, J
        log = new_log(self.columns, n_steps)
        sinr_columns = [c for c in self.columns if c.startswith(("sinr.", "se."))]
        pending, lost = list(self.losses), frozenset[str]()
        homing: dict[str, HomeFlight] = {}  # relays flying home (out of the network), their flights
        landed: set[str] = set()  # relays home and down: out of the flight
        waiting = set(self.spares)  # spares on the ground at their starts (out of the flight)
        ferrying: dict[str, tuple[str, PlaceFlight]] = {}  # spares flying to a relay's place: (that relay, the flight)
        replaced: dict[str, str] = {}  # spare -> the relay whose place it flies to or took
        wall0 = time.perf_counter()
        aborted, flown, exit_status = None, n_steps, None
        # a full collection took 70-100 ms of one step (sim/realtime.py); the relays' threads stop with the flight
        with full_collections_paused(), closing(self.control):
            for k in range(n_steps):
                t = k * period
                while pending and t >= pending[0][0] - 1e-9:
                    when, now_lost = pending.pop(0)  # a spare on its way to one of them takes its place
                    self._recompose(now_lost | landed | set(homing), now_lost - lost, x, ferrying, when)
                    lost = now_lost
                gone = lost | landed | waiting
                flying = {n: xs for n, xs in x.items() if n not in gone}
                truth = {name: path.state(t) for name, path in self.sources.items()}
                src = self._known_sources(truth)  # over the optical links, with CSI noise
                pj, powers, std = self._known_jammers(t)
                if self.air is not None:
                    self.air.begin()
                eta = {**{n: xs[ETA] for n, xs in flying.items()}, **{n: s.attitude(self.gravity) for n, s in truth.items()}}
                R = {n: rotation_zyx(e) for n, e in eta.items()}  # every vehicle's attitude, body to world
                refs = self.control.plan(t, {n: xs for n, xs in flying.items() if n not in homing and n not in ferrying},
                                         src, (pj, powers, std))
                refs |= {n: home.reference(period, x[n][P], x[n][V]) for n, home in homing.items() if n in flying}
                refs |= self._ferry_references(period, x, ferrying)
                self.planner_ms.append(self.control.planner_ms)
                row: dict[str, object] = {"t": t}
                predicted = self.control.predicted(x, src)  # every vehicle over the horizon: the relays' latest plans
                true_positions = {**{n: xs[P] for n, xs in flying.items()}, **{n: s.p for n, s in truth.items()},
                                  **self.stations}
                inputs = {}
                infos = self._relay_steps(k, [r for r in self.relays if r.name not in gone], x, refs, predicted, gone)
                for r in self.relays:
                    if r.name in gone:
                        row |= gone_row(r.name, r.vehicle.n_rotors, "standby" if r.name in waiting else "lost")
                        if self.air is not None:
                            row |= dict.fromkeys(self.air.columns(r.name, f"{r.name}."), math.nan)
                        continue
                    info = infos[r.name]
                    inputs[r.name] = info.u
                    up, down = self.control.neighbours(r.name)
                    row |= relay_row(r.name, x[r.name], R[r.name], info, refs[r.name], true_positions[up],
                                     true_positions[down], bool(r.controller.last_violations))
                    if self.air is not None:
                        row |= self.air.values(r.name, x[r.name], f"{r.name}.")
                for name, s in truth.items():
                    row |= source_row(name, s.p, eta[name])
                in_scene = self.scene.node_names  # a relay flying home has left the network's scene
                poses = {n: self.scene.pose(n, true_positions[n], R[n]) for n in R if n in in_scene}
                gains = None
                if self.perturbations.active:  # fading and shadowing on every link, each its own
                    velocities = {**{n: xs[V] if n in flying else np.zeros(3) for n, xs in x.items()},
                                  **{n: s.v for n, s in truth.items()}, **{n: np.zeros(3) for n in self.stations}}
                    every, values = self.perturbations.step(t, {**{n: xs[P] for n, xs in x.items()}, **true_positions},
                                                            velocities)  # a lost relay's links at where it was lost
                    gains = None if every is None else every[self._links_now]
                    row |= values
                if self.blockage is not None:  # a link through an obstacle that blocks radio loses its nlos_loss_db
                    blocked, values = self.blockage.step(self.scene, t, true_positions)
                    gains = blocked if gains is None else gains * blocked
                    row |= dict.fromkeys(self.nlos_columns, math.nan) | values
                link_gains = None
                if self.traced is not None:  # the links' gains ray traced at the true poses
                    link_gains, values = self.traced.step(self.scene, t, poses)
                    row |= dict.fromkeys(self.traced_columns, math.nan) | values
                state = self.scene.evaluate(t, poses, fading=gains, link_gains=link_gains, ends="serving")
                if self.handover is not None:
                    state, values = self._hand_over(t, state, poses, gains, link_gains)
                    row |= values
                if self.sensing is not None:  # the receivers read this step's interference; the estimate is the next step's
                    row |= self.sensing.step(t, state, self.scene.with_fixed(poses))
                row |= dict.fromkeys(sinr_columns, math.nan)  # a hop the network does not take now
                row |= link_row(self.scene, t, state)
                row["separation_min"] = separation_min(np.array([true_positions[n] for n in (*flying, *truth)]))
                if self.air is not None:
                    row |= self.air.wind_values()
                empty = []
                for r in self.relays:
                    if r.battery is not None:
                        soc = r.battery.state_of_charge(drawn[r.name]) if r.name not in gone else math.nan
                        if soc < 0.0:  # its usable energy spent: it cannot fly on (logged empty, the flight ends here)
                            empty.append(r.name)
                            soc = 0.0
                        row |= {f"{r.name}.soc": soc, f"{r.name}.battery_reserve": bool(soc <= r.battery.reserve_fraction)}
                        if r.home is not None:
                            row[f"{r.name}.going_home"] = r.name in homing
                        if r.name not in gone:
                            drawn[r.name] += r.battery.draw(float(r.vehicle.shaft_power(x[r.name][ROTORS])), period)
                replaced |= {spare: leaving for spare, (leaving, _) in ferrying.items()}
                for n in self.spares:
                    row |= {f"{n}.waiting": n in waiting, f"{n}.ferrying": n in ferrying, f"{n}.replaces": replaced.get(n, "")}
                record_row(log, k, row, self.columns)
                if empty:  # the steps flown are kept; the run is reported unsafe
                    aborted, flown = f"relay {empty[0]!r}: its battery is empty at t = {t:.2f} s: it cannot fly on", k + 1
                    exit_status = ExitStatus.BATTERY_EMPTY.value
                    break
                self._go_home(t, drawn, x, flying, homing, gone, ferrying)
                if waiting:
                    self._launch(drawn, x, waiting, ferrying)
                for r in self.relays:
                    if r.name not in gone:
                        d = self._process_noise(r.name)
                        if self.air is not None:
                            x[r.name] = self.air.advance(r.name, x[r.name], inputs[r.name], d)
                        else:
                            assert r.plant is not None  # checked in __init__
                            x[r.name] = np.asarray(r.plant(x[r.name], inputs[r.name], d)).ravel()
                landed |= {n for n, home in homing.items() if n not in landed and home.landed(x[n][P])}
                bad = [n for n, xs in x.items() if n not in gone and not np.all(np.isfinite(xs))]
                if bad:  # the steps flown are kept; the run is reported unsafe
                    aborted, flown = f"relay {bad[0]!r}: the plant's state became non-finite after t = {t:.3f} s", k + 1
                    exit_status = ExitStatus.NON_FINITE.value
                    break
                if progress is not None:
                    progress(k + 1, n_steps)
        wall = time.perf_counter() - wall0
        if flown < n_steps:
            log = steps_flown(log, flown)
        return MissionResult(log=log, wall_s=wall, sim_s=(flown - 1) * period,
                             qp_failures=sum(r.controller.nmpc.failures for r in self.relays),
                             controller=" | ".join(dict.fromkeys(r.controller.nmpc.settings.fingerprint() for r in self.relays)),
                             fallback_episodes=sum(r.controller.fallback_episodes for r in self.relays), aborted=aborted,
                             exit_status=exit_status, separation_unguarded=dict(self.control.unguarded))
