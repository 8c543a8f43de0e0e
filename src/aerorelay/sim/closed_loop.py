"""Closed-loop relay mission: planner + relay controller + RK4 plant + the radio scene's true channel.

The plant (MRAV-1) is integrated by RK4 at ``sim.plant_rate_hz`` with the controller's input
held over each control period. At every control step the true channel (``models.radio``) is
evaluated with the scene's antennas, both vehicles' attitudes (MRAV-2's follows its
acceleration) and every jammer, with Rician fading when configured. One log row per control step; the columns follow the vehicle's rotor
count (``log_columns``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from ..control.nmpc import StepInfo
from ..control.relay import RelayController
from ..flight.stepper import RelayStepper, SourceState
from ..models.channel import misalignment, mutual_alignment
from ..models.drag import drag_acceleration
from ..models.geometry import rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.radio import ChannelState, RadioScene
from ..models.streams import generator
from ..models.vehicle import Multirotor
from ..planning.base import Planner, Reference
from .air import Air
from .blockage import Blockage
from .exit_status import ExitStatus
from .jammer_sensing import JammerSensing
from .perturbations import LinkPerturbations, PerturbationSettings
from .realtime import full_collections_paused

BENCH_POINT_EVERY = 500  # control steps between two states kept for `aerorelay bench`'s full IPOPT solves
BENCH_POINT_OFFSET = 250  # the first one kept, mid-way into the first interval


# the log's columns that are not floats, with their types (flags and the QP's status text)
LOG_COLUMN_TYPES: dict[str, type] = {"jammer_on": bool, "qp_ok": bool, "qp_status": str, "fallback": bool, "safety_violation": bool}
# the columns a step records by name, after the numeric row (written in log_columns' order)
RECORDED_BY_NAME = ("qp_ok", "qp_status", "fallback", "safety_violation", "taylor_rel_err")


# the log's columns by group, in order (one row per control step; units in guide/run-folders)
RELAY_STATE_COLUMNS = ("p1_x", "p1_y", "p1_z", "phi1", "theta1", "psi1", "v1_x", "v1_y", "v1_z", "omega1_x", "omega1_y",
                       "omega1_z")  # the plant's state x[0:12]: m, rad, m/s, rad/s (world; ZYX Euler; body rates)
SOURCE_COLUMNS = ("p2_x", "p2_y", "p2_z", "phi2", "theta2", "psi2")  # MRAV-2's position (m) and attitude (rad)
REFERENCE_COLUMNS = ("pd_x", "pd_y", "pd_z")  # the planner's position reference, m
LINK_COLUMNS = ("jammer_on", "gamma_21", "gamma_10", "se_21", "se_10", "capacity", "v_12", "v_10", "mutual_alignment")
STEP_COLUMNS = ("slack_max", "solve_ms", "feedback_ms")


def rotor_columns(n_rotors: int) -> tuple[list[str], list[str]]:
    """The motor speeds' (``Omega_i``, Hz) and their rates' (``u_i``, Hz/s) columns."""
    return [f"Omega_{i}" for i in range(1, n_rotors + 1)], [f"u_{i}" for i in range(1, n_rotors + 1)]


def log_columns(n_rotors: int) -> list[str]:
    """The per-step log's columns, in order, for a relay with ``n_rotors`` rotors."""
    omega, rates = rotor_columns(n_rotors)
    return ["t", *RELAY_STATE_COLUMNS, *omega, *rates, *SOURCE_COLUMNS, *REFERENCE_COLUMNS, *LINK_COLUMNS, *STEP_COLUMNS,
            *RECORDED_BY_NAME]


def step_count(duration_s: float, period_s: float) -> int:
    """Control steps of a mission of ``duration_s`` at ``period_s`` (both ends included)."""
    return int(math.floor(duration_s / period_s + 1e-9)) + 1


def jammer_columns(scene: RadioScene) -> list[str]:
    """The true jammer positions' columns ``jam_<name>_x/y/z`` (m, world)."""
    return [f"jam_{j.name}_{a}" for j in scene.jammers for a in "xyz"]


