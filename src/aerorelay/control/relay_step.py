"""One relay's part of the controller (``RelayStep``) and the step API's vocabulary: what a relay knows of a
source (``SourceState``), when stale inputs hold and land (``StaleSettings``), one control step's output
(``Command``), the telemetry check (``TelemetryCheck``) and the warnings for a state that can be stepped but
not flown as meant (``StateSanity``). ``control.network.Controller`` steps every relay of any network with them.

Inputs that go stale put a relay in a failsafe, the behaviour autopilots give: a relay state (or source)
older than ``hold_after_s`` makes the command a position hold where the relay last was (no rotor
command: the autopilot holds); older than ``land_after_s`` a landing straight down at ``land_speed_m_s``
to the ground. A fresh state resumes the NMPC.

Inputs are checked before they are flown (``TelemetryCheck``): a relay state or source with a
non-finite entry, a stamp ahead of the clock or behind the last trusted one, or a jump from the last
trusted state that no vehicle of this one's thrust can make in the time between them is not trusted:
the step treats it as stale and says why (``Command.rejected``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..estimation.disturbance import ExternalAccelerationObserver
from ..models.geometry import quaternion_wxyz, rotation_zyx
from ..models.state import ETA, OMEGA, ROTORS, YAW, P, V
from ..models.vehicle import Multirotor
from ..planning.base import Reference
from .nmpc import StepInfo
from .relay import RelayController

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
    # a source's reach between two of its reports (m/s^2: a multirotor inspector's, about 3 g): a farther jump is not
    # planned on (a 1 km jump of the source's reported position was planned on by one relay and by a chain alike)
    source_accel_max_m_s2: float = 30.0

    def too_old(self, t: float, stamp: float) -> bool:
        """Whether an input measured at ``stamp`` is stale at ``t`` (older than ``hold_after_s``): the one rule."""
        return t - stamp > self.hold_after_s

    def __post_init__(self):
        if not 0 < self.hold_after_s < self.land_after_s or self.land_speed_m_s <= 0:
            raise ValueError(f"StaleSettings: need 0 < hold_after_s ({self.hold_after_s}) < land_after_s "
                             f"({self.land_after_s}) and land_speed_m_s > 0 ({self.land_speed_m_s})")
        if not (self.jump_tolerance_m > 0 and self.jump_tolerance_m_s > 0 and self.source_accel_max_m_s2 > 0):
            raise ValueError(f"StaleSettings: need jump_tolerance_m > 0 ({self.jump_tolerance_m}), jump_tolerance_m_s > 0 "
                             f"({self.jump_tolerance_m_s}) and source_accel_max_m_s2 > 0 ({self.source_accel_max_m_s2})")


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

    TURNING_RAD_S = 0.005  # the attitude moving at all (0.3 deg/s) while the rates read exactly zero: a real vehicle's
    # rates are never exactly 0.0 in flight; a simulator state without them put 42% of the steps on the brake law at an
    # attitude turning slower than the 0.3 rad/s this was before (issue 61)
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
        if np.all(x[ROTORS] == 0.0):
            self._say("rotors", "the relay state's rotor speeds are all zero: the NMPC steps from motors at rest (an "
                                "autopilot reports none: pass the speeds last commanded, as flight.autopilot_loop does)")
        if x[2] < self.ground - 0.5:
            self._say("frame", f"the relay state's z = {x[2]:.2f} m is below the ground ({self.ground:g} m): a NED position "
                               "passed as ENU? (flight.frames.ned_to_enu)")
        if self._last is not None and t > self._last[0]:
            rate = float(np.linalg.norm(x[ETA] - self._last[1])) / (t - self._last[0])
            self._still = self._still + 1 if rate > self.TURNING_RAD_S and not np.any(x[OMEGA]) else 0
            if self._still >= self.STEPS:
                self._say("rates", f"the relay's attitude turns at {rate:.2f} rad/s while its body rates read zero: the "
                                   "NMPC's model then disagrees with the vehicle (its QPs fail and the brake law flies); pass "
                                   "the measured body rates (rad/s, body FLU)")
        self._last = (t, x[ETA].copy())


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
                why = beyond_reach(self.trusted, stamp, x[P], x[V], self.a_max, self.stale, "relay")
                if why is not None:
                    return why
        if source is not None:
            if not all(np.all(np.isfinite(v)) for v in (source.p, source.v, source.a)):
                return "source not finite"
            if source.stamp is not None and not (np.isfinite(source.stamp) and source.stamp <= t + ahead):
                return f"source stamped ahead of the clock or not finite ({source.stamp})"
        return None

    def trust(self, stamp: float, x: np.ndarray) -> None:
        """Keep ``x`` (stamped ``stamp``) as the last trusted state."""
        self.trusted = (stamp, x[P].copy(), x[V].copy())


def beyond_reach(trusted: tuple[float, np.ndarray, np.ndarray], stamp: float, p: np.ndarray, v: np.ndarray, a_max: float,
                 stale: StaleSettings, what: str) -> str | None:
    """Why a report of a vehicle's position ``p`` (m) and velocity ``v`` (m/s) at ``stamp`` (s) cannot follow its last
    trusted one ``(stamp, p, v)``: stamped before it, or farther than ``|p - p0 - v0 dt| <= a_max dt^2 / 2 +
    jump_tolerance_m``, ``|v - v0| <= a_max dt + jump_tolerance_m_s`` (``a_max`` m/s^2) allow; None when it can."""
    s0, p0, v0 = trusted
    if stamp < s0:
        return f"{what} state stamped {s0 - stamp:.3f} s before the last trusted one (time went backwards)"
    dt = stamp - s0
    dp = float(np.linalg.norm(p - p0 - v0 * dt))
    dv = float(np.linalg.norm(v - v0))
    if dp > 0.5 * a_max * dt ** 2 + stale.jump_tolerance_m:
        return f"{what} position jumped {dp:.2f} m from the last trusted state in {dt:.3f} s (no vehicle reach)"
    if dv > a_max * dt + stale.jump_tolerance_m_s:
        return f"{what} velocity jumped {dv:.2f} m/s from the last trusted state in {dt:.3f} s (no vehicle reach)"
    return None


def checked_source(source: SourceState | None) -> SourceState | None:
    """``source`` with its vectors as float arrays; a ValueError naming the field when one is not three numbers."""
    if source is None:
        return None
    if not isinstance(source, SourceState):
        if hasattr(source, "keys") and {"p", "v", "a"} <= set(source):  # a mapping by name, as a state may be
            source = SourceState(source["p"], source["v"], source["a"], source.get("stamp"))
        else:
            raise ValueError(f"step: a source must be an aerorelay.SourceState(p, v, a[, stamp]) or a mapping with 'p', 'v' "
                             f"and 'a' (m, m/s, m/s^2 ENU), got {type(source).__name__}")
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


class StepBackend(Protocol):
    """What flies a relay's step in place of its Python controller (``RelayStep.backend``): given the relay's step
    (its ``controller``, ``last_a_ext``, ...), the state, the last input, the stage parameters and the shift, the
    step's ``StepInfo`` (e.g. the C tree's command beside the Python controller's: ``assembly.codegen``)."""

    def __call__(self, step: RelayStep, x: np.ndarray, u_prev: np.ndarray, P: np.ndarray, shift: bool) -> StepInfo: ...


