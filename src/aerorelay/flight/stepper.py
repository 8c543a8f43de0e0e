"""The relay controller stepped from outside: ``ctrl = ar.controller(sc)``; each control period
``cmd = ctrl.step(t, relay_state, source)`` with the relay's measured state and what it knows of the
source, in aerorelay's frames (world ENU, body FLU; ``flight.frames`` converts at an autopilot's
edge). ``cmd`` carries the rotor speeds and their rates (what aerorelay's plant flies) and the
setpoints an autopilot accepts: position, velocity and acceleration, the attitude quaternion with the
collective thrust normalized to hover, the body rates (the relay's state one control period ahead
under the command, by its own model); the step's computation time and whether it met its deadline.

Inputs that go stale put it in a failsafe, the behaviour autopilots give: a relay state (or source)
older than ``hold_after_s`` makes the command a position hold where the relay last was (no rotor
command: the autopilot holds); older than ``land_after_s`` a landing straight down at ``land_speed_m_s``
to the ground. A fresh state resumes the NMPC.

Inputs are checked before they are flown (``TelemetryCheck``): a relay state or source with a
non-finite entry, a stamp ahead of the clock or behind the last trusted one, or a jump from the last
trusted state that no vehicle of this one's thrust can make in the time between them is not trusted:
the step treats it as stale and says why (``Command.rejected``). A clock ``t`` that goes backwards
or is not finite, or inputs of the wrong shape, are errors (``ValueError`` naming the argument).

``ar.simulate`` flies the same steps (``prepare`` then ``act``) on aerorelay's plant: stepping
``ar.controller(sc)`` over the plant reproduces it bit for bit (tested).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..control.nmpc import StepInfo
from ..control.relay import RelayController
from ..estimation.disturbance import ExternalAccelerationObserver
from ..models.geometry import rotation_zyx
from ..models.vehicle import Multirotor
from ..planning.base import Planner, PlannerInput, Reference
from .frames import quaternion_wxyz
from .readings import JammersFromReadings

MODES = ("nmpc", "fallback", "hold", "land")  # Command.mode
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SourceState:
    """What the relay knows of the source (MRAV-2): position (m), velocity (m/s), acceleration
    (m/s^2), world ENU, and when it was measured (s, the controller's clock; None: now)."""

    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    stamp: float | None = None


@dataclass(frozen=True)
class StaleSettings:
    """When stale inputs hold (s), when they land (s), how fast the landing descends (m/s) and the
    ground's height (m, world z)."""

    hold_after_s: float = 0.05
    land_after_s: float = 3.0
    land_speed_m_s: float = 0.5
    ground_z_m: float = 0.0
    # what a measured state may differ from the kinematic reach of the last trusted one (noise, m and m/s)
    jump_tolerance_m: float = 0.5
    jump_tolerance_m_s: float = 5.0

    def __post_init__(self):
        if not 0 < self.hold_after_s < self.land_after_s or self.land_speed_m_s <= 0:
            raise ValueError(f"StaleSettings: need 0 < hold_after_s ({self.hold_after_s}) < land_after_s "
                             f"({self.land_after_s}) and land_speed_m_s > 0 ({self.land_speed_m_s})")
        if not (self.jump_tolerance_m > 0 and self.jump_tolerance_m_s > 0):
            raise ValueError(f"StaleSettings: need jump_tolerance_m > 0 ({self.jump_tolerance_m}) and "
                             f"jump_tolerance_m_s > 0 ({self.jump_tolerance_m_s})")


@dataclass(frozen=True)
class Command:
    """One control step's output (world ENU, body FLU). ``mode``: ``nmpc``, ``fallback`` (the brake
    law flies), ``hold`` or ``land`` (stale input: setpoints only, ``rotor_speeds_hz`` and
    ``omega_dot_hz_s`` None). Setpoints are the relay's state one period ahead by its model."""

    t: float
    mode: str
    omega_dot_hz_s: np.ndarray | None
    rotor_speeds_hz: np.ndarray | None
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    attitude_wxyz: np.ndarray
    thrust_normalized: float
    body_rates_rad_s: np.ndarray
    compute_ms: float
    deadline_met: bool
    reference: Reference | None = None
    info: StepInfo | None = None
    rejected: str | None = None  # why the step's inputs were not trusted (then mode is hold or land)


class StateSanity:
    """Warnings (logged once each) for a relay state that can be stepped but not flown as meant, the
    mistakes of a user's own simulator: body rates held at zero while the attitude turns (a simulator
    without rates), rotor speeds all zero (the state of a vehicle that reports none: build it with
    ``flight.autopilot_loop.AutopilotLoop`` or ``CommandedState``), a position below the ground (a
    NED position passed as ENU)."""

    TURNING_RAD_S = 0.3  # the attitude turning this fast while the rates read zero
    STEPS = 5  # ... for this many steps in a row

    def __init__(self, ground_z_m: float):
        self.ground = ground_z_m
        self.said: set[str] = set()
        self._still = 0
        self._last: tuple[float, np.ndarray] | None = None

    def _say(self, kind: str, text: str) -> None:
        if kind not in self.said:
            self.said.add(kind)
            log.warning("step: %s", text)

    def check(self, t: float, x: np.ndarray) -> None:
        if np.all(x[12:] == 0.0):
            self._say("rotors", "the relay state's rotor speeds are all zero: the NMPC steps from motors at rest (an "
                                "autopilot reports none: pass the speeds last commanded, as flight.autopilot_loop does)")
        if x[2] < self.ground - 0.5:
            self._say("frame", f"the relay state's z = {x[2]:.2f} m is below the ground ({self.ground:g} m): a NED position "
                               "passed as ENU? (flight.frames.ned_to_enu)")
        if self._last is not None and t > self._last[0]:
            rate = float(np.linalg.norm(x[3:6] - self._last[1])) / (t - self._last[0])
            self._still = self._still + 1 if rate > self.TURNING_RAD_S and not np.any(x[9:12]) else 0
            if self._still >= self.STEPS:
                self._say("rates", f"the relay's attitude turns at {rate:.2f} rad/s while its body rates read zero: the "
                                   "NMPC's model then disagrees with the vehicle (its QPs fail and the brake law flies); pass "
                                   "the measured body rates (rad/s, body FLU)")
        self._last = (t, x[3:6].copy())


class TelemetryCheck:
    """Whether a measured relay state and source can be flown (see the module): ``problem(...)`` says
    why not, or None. The reach from the last trusted state ``(stamp, p, v)`` over ``dt`` is
    ``|p - p0 - v0 dt| <= a_max dt^2 / 2 + jump_tolerance_m`` and ``|v - v0| <= a_max dt +
    jump_tolerance_m_s``, with ``a_max`` the vehicle's full thrust over its mass plus gravity (m/s^2)."""

    def __init__(self, vehicle: Multirotor, stale: StaleSettings):
        F, _ = vehicle.allocation()
        full_thrust = float(np.sum(np.linalg.norm(F, axis=0))) * vehicle.omega_max ** 2
        self.a_max = full_thrust / vehicle.mass + vehicle.gravity
        self.stale = stale
        self.trusted: tuple[float, np.ndarray, np.ndarray] | None = None  # (stamp s, p m, v m/s) last trusted

    def problem(self, t: float, x: np.ndarray | None, stamp: float, source: SourceState | None) -> str | None:
        """Why the relay state ``x`` (stamped ``stamp``) or the ``source`` cannot be trusted at ``t``; None when they can."""
        ahead = self.stale.hold_after_s  # clocks of two processes may differ this much
        if x is not None:
            bad = [name for name, sl in (("position", slice(0, 3)), ("attitude", slice(3, 6)), ("velocity", slice(6, 9)),
                                         ("body rates", slice(9, 12)), ("rotor speeds", slice(12, None)))
                   if not np.all(np.isfinite(x[sl]))]
            if bad:
                return f"relay state not finite ({', '.join(bad)})"
            if not np.isfinite(stamp):
                return "relay state's stamp not finite"
            if stamp > t + ahead:
                return f"relay state stamped {stamp - t:.3f} s ahead of the clock"
            if self.trusted is not None:
                s0, p0, v0 = self.trusted
                if stamp < s0:
                    return f"relay state stamped {s0 - stamp:.3f} s before the last trusted one (time went backwards)"
                dt = stamp - s0
                dp = float(np.linalg.norm(x[0:3] - p0 - v0 * dt))
                dv = float(np.linalg.norm(x[6:9] - v0))
                if dp > 0.5 * self.a_max * dt ** 2 + self.stale.jump_tolerance_m:
                    return f"relay position jumped {dp:.2f} m from the last trusted state in {dt:.3f} s (no vehicle reach)"
                if dv > self.a_max * dt + self.stale.jump_tolerance_m_s:
                    return f"relay velocity jumped {dv:.2f} m/s from the last trusted state in {dt:.3f} s (no vehicle reach)"
        if source is not None:
            if not all(np.all(np.isfinite(v)) for v in (source.p, source.v, source.a)):
                return "source not finite"
            if source.stamp is not None and not (np.isfinite(source.stamp) and source.stamp <= t + ahead):
                return f"source stamped ahead of the clock or not finite ({source.stamp})"
        return None

    def trust(self, stamp: float, x: np.ndarray) -> None:
        """Keep ``x`` (stamped ``stamp``) as the last trusted state."""
        self.trusted = (stamp, x[0:3].copy(), x[6:9].copy())


def checked_source(source: SourceState | None) -> SourceState | None:
    """``source`` with its vectors as float arrays; a ValueError naming the field when one is not three numbers."""
    if source is None:
        return None
    vecs = {}
    for name in ("p", "v", "a"):
        try:
            vecs[name] = np.asarray(getattr(source, name), float)
        except (TypeError, ValueError):
            raise ValueError(f"step: source.{name} must be three numbers (m, m/s, m/s^2 ENU), got {getattr(source, name)!r}") from None
        if vecs[name].shape != (3,):
            raise ValueError(f"step: source.{name} must be three numbers (m, m/s, m/s^2 ENU), got shape {vecs[name].shape}")
    stamp = source.stamp if source.stamp is None else float(source.stamp)
    return SourceState(vecs["p"], vecs["v"], vecs["a"], stamp=stamp)


JammerView = Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray | None]]