def jammer_values(scene: RadioScene, t: float) -> dict[str, float]:
    """Every jammer's true position at ``t`` by its ``jammer_columns`` names."""
    return dict(zip(jammer_columns(scene), [float(v) for j in scene.jammers for v in j.position_at(t)], strict=True))


def new_log(columns: list[str], n_steps: int, kind_of: Callable[[str], type]) -> dict[str, np.ndarray]:
    """An empty per-step log: a float, bool or object (text) array per column, by ``kind_of``."""
    def empty(kind: type) -> np.ndarray:
        return np.zeros(n_steps, dtype=bool) if kind is bool else np.empty(n_steps, dtype=object) if kind is str \
            else np.empty(n_steps)
    return {c: empty(kind_of(c)) for c in columns}


def record_row(log: dict[str, np.ndarray], k: int, row: dict, columns: list[str], who: str = "log row") -> None:
    """Write step ``k``'s ``row`` (by column name) into ``log``; at the first step, a column declared
    but not recorded, or recorded but not declared, is an error."""
    if k == 0 and set(row) != set(columns):
        raise ValueError(f"{who}: columns {sorted(set(columns) ^ set(row))} not both declared and recorded")
    for name, val in row.items():
        log[name][k] = val


def steps_flown(log: dict[str, np.ndarray], flown: int) -> dict[str, np.ndarray]:
    """The log's first ``flown`` steps (a flight ended early keeps what it flew)."""
    return {c: v[:flown] for c, v in log.items()}


def relay_source_poses(scene: RadioScene, names: dict[str, str], x1: np.ndarray, p2, eta2) -> dict:
    """The radio poses of the relay at state ``x1`` and the source at ``p2`` (m) with attitude ``eta2``
    (rad, ZYX), by the scene's node ``names`` (role -> name)."""
    return {names["relay"]: scene.pose(names["relay"], x1[0:3], rotation_zyx(x1[3:6])),
            names["source"]: scene.pose(names["source"], p2, rotation_zyx(eta2))}


def mission_row(veh: Multirotor, scene: RadioScene, t: float, x: np.ndarray, u: np.ndarray, p2, eta2, ref: Reference,
                channel: ChannelState, p0: np.ndarray, info: StepInfo, violation: bool) -> dict:
    """One control step's log row by column name (``log_columns`` and the jammers' positions): the relay's
    state ``x`` and input ``u``, the source at ``p2`` / ``eta2``, the planner's reference, the ``channel``
    and the relay's misalignments toward the source and the base station at ``p0`` (``v_12``, ``v_10``),
    the NMPC's step ``info``, the supervisor's ``violation``."""
    g21, g10 = (float(g) for g in channel.sinr)
    jam_on = any(float(j.power_at(t)) > 0 for j in scene.jammers)
    nr = veh.n_rotors
    if x.shape != (veh.nx,) or u.shape != (nr,):
        raise ValueError(f"log row: state {x.shape} / input {u.shape} do not match the {nr}-rotor vehicle")
    omega, rates = rotor_columns(nr)
    R1 = rotation_zyx(x[3:6])
    v12, v10 = float(misalignment(x[0:3], R1, p2)), float(misalignment(x[0:3], R1, p0))
    row = {"t": t, **dict(zip(RELAY_STATE_COLUMNS, x[0:12], strict=True)), **dict(zip(omega, x[12 : 12 + nr], strict=True)),
           **dict(zip(rates, u, strict=True)), **dict(zip(SOURCE_COLUMNS, [*p2, *eta2], strict=True)),
           **dict(zip(REFERENCE_COLUMNS, ref.p_ref, strict=True)),
           "jammer_on": float(jam_on), "gamma_21": g21, "gamma_10": g10, "se_21": math.log2(1 + g21),
           "se_10": math.log2(1 + g10), "capacity": float(channel.capacity), "v_12": v12, "v_10": v10,
           "mutual_alignment": float(mutual_alignment(v12, v10)), "slack_max": info.slack_max,
           "solve_ms": info.solve_ms, "feedback_ms": info.feedback_ms,
           "qp_ok": info.ok, "qp_status": info.status, "fallback": info.fallback,
           "safety_violation": violation, "taylor_rel_err": ref.taylor_rel_err}
    return row | jammer_values(scene, t)


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
        a = d[:3] if drag is None else d[:3] + drag_acceleration(xx[3:6], xx[6:9], wind, drag, veh.mass)
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
    relay_start: np.ndarray
    seed: int = 0
    csi_noise_m: float = 0.0
    process_noise_v: float = 0.0
    process_noise_w: float = 0.0
    fading_k_db: float | None = None
    senses_jammer_state: bool = False
    # fading model, shadowing and carrier of the plant's random channel terms (sim/perturbations.py)
    channel_noise: PerturbationSettings | None = None

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


