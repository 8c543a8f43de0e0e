"""Closed-loop relay mission: planner + relay controller + RK4 plant + true channel.

The plant (MRAV-1) is integrated by RK4 at ``sim.plant_rate_hz`` with the controller's input
held over each control period. At every control step the true channel is evaluated with real
antenna gains and both vehicles' attitudes (MRAV-2's follows its acceleration), with Rician
fading when configured. One log row per control step; the columns follow the vehicle's rotor
count (``log_columns``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..config import Scenario
from ..control.nmpc import NmpcSettings, StepInfo
from ..control.relay import RelayController
from ..models.channel import end_to_end_capacity, jammer_gain_sq, legitimate_gain_sq, misalignment, mutual_alignment, sinr
from ..models.fading import RicianFading
from ..models.geometry import rotation_zyx
from ..planning.base import PlannerInput, build_planner
from .mission import source_trajectory


def log_columns(n_rotors: int) -> list[str]:
    """The per-step log's columns, in order, for a relay with ``n_rotors`` rotors."""
    return (
        ["t", "p1_x", "p1_y", "p1_z", "phi1", "theta1", "psi1", "v1_x", "v1_y", "v1_z", "omega1_x", "omega1_y", "omega1_z"]
        + [f"Omega_{i}" for i in range(1, n_rotors + 1)]
        + [f"u_{i}" for i in range(1, n_rotors + 1)]
        + ["p2_x", "p2_y", "p2_z", "phi2", "theta2", "psi2", "pd_x", "pd_y", "pd_z", "jammer_on", "gamma_21", "gamma_10",
           "se_21", "se_10", "capacity", "v_12", "v_10", "mutual_alignment", "slack_max", "solve_ms", "feedback_ms",
           "qp_status", "fallback", "taylor_rel_err"]
    )


def plant_step_function(sc: Scenario) -> ca.Function:
    """CasADi function ``(x, u, d) -> x`` advancing one control period with RK4 sub-steps.

    ``d = (a_dist (m/s^2, world), alpha_dist (rad/s^2, body))`` is a process disturbance held
    over the period.
    """
    veh = sc.platform.vehicle()
    n_sub = int(round(sc.sim.plant_rate_hz * sc.control_period_s))
    dt = 1.0 / sc.sim.plant_rate_hz
    x, u, d = ca.SX.sym("x", veh.nx), ca.SX.sym("u", veh.n_rotors), ca.SX.sym("d", 6)

    def f(xx):
        dx = veh.dynamics(xx, u)
        return dx + ca.vertcat(ca.SX(3, 1), ca.SX(3, 1), d[:3], d[3:], ca.SX(veh.n_rotors, 1))

    xk = x
    for _ in range(n_sub):
        k1 = f(xk)
        k2 = f(xk + 0.5 * dt * k1)
        k3 = f(xk + 0.5 * dt * k2)
        k4 = f(xk + dt * k3)
        xk = xk + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("plant_step", [x, u, d], [xk])


@dataclass
class MissionResult:
    """Per-step log (dict of equal-length arrays) and run facts."""

    log: dict
    wall_s: float
    sim_s: float
    qp_failures: int
    scenario: Scenario
    controller: str = ""  # NmpcSettings.fingerprint() of the controller that flew it
    fallback_episodes: int = 0


