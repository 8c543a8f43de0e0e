"""The relay controller: OCP, NMPC, stage parameters and the fail-safe.

``RelayController(spec, weights, mu=..., failsafe=...)`` (built from a scenario by
``assembly.parts``) owns the NMPC (``nmpc.py``) and the brake law (``failsafe.py``).
Each control step: ``parameters(ref, p2, v2, a2)`` fills the named stage parameters from the
planner's reference and MRAV-2's state; ``step(x, u_prev, P)`` runs one RTI. After
``controller.failsafe.failures_to_fallback`` consecutive QP failures, or at once on a non-finite
state or input, the plan is reset and the brake law flies the relay to rest inside the
workspace; the NMPC is tried again every step from a fresh plan and takes over after
``successes_to_resume`` consecutive successes. The flight-safety supervisor (``supervisor.py``)
hands over at once, whatever the QP status, when the state leaves its safety envelope, and the
NMPC resumes only from inside it. Every episode is logged.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..models.geometry import constant_acceleration_path, realign_with_thrust, thrust_direction_from_acceleration
from ..models.obstacles import Obstacle, separating_planes
from ..models.state import ETA, P, V
from .failsafe import BrakeLaw, Hold
from .nmpc import NMPC, NmpcSettings, StepInfo
from .ocp import OcpSpec
from .supervisor import SafetyEnvelope

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class FailsafeSettings:
    """When the brake law takes over (consecutive QP failures) and hands back (consecutive
    successes); how far inside the workspace (m) its hold point stays."""

    failures_to_fallback: int = 3
    successes_to_resume: int = 5
    workspace_margin_m: float = 0.5


class RelayController:
    """NMPC + fail-safe for one mission (stateful). ``weights``: the ``sw_*`` stage parameters
    (square roots of the weights per stage); ``mu``: the mutual-alignment threshold."""

    def __init__(self, spec: OcpSpec, weights: dict[str, np.ndarray], *, mu: float,
                 failsafe: FailsafeSettings = FailsafeSettings(), settings: NmpcSettings | None = None,
                 envelope: SafetyEnvelope | None = None, obstacles: tuple[Obstacle, ...] = (), name: str = ""):
        if len(obstacles) != spec.obstacles:
            raise ValueError(f"RelayController: the OCP keeps out of {spec.obstacles} obstacles, {len(obstacles)} given")
        self.spec = spec
        self.name = name  # the relay it flies (a network's recording and logs tell its relays apart by it)
        self.obstacles = obstacles  # grown by their margins: the NMPC keeps out of these
        self.envelope = envelope  # None: no supervisor (QP failures alone hand over)
        self.last_violations: list[str] = []
        self.safety_handovers = 0
        self.mu = mu
        self.nmpc = NMPC(self.spec, settings)
        # where the plan the next step starts from is read (the obstacles' planes, the other relays' separation
        # rows): this NMPC's, or what flies the step instead (the C library: assembly.c_engine)
        self.guess_source: Callable[[], np.ndarray | None] = self.own_guess
        self.weights = weights
        fs = failsafe
        self.brake = BrakeLaw(spec.vehicle, spec.workspace_min, spec.workspace_max, margin_m=fs.workspace_margin_m)
        self.failures_to_fallback, self.successes_to_resume = fs.failures_to_fallback, fs.successes_to_resume
        self.fallback_active = False
        self.fallback_episodes = 0
        self._consecutive_failures = 0
        self._successes = 0
        self._hold: Hold = self.brake.hold(np.zeros(3))

    @property
    def settings(self) -> NmpcSettings:
        return self.nmpc.settings

    def parameters(self, ref, p2, v2, a2, others: np.ndarray | None = None, separation_m: float = 0.0, *,
                   p2_path: np.ndarray | None = None, p0_path: np.ndarray | None = None,
                   a_ext: np.ndarray | None = None) -> np.ndarray:
        """Stage parameters: the governed reference extrapolated at ``v_ref``, ``rho_d`` from
        ``a_ref`` (eq. 20, ``(a_d + g e3)/|a_d + g e3|``), MRAV-2 at constant acceleration (or its
        predicted ``p2_path`` ``(3, N + 1)``, m: a fleet's upstream node), mu, weights; a relay of a
        fleet: the other vehicles' predicted positions ``others`` ``(3 neighbours, N + 1)`` (m, world)
        and the separation to keep (m) (``spec.neighbours``), the next node toward the base station
        ``p0_path`` ``(3, N + 1)`` (m, world; ``spec.p0_parameter``); ``a_ext``: the observer's external
        acceleration (m/s^2, world; ``spec.disturbance``; None: zero), which the thrust direction also
        counters; with obstacles, one separating plane per obstacle and stage from the previous plan."""
        spec = self.spec
        tk = spec.ts * np.arange(spec.horizon + 1)
        a_ext = np.zeros(3) if a_ext is None else np.asarray(a_ext, float)
        # rho_d (eq. 20; the thrust also counters the external acceleration), unless a planner gives the antenna axis:
        # then that axis relative to the thrust a_ref needs, carried with the thrust that also counters a_ext
        g = spec.vehicle.gravity
        if ref.axis is None:
            rho_d = thrust_direction_from_acceleration(ref.a_ref - a_ext, g)
        elif np.any(a_ext != 0.0):
            rho_d = realign_with_thrust(ref.axis, ref.a_ref, ref.a_ref - a_ext, g)
        else:
            rho_d = ref.axis
        values = {
            "p_ref": ref.p_ref[:, None] + ref.v_ref[:, None] * tk,
            "v_ref": ref.v_ref,
            "rho_d": rho_d,
            "p2": constant_acceleration_path(p2, v2, a2, tk) if p2_path is None else p2_path,
            "mu": self.mu,
            "psi_ref": ref.yaw,
            **self.weights,
        }
        if spec.neighbours:
            if others is None or np.shape(others) != (3 * spec.neighbours, spec.horizon + 1):
                raise ValueError(f"parameters: others must be (3 x {spec.neighbours}, {spec.horizon + 1}), got "
                                 f"{None if others is None else np.shape(others)}")
            values["p_others"], values["separation_m"] = others, separation_m
        if spec.disturbance:
            values["a_ext"] = a_ext
        if spec.obstacles:
            values["obstacle_planes"] = self.obstacle_planes(values["p_ref"])
        if spec.p0_parameter:
            if p0_path is None:
                raise ValueError(f"parameters: this relay's OCP needs p0_path (3, {spec.horizon + 1}), its next node toward the base station")
            values["p0"] = p0_path
        return spec.params.matrix(spec.horizon + 1, values)

    def own_guess(self) -> np.ndarray | None:
        """This NMPC's plan the next step starts from, ``(nx, N + 1)`` (None before its first step)."""
        return self.nmpc.plan()[0] if self.nmpc.initialized else None

    def obstacle_planes(self, p_ref: np.ndarray) -> np.ndarray:
        """``(4 obstacles, N + 1)``: per stage and obstacle the separating plane ``(n, c)`` through the
        grown obstacle's nearest point to the previous plan's position at that stage (before the first
        plan: to the reference ``p_ref`` ``(3, N + 1)``)."""
        plan = self.guess_source()
        pos = plan[P] if plan is not None else p_ref
        out = np.empty((4 * len(self.obstacles), pos.shape[1]))
        for j, o in enumerate(self.obstacles):
            n, c = separating_planes(o, pos.T)
            out[4 * j : 4 * j + 3], out[4 * j + 3] = n.T, c
        return out

    def step(self, x: np.ndarray, u_prev: np.ndarray, P: np.ndarray, shift: bool = True) -> StepInfo:
        """One control step: the NMPC's input, or the brake law's while the NMPC cannot fly."""
        x = np.asarray(x, float)
        if not np.all(np.isfinite(x)):
            self._enter_fallback(x, "non-finite state")
            return StepInfo(self.brake(x, self._hold), False, "non-finite state", 0.0, 0.0, float("nan"), fallback=True)
        unsafe = self.envelope.violations(x) if self.envelope is not None else []
        self.last_violations = unsafe
        if unsafe:  # outside the safety envelope: the brake law flies, whatever the QP says
            self.safety_handovers += not self.fallback_active
            self._enter_fallback(x, "safety envelope: " + "; ".join(unsafe))
        if self.fallback_active:
            return self._fallback_step(x, u_prev, P, shift)
        info = self.nmpc.step(x, u_prev, P, shift)
        if info.ok:
            self._consecutive_failures = 0
            return info
        self._consecutive_failures += 1
        if self._consecutive_failures >= self.failures_to_fallback or not info.input_finite:
            self._enter_fallback(x, f"{self._consecutive_failures} consecutive QP failures ({info.status})")
            return replace(info, u=self.brake(x, self._hold), fallback=True)
        return info

    def _enter_fallback(self, x: np.ndarray, why: str):
        if not self.fallback_active:
            self.fallback_active = True
            self.fallback_episodes += 1
            self._hold = self.brake.hold(x[P], x[V], x[ETA]) if np.all(np.isfinite(x[P])) else self.brake.hold(self._hold.point)
            log.warning("fail-safe: %s; brake law stops the relay at %s (%.1f rad/s)", why, np.round(self._hold.point, 2), self._hold.freq)
        self._successes = 0
        self._consecutive_failures = 0

    def _fallback_step(self, x, u_prev, P, shift) -> StepInfo:
        """Brake law input; the NMPC is tried from a fresh plan and resumes after enough successes."""
        self.nmpc.initialized = False
        info = self.nmpc.step(x, u_prev, P, shift)
        # resume only once the brake law has slowed the relay (a hand-over back and forth at speed,
        # a QP that fails again right after, ends each episode nearer a wall), and after a safety
        # hand-over only while the envelope allows another one
        env = self.envelope
        slow = env is None or env.at_rest(x)
        handovers_left = env is None or self.safety_handovers == 0 or self.safety_handovers < env.max_handovers
        may_resume = not self.last_violations and slow and handovers_left
        self._successes = self._successes + 1 if info.ok and may_resume else 0
        if self._successes >= self.successes_to_resume:
            self.fallback_active = False
            self._successes = 0
            log.warning("fail-safe: NMPC resumes after %d successful QPs", self.successes_to_resume)
            return info
        return replace(info, u=self.brake(x, self._hold), fallback=True)