class RelayStep:
    """One relay's part of the controller, whatever the network: its NMPC (no planner of its own: the network's
    planner gives its reference), its telemetry check and state sanity, its external-force observer and its
    stale-input failsafe (hold where it last was, then land). ``controller.network.Controller`` steps every relay's."""

    def __init__(self, *, vehicle: Multirotor, controller: RelayController, period_s: float,
                 observer: ExternalAccelerationObserver | None = None, stale: StaleSettings = StaleSettings(),
                 engine: str = "python"):
        self.vehicle, self.controller, self.period = vehicle, controller, period_s
        # what flies the step (``controller.backend``): "python" (``controller``) or "c" (the relay's generated C
        # library, installed as ``backend`` where a flight's controller is made: ``assembly.c_engine``)
        self.engine = engine
        self.observer, self.stale = observer, stale
        # (time, state) of the last fresh step: where a hold holds
        self._last_step: tuple[float, np.ndarray] | None = None
        self.shift = period_s >= controller.spec.ts - 1e-12
        self.u = np.zeros(vehicle.n_rotors)  # the input applied last (Hz/s)
        self._x_prev: np.ndarray | None = None  # the state of the previous step when it was fresh (the observer's)
        self._land_from: tuple[float, np.ndarray] | None = None
        self.check = TelemetryCheck(vehicle, stale)
        self.sanity = StateSanity(stale.ground_z_m)
        # what flies the step (``StepBackend``; None: the Python controller), and the external acceleration its last
        # stage parameters took (m/s^2, world): a backend that replays or stands in for the controller reads it
        self.backend: StepBackend | None = None
        self.last_a_ext = np.zeros(3)
        F, _ = vehicle.allocation()
        self._thrust_per_speed2 = F

    @property
    def has_state(self) -> bool:
        """Whether a fresh relay state has been stepped (a hold needs a place to hold)."""
        return self._last_step is not None

    @property
    def last_state(self) -> np.ndarray | None:
        """The last fresh state stepped (None before one)."""
        return None if self._last_step is None else self._last_step[1]

    def problem(self, t: float, x: np.ndarray | None, stamp: float) -> str | None:
        """Why the relay state ``x`` (stamped ``stamp``) cannot be trusted at ``t`` (``TelemetryCheck``); None when it can."""
        return self.check.problem(t, x, stamp, None)

    def accept(self, t: float, stamp: float, x: np.ndarray) -> None:
        """A fresh, trusted state ``x`` (measured at ``stamp``) for the step at ``t``: kept as the last trusted one,
        checked for the mistakes of a user's simulator, folded into the observer (after a fresh step), where a later
        hold holds."""
        self.check.trust(stamp, x)
        self.sanity.check(t, x)
        if self.observer is not None and self._x_prev is not None:
            self.observer.update(self._x_prev, self.u, x)
        self._land_from = None
        self._last_step = (t, x.copy())
        self._x_prev = x.copy()

    def missed(self) -> None:
        """A step without a fresh state: the observer restarts from the next fresh one (a gap is not one period)."""
        self._x_prev = None

    def parameters(self, ref: Reference, *, p2_path: np.ndarray, p0_path: np.ndarray | None = None,
                   others: np.ndarray | None = None, separation_m: float = 0.0,
                   a_ext: np.ndarray | None = None) -> np.ndarray:
        """The NMPC's stage parameters for the reference ``ref``: its upstream node's predicted positions ``p2_path``
        ``(3, N + 1)`` (m, world), its downstream node's ``p0_path`` (when its OCP takes it), the other vehicles'
        ``others`` and the separation to keep (m), ``a_ext`` (m/s^2; default this relay's observer's estimate)."""
        if a_ext is None and self.observer is not None:
            a_ext = self.observer.estimate
        zero = np.zeros(3)
        self.last_a_ext = zero if a_ext is None else np.array(a_ext, float)
        return self.controller.parameters(ref, zero, zero, zero, others, separation_m, p2_path=p2_path, p0_path=p0_path,
                                          a_ext=a_ext)

    def guess(self) -> np.ndarray | None:
        """The plan the next step starts from, ``(nx, N + 1)`` (the NMPC's OCP states over its horizon: the last plan
        shifted by the step flown since), from what flies the step (``RelayController.guess_source``: its NMPC, or the C
        library); None before the first step."""
        return self.controller.guess_source()

    def act(self, x: np.ndarray, P: np.ndarray) -> StepInfo:
        """The NMPC's (or the fail-safe's) input for the relay at ``x`` with stage parameters ``P`` (by ``backend`` when
        one is given)."""
        info = (self.controller.step(x, self.u, P, shift=self.shift) if self.backend is None else
                self.backend(self, x, self.u, P, self.shift))
        self.u = info.u
        return info

    def command(self, t: float, x: np.ndarray, info: StepInfo, ref: Reference, t0: float) -> Command:
        """The ``Command`` of a step flown at ``x`` with ``info`` on ``ref`` (setpoints one period ahead by the model);
        ``t0``: when the step began (``time.perf_counter``), for its compute time."""
        veh = self.vehicle
        x1 = np.asarray(veh.rk4_step(x, info.u, self.period), float)  # one period ahead under the command
        a_ext = self.observer.estimate if self.observer is not None else np.zeros(3)
        acc = np.asarray(veh.dynamics(x1, info.u, a_ext), float)[V]
        thrust = float(np.linalg.norm(self._thrust_per_speed2 @ x1[ROTORS] ** 2)) / (veh.mass * veh.gravity)
        ms = (time.perf_counter() - t0) * 1e3
        return Command(t=t, mode="fallback" if info.fallback else "nmpc", omega_dot_hz_s=info.u.copy(),
                       rotor_speeds_hz=x[ROTORS] + info.u * self.period, position_m=x1[P], velocity_m_s=x1[V],
                       acceleration_m_s2=acc, attitude_wxyz=quaternion_wxyz(rotation_zyx(x1[ETA])), thrust_normalized=thrust,
                       body_rates_rad_s=x1[OMEGA], compute_ms=ms, deadline_met=ms <= self.period * 1e3, reference=ref, info=info)

    def remember(self, t: float, x: np.ndarray) -> None:
        """A fresh state ``x`` flown at ``t`` (s) by a caller that checks nothing (``ar.simulate``'s plant): where a
        later hold holds, and the landing's clock restarts."""
        self._land_from = None
        self._last_step = (t, np.asarray(x, float).copy())

    def hold_command(self, t: float, t0: float) -> Command:
        """The stale-input command at ``t`` (s): hold where the relay last was (level, its last yaw), land straight
        down once stale for ``land_after_s`` (``t0``: when the step began, ``time.perf_counter``)."""
        if self._last_step is None:
            raise ValueError("step: no relay state and source received yet (nothing to hold)")
        since, x = self._last_step
        p, yaw = x[P], float(x[YAW])
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