class ClosedLoop:
    """Simulates one scenario. ``run(progress)`` returns a MissionResult."""

    def __init__(self, sc: Scenario, nmpc_settings: NmpcSettings | None = None):
        self.sc = sc
        self.controller = RelayController(sc, nmpc_settings)
        self.spec = self.controller.spec
        self.veh = self.spec.vehicle
        self.columns = log_columns(self.veh.n_rotors)
        self._numeric_columns = [c for c in self.columns if c not in ("qp_status", "fallback", "taylor_rel_err")]
        self.plant = plant_step_function(sc)
        self.source = source_trajectory(sc.mission)
        self.planner = build_planner(sc, self.source)
        self.jammer = sc.jammer.build()
        self.patterns = sc.antenna.patterns()
        self.rng = np.random.default_rng(sc.seed)
        k_db = sc.perturbations.fading_k_db
        self.fading = None if k_db is None or math.isinf(k_db) else RicianFading(k_db, seed=sc.seed + 1)
        # (preparation ms, feedback ms, IPM iterations, planner ms) per step
        self.timings: list[tuple[float, float, int, float]] = []
        self.bench_points: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]] = []

    @property
    def nmpc(self):
        return self.controller.nmpc

    def _planned_jammer_power(self, t: float) -> float:
        """P_J the planner plans with: 0 before localization (tau_E); afterwards the nominal
        power, or the power actually radiated now when the controller senses the schedule."""
        if not self.jammer.is_localized(t):
            return 0.0
        if self.sc.controller.senses_jammer_state:
            return float(self.jammer.power_at(t))
        return self.sc.jammer.power_w

    def _channel(self, t, x1, p2, eta2):
        """True SINRs (real gains, jammer schedule, fading) and the relay's misalignments."""
        sc = self.sc
        p0 = np.array(sc.nodes.bs, float)
        p1, R1 = x1[0:3], rotation_zyx(x1[3:6])
        R2, R0 = rotation_zyx(eta2), np.eye(3)
        pj = self.jammer.position
        PJ = float(self.jammer.power_at(t))
        fade = self.fading.power_gain(4) if self.fading is not None else np.ones(4)
        pat = self.patterns
        h21 = legitimate_gain_sq(p2, R2, p1, R1, pat.source, pat.relay) * fade[0]
        h10 = legitimate_gain_sq(p1, R1, p0, R0, pat.relay, pat.bs) * fade[1]
        f1 = jammer_gain_sq(pj, p1, R1, pat.relay) * fade[2]
        f0 = jammer_gain_sq(pj, p0, R0, pat.bs) * fade[3]
        kw = dict(tx_power=sc.channel.tx_power_w, jam_power=PJ, noise_power=sc.channel.noise_power_w)
        g21, g10 = float(sinr(h21, f1, **kw)), float(sinr(h10, f0, **kw))
        v12, v10 = float(misalignment(p1, R1, p2)), float(misalignment(p1, R1, p0))
        return PJ > 0, g21, g10, v12, v10

    def run(self, progress=None) -> MissionResult:
        sc, veh = self.sc, self.veh
        period = sc.control_period_s
        n_steps = int(math.floor(sc.duration_s / period + 1e-9)) + 1
        shift = period >= self.spec.ts - 1e-12
        x = veh.hover_state(sc.nodes.relay)
        u = np.zeros(veh.n_rotors)
        log: dict[str, np.ndarray] = {c: np.empty(n_steps) for c in self.columns}
        log["qp_status"] = np.empty(n_steps, dtype=object)
        log["fallback"] = np.zeros(n_steps, dtype=bool)
        pert = sc.perturbations
        wall0 = time.perf_counter()
        for k in range(n_steps):
            t = k * period
            src = self.source.state(t)
            eta2 = src.attitude(veh.gravity)
            # what the controller knows: MRAV-2 over the optical link, the jammer after tau_E (with CSI noise)
            p2_meas = src.p + self.rng.normal(0.0, pert.csi_noise_m, 3) if pert.csi_noise_m > 0 else src.p
            pj_meas = self.jammer.position + (self.rng.normal(0.0, pert.csi_noise_m, 3) if pert.csi_noise_m > 0 else 0.0)
            t_plan = time.perf_counter()
            ref = self.planner.update(PlannerInput(t, period, x[0:3].copy(), p2_meas, src.v, src.a, pj_meas,
                                                   self._planned_jammer_power(t)))
            planner_ms = (time.perf_counter() - t_plan) * 1e3
            P = self.controller.parameters(ref, p2_meas, src.v, src.a)
            if k % 500 == 250:  # (x, u_prev, P, guess) samples for benchmarking a full solve at the same points
                self.bench_points.append((x.copy(), u.copy(), P.copy(), self.nmpc.guess() if self.nmpc.initialized else None))
            info = self.controller.step(x, u, P, shift=shift)
            self.timings.append((info.prep_ms, info.feedback_ms, info.qp_iters, planner_ms))
            u = info.u
            jam_on, g21, g10, v12, v10 = self._channel(t, x, src.p, eta2)
            self._record(log, k, t, x, u, src.p, eta2, ref, (jam_on, g21, g10, v12, v10), info)
            d = np.concatenate([self.rng.normal(0.0, pert.process_noise_v, 3), self.rng.normal(0.0, pert.process_noise_w, 3)])
            x = np.asarray(self.plant(x, u, d)).ravel()
            if not np.all(np.isfinite(x)):
                raise FloatingPointError(f"plant state became non-finite at t = {t:.3f} s")
            if progress is not None:
                progress(k + 1, n_steps)
        wall = time.perf_counter() - wall0
        return MissionResult(log, wall, (n_steps - 1) * period, self.nmpc.failures, sc, self.nmpc.settings.fingerprint(),
                             self.controller.fallback_episodes)

    def _record(self, log, k, t, x, u, p2, eta2, ref, channel, info: StepInfo):
        jam_on, g21, g10, v12, v10 = channel
        nr = self.veh.n_rotors
        if x.shape != (self.veh.nx,) or u.shape != (nr,):
            raise ValueError(f"log row: state {x.shape} / input {u.shape} do not match the {nr}-rotor vehicle")
        se21, se10 = math.log2(1 + g21), math.log2(1 + g10)
        values = (
            [t, *x[0:12], *x[12 : 12 + nr], *u, *p2, *eta2, *ref.p_ref, float(jam_on), g21, g10,
             se21, se10, float(end_to_end_capacity(g21, g10, self.sc.channel.bandwidth)), v12, v10,
             float(mutual_alignment(v12, v10)), info.slack_max, info.solve_ms, info.feedback_ms]
        )
        for name, val in zip(self._numeric_columns, values, strict=True):
            log[name][k] = val
        log["qp_status"][k] = info.status if info.ok else f"failed:{info.status}"
        log["fallback"][k] = info.fallback
        log["taylor_rel_err"][k] = ref.taylor_rel_err