class RelayStepper:
    """The planner and the NMPC of one relay, stepped from outside (see the module)."""

    def __init__(self, *, vehicle: Multirotor, planner: Planner | None, controller: RelayController, period_s: float,
                 jammers: JammerView, observer: ExternalAccelerationObserver | None = None,
                 stale: StaleSettings = StaleSettings(), estimated: JammersFromReadings | None = None):
        """``jammers(t)``: the jammers as the relay knows them at ``t``: positions ``(nJ, 3)`` m, the
        powers it plans with (W) and the position std (m; None: known exactly). ``estimated``: the
        jammers are estimated from the readings ``step`` is handed (then ``jammers`` is its view).
        ``planner`` None: a relay of a network whose planner plans every relay (``parameters``)."""
        self.vehicle, self.planner, self.controller, self.period = vehicle, planner, controller, period_s
        self.jammers, self.observer, self.stale, self.estimated = jammers, observer, stale, estimated
        # (time, state) of the last fresh step: where a hold holds and where the next step's readings were taken
        self._last_step: tuple[float, np.ndarray] | None = None
        self.shift = period_s >= controller.spec.ts - 1e-12
        self.u = np.zeros(vehicle.n_rotors)  # the input applied last (Hz/s)
        self.planner_ms = 0.0
        self._x_prev: np.ndarray | None = None
        self._land_from: tuple[float, np.ndarray] | None = None
        self.check = TelemetryCheck(vehicle, stale)
        self.sanity = StateSanity(stale.ground_z_m)
        self._t_last: float | None = None  # the clock of the last step (it must not go backwards)
        F, _ = vehicle.allocation()
        self._thrust_per_speed2 = F

    @property
    def has_state(self) -> bool:
        """Whether a fresh relay state has been stepped (a hold needs a place to hold)."""
        return self._last_step is not None

    # -- the NMPC's step in two phases (ar.simulate calls them with its own measurements) ---------------
    def prepare(self, t: float, x: np.ndarray, source: SourceState, *, jammers=None,
                a_ext: np.ndarray | None = None) -> tuple[Reference, np.ndarray]:
        """The planner's reference and the NMPC's stage parameters for the relay at ``x``; ``jammers``:
        ``(positions, powers, std)`` measured outside (default ``self.jammers(t)``); ``a_ext``: an
        external-acceleration estimate made outside (default: this stepper's observer's, if any)."""
        ref = self.plan(t, x, source, jammers=jammers)
        if a_ext is None and self.observer is not None:
            a_ext = self.observer.estimate
        return ref, self.controller.parameters(ref, source.p, source.v, source.a, a_ext=a_ext)

    def plan(self, t: float, x: np.ndarray, source: SourceState, *, jammers=None) -> Reference:
        """This relay's planner's reference for the relay at ``x`` (its time in ``planner_ms``)."""
        if self.planner is None:
            raise ValueError("step: this relay's references come from its network's planner (it has none of its own)")
        pj, powers, std = jammers if jammers is not None else self.jammers(t)
        t0 = time.perf_counter()
        ref = self.planner.update(PlannerInput(t=t, dt=self.period, p1=x[0:3].copy(), p2=source.p, v2=source.v, a2=source.a,
                                               jammer_positions=pj, jammer_powers=powers, jammer_std_m=std,
                                               psi1=float(x[5]), v1=x[6:9].copy()))
        self.planner_ms = (time.perf_counter() - t0) * 1e3
        return ref

    def parameters(self, ref: Reference, *, p2_path: np.ndarray, p0_path: np.ndarray | None = None,
                   others: np.ndarray | None = None, separation_m: float = 0.0,
                   a_ext: np.ndarray | None = None) -> np.ndarray:
        """The NMPC's stage parameters for the reference ``ref`` of a relay in a network: its upstream node's
        predicted positions ``p2_path`` ``(3, N + 1)`` (m, world), its downstream node's ``p0_path`` (when its
        OCP takes it), the other vehicles' ``others`` and the separation to keep (m), ``a_ext`` (m/s^2)."""
        if a_ext is None and self.observer is not None:
            a_ext = self.observer.estimate
        zero = np.zeros(3)
        return self.controller.parameters(ref, zero, zero, zero, others, separation_m, p2_path=p2_path, p0_path=p0_path,
                                          a_ext=a_ext)

    def act(self, x: np.ndarray, P: np.ndarray) -> StepInfo:
        """The NMPC's (or the fail-safe's) input for the relay at ``x`` with stage parameters ``P``."""
        info = self.controller.step(x, self.u, P, shift=self.shift)
        self.u = info.u
        return info

    # -- the step API -----------------------------------------------------------------------------------
    def step(self, t: float, relay_state: np.ndarray | None, source: SourceState | None, *,
             state_stamp: float | None = None, jammers=None, readings: Mapping[str, float] | None = None) -> Command:
        """One control step at ``t`` (s): ``relay_state`` the full state ``(p, eta, v, omega, Omega)``
        (m, rad ZYX, m/s, rad/s FLU, Hz; None: no new state), measured at ``state_stamp`` (None: ``t``).
        ``readings``: with ``jammer.localization = "estimated"``, what each receiver (by node name: the
        relay, the base station with ``estimation.use_bs``) measured over the last period, interference
        plus noise in W, taken where the relay was at its last step (``flight/readings.py``)."""
        t0 = time.perf_counter()
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"step: t must be a finite time (s), got {t}")
        if self._t_last is not None and t < self._t_last:
            raise ValueError(f"step: t = {t:.6g} s is before the previous step's {self._t_last:.6g} s (the clock went backwards)")
        x = None
        if relay_state is not None:
            x = np.asarray(relay_state, float)
            if x.shape != (self.vehicle.nx,):
                raise ValueError(f"step: relay_state must have {self.vehicle.nx} entries (p, eta, v, omega, Omega), got {x.shape}")
        source = checked_source(source)
        self._t_last = t
        stamp = t if state_stamp is None else float(state_stamp)
        rejected = self.check.problem(t, x, stamp, source)
        if readings:
            self._fold(t, x if rejected is None else None, readings)
        if rejected is not None or self.stale_reason(t, x, stamp, source) is not None:
            self._x_prev = None  # the observer restarts from the next fresh state (a gap is not one period)
            if rejected is not None and self._last_step is None:
                raise ValueError(f"step: {rejected}, and no trusted relay state yet (nothing to hold)")
            cmd = self._stale_command(t, t0)
            return cmd if rejected is None else replace(cmd, rejected=rejected)
        assert x is not None and source is not None
        self.check.trust(stamp, x)
        self.sanity.check(t, x)
        if self.observer is not None and self._x_prev is not None:
            self.observer.update(self._x_prev, self.u, x)
        self._land_from = None
        self._last_step = (t, x.copy())
        ref, P = self.prepare(t, x, source, jammers=jammers)
        info = self.act(x, P)
        self._x_prev = x.copy()
        return self.command(t, x, info, ref, t0)

    def stale_reason(self, t: float, x: np.ndarray | None, stamp: float, source: SourceState | None) -> str | None:
        """Why the relay state ``x`` (stamped ``stamp``) and ``source`` are not fresh at ``t`` (missing, or
        older than ``hold_after_s``); None when both are."""
        hold = self.stale.hold_after_s
        if x is None:
            return "no relay state"
        if source is None:
            return "no source"
        if t - stamp > hold:
            return f"relay state {t - stamp:.3f} s old"
        if source.stamp is not None and t - source.stamp > hold:
            return f"source {t - source.stamp:.3f} s old"
        return None

    def _fold(self, t: float, relay_state: np.ndarray | None, readings: Mapping[str, float]) -> None:
        """Fold readings into the estimate: taken at the last step's time and pose (the current ones at the first)."""
        if self.estimated is None:
            raise ValueError("step: readings given, but the scenario's jammers are not estimated "
                             "(jammer.localization = 'estimated')")
        for name, w in readings.items():
            if not (isinstance(w, int | float | np.floating) and np.isfinite(w) and w >= 0):
                raise ValueError(f"step: readings[{name!r}] must be a finite power >= 0 W, got {w!r}")
        if self._last_step is not None:
            self.estimated.add(*self._last_step, readings)
        elif relay_state is not None:
            self.estimated.add(t, np.asarray(relay_state, float), readings)

    def command(self, t: float, x: np.ndarray, info: StepInfo, ref: Reference, t0: float) -> Command:
        """The ``Command`` of a step flown at ``x`` with ``info`` on ``ref`` (setpoints one period ahead by the model);
        ``t0``: when the step began (``time.perf_counter``), for its compute time."""
        veh = self.vehicle
        x1 = np.asarray(veh.rk4_step(x, info.u, self.period), float)  # one period ahead under the command
        a_ext = self.observer.estimate if self.observer is not None else np.zeros(3)
        acc = np.asarray(veh.dynamics(x1, info.u, a_ext), float)[6:9]
        thrust = float(np.linalg.norm(self._thrust_per_speed2 @ x1[12:] ** 2)) / (veh.mass * veh.gravity)
        ms = (time.perf_counter() - t0) * 1e3
        return Command(t=t, mode="fallback" if info.fallback else "nmpc", omega_dot_hz_s=info.u.copy(),
                       rotor_speeds_hz=x[12:] + info.u * self.period, position_m=x1[0:3], velocity_m_s=x1[6:9],
                       acceleration_m_s2=acc, attitude_wxyz=quaternion_wxyz(rotation_zyx(x1[3:6])), thrust_normalized=thrust,
                       body_rates_rad_s=x1[9:12], compute_ms=ms, deadline_met=ms <= self.period * 1e3, reference=ref, info=info)

    def remember(self, t: float, x: np.ndarray) -> None:
        """A fresh state ``x`` flown at ``t`` (s) by a caller that steps this relay's NMPC itself (a network's
        step): where a later hold holds, and the landing's clock restarts."""
        self._land_from = None
        self._last_step = (t, np.asarray(x, float).copy())

    def hold_command(self, t: float, t0: float) -> Command:
        """The stale-input command at ``t`` (s): hold where the relay last was, land once stale for
        ``land_after_s`` (``t0``: when the step began, ``time.perf_counter``)."""
        return self._stale_command(t, t0)

    def _stale_command(self, t: float, t0: float) -> Command:
        """Hold where the relay last was (level, its last yaw); land straight down once the input stays stale."""
        if self._last_step is None:
            raise ValueError("step: no relay state and source received yet (nothing to hold)")
        since, x = self._last_step
        p, yaw = x[0:3], float(x[5])
        mode, v = "hold", np.zeros(3)
        target = p.copy()
        if t - since > self.stale.land_after_s:
            mode = "land"
            if self._land_from is None:
                self._land_from = (t, p.copy())
            t_land, p_land = self._land_from
            target[2] = max(self.stale.ground_z_m, p_land[2] - self.stale.land_speed_m_s * (t - t_land))
            if target[2] > self.stale.ground_z_m:
                v = np.array([0.0, 0.0, -self.stale.land_speed_m_s])
        ms = (time.perf_counter() - t0) * 1e3
        return Command(t=t, mode=mode, omega_dot_hz_s=None, rotor_speeds_hz=None, position_m=target, velocity_m_s=v,
                       acceleration_m_s2=np.zeros(3), attitude_wxyz=quaternion_wxyz(rotation_zyx([0.0, 0.0, yaw])),
                       thrust_normalized=1.0,
                       body_rates_rad_s=np.zeros(3), compute_ms=ms, deadline_met=ms <= self.period * 1e3)