class ClosedLoop:
    """Flies one mission from its parts (``assembly.parts`` makes them from a scenario):
    ``run(progress)`` returns a MissionResult."""

    def __init__(self, *, vehicle: Multirotor, scene: RadioScene, source: SourceTrajectory, planner: Planner,
                 controller: RelayController, plant: ca.Function, settings: SimSettings,
                 sensing: JammerSensing | None = None, air: Air | None = None, blockage: Blockage | None = None):
        self.veh, self.scene, self.source, self.planner = vehicle, scene, source, planner
        self.air = air  # [wind]: the plant steps through it (drag in the wind) and its observer feeds the NMPC
        self.sensing = sensing
        self.controller, self.plant, self.settings = controller, plant, settings
        self.spec = controller.spec
        self.columns = log_columns(self.veh.n_rotors)
        self.csi_rng = generator(settings.seed, "csi")  # one stream per purpose (models/streams.py)
        self.process_rng = generator(settings.seed, "process")
        self.perturbations = settings.link_perturbations(scene)
        self.columns = self.columns + jammer_columns(scene) + self.perturbations.columns + (sensing.columns if sensing else [])
        self._bs_position = scene.fixed_pose(scene.name_of("base_station")).position
        self._noise_values: dict[str, Any] = {}  # log values of the random terms and the jammer estimate
        self.names = {role: scene.name_of(role) for role in ("base_station", "source", "relay")}
        if air is not None:
            self.columns = self.columns + air.wind_columns() + air.columns(self.names["relay"])
        self.blockage = blockage if blockage is not None and blockage.active else None  # obstacles that block radio
        if self.blockage is not None:
            self.columns = self.columns + self.blockage.columns(scene)
        self.timings: list[StepTiming] = []
        self.bench_points: list[BenchPoint] = []
        # the relay's side of each step (planner, stage parameters, NMPC), as ar.controller(sc).step flies it
        self.stepper = RelayStepper(vehicle=vehicle, planner=planner, controller=controller, period_s=settings.period_s,
                                    jammers=self._oracle_jammers)

    @property
    def nmpc(self):
        return self.controller.nmpc

    def _channel(self, t, x1, p2, eta2, v2) -> ChannelState:
        """True channel (the scene's antennas, jammer schedules, fading); the relay's jammer readings and
        estimate when it estimates them."""
        p1 = x1[0:3]
        poses = relay_source_poses(self.scene, self.names, x1, p2, eta2)
        fade, self._noise_values = None, {}
        positions = {self.names["relay"]: p1, self.names["source"]: p2, self.names["base_station"]: self._bs_position}
        if self.perturbations.active:  # the paper's channel has no random term: nothing to build per step
            velocities = {self.names["relay"]: x1[6:9], self.names["source"]: v2, self.names["base_station"]: np.zeros(3)}
            fade, self._noise_values = self.perturbations.step(t, positions, velocities)
        if self.blockage is not None:  # a link through an obstacle that blocks radio loses its nlos_loss_db
            blocked, values = self.blockage.step(self.scene, t, positions)
            fade = blocked if fade is None else fade * blocked
            self._noise_values = {**self._noise_values, **values}
        state = self.scene.evaluate(t, poses, fading=fade)
        if self.sensing is not None:
            bs = self.names["base_station"]
            self._noise_values = {**self._noise_values, **self.sensing.step(t, state, {**poses, bs: self.scene.fixed_pose(bs)})}
        return state

    def _oracle_jammers(self, t: float) -> tuple[np.ndarray, np.ndarray, None]:
        st = self.settings
        return (*known_jammers(self.scene, t, st.senses_jammer_state, st.csi_noise_m, self.csi_rng), None)

    def run(self, progress=None) -> MissionResult:
        st, veh = self.settings, self.veh
        period = st.period_s
        n_steps = step_count(st.duration_s, period)
        x = veh.hover_state(st.relay_start)
        u = np.zeros(veh.n_rotors)
        # flags and the status text recorded by name: their own dtypes (the rest, jammer_on too, float until log_frame)
        log = new_log(self.columns, n_steps, lambda c: LOG_COLUMN_TYPES.get(c, float) if c in RECORDED_BY_NAME else float)
        wall0 = time.perf_counter()
        aborted, flown, exit_status = None, n_steps, None
        with full_collections_paused():  # a full collection took 70-100 ms of one step (sim/realtime.py)
            for k in range(n_steps):
                t = k * period
                src = self.source.state(t)
                eta2 = src.attitude(veh.gravity)
                # what the controller knows: MRAV-2 over the optical link, the jammers after tau_E (with CSI noise)
                p2_meas = src.p + self.csi_rng.normal(0.0, st.csi_noise_m, 3) if st.csi_noise_m > 0 else src.p
                pj_std = None
                if self.sensing is not None:  # what the relay estimated from its readings up to the last step
                    pj_meas, pj_powers, pj_std = self.sensing.estimate.planner_view(st.senses_jammer_state)
                else:
                    pj_meas, pj_powers = known_jammers(self.scene, t, st.senses_jammer_state, st.csi_noise_m, self.csi_rng)
                if self.air is not None:
                    self.air.begin()
                ref, P = self.stepper.prepare(t, x, SourceState(p2_meas, src.v, src.a), jammers=(pj_meas, pj_powers, pj_std),
                                              a_ext=self.air.estimate(self.names["relay"]) if self.air else None)
                planner_ms = self.stepper.planner_ms
                if k % BENCH_POINT_EVERY == BENCH_POINT_OFFSET:  # samples for benchmarking a full solve at the same points
                    self.bench_points.append(BenchPoint(x.copy(), u.copy(), P.copy(), self.nmpc.guess() if self.nmpc.initialized else None))
                info = self.stepper.act(x, P)
                u = info.u
                channel = self._channel(t, x, src.p, eta2, src.v)
                self.timings.append(StepTiming(info.prep_ms, info.feedback_ms, info.qp_iters, planner_ms,
                                               self.sensing.last_ms if self.sensing else 0.0))
                self._record(log, k, t, x, u, src.p, eta2, ref, channel, info)
                d = np.concatenate([self.process_rng.normal(0.0, st.process_noise_v, 3),
                                    self.process_rng.normal(0.0, st.process_noise_w, 3)])
                x = self.air.advance(self.names["relay"], x, u, d) if self.air else np.asarray(self.plant(x, u, d)).ravel()
                if not np.all(np.isfinite(x)):  # the steps flown are kept; the run is reported unsafe
                    aborted, flown = f"the plant's state became non-finite after t = {t:.3f} s", k + 1
                    exit_status = ExitStatus.NON_FINITE.value
                    break
                if progress is not None:
                    progress(k + 1, n_steps)
        wall = time.perf_counter() - wall0
        if flown < n_steps:
            log = steps_flown(log, flown)
        return MissionResult(log=log, wall_s=wall, sim_s=(flown - 1) * period, qp_failures=self.nmpc.failures,
                             controller=self.nmpc.settings.fingerprint(), fallback_episodes=self.controller.fallback_episodes,
                             aborted=aborted, exit_status=exit_status)

    def _record(self, log, k, t, x, u, p2, eta2, ref, channel: ChannelState, info: StepInfo):
        row = mission_row(self.veh, self.scene, t, x, u, p2, eta2, ref, channel, self._bs_position, info,
                          bool(self.controller.last_violations))
        row.update(self._noise_values)
        if self.air is not None:
            row.update(self.air.wind_values() | self.air.values(self.names["relay"], x))
        record_row(log, k, row, self.columns)
