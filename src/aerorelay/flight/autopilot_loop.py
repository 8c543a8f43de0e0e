"""One loop for every transport that flies the relay on an autopilot (the MAVLink bridge, the ROS 2
node): what the autopilot measured of the relay and what the relay knows of the source in, the
controller's command out. It owns what the transports must not each write again:

* the relay's state for the NMPC (``flight.commanded``: position and velocity measured, the rotor
  speeds last commanded, the NMPC's own attitude for the autopilot's attitude loop);
* the first step's gating: nothing runs until a fresh, trusted relay state *and* source have
  arrived (before that there is nothing to hold), and ``waiting`` says why;
* the telemetry check (``flight.stepper.TelemetryCheck``) and the hold/land failsafe of the stepper;
* the source's acceleration, when a transport does not measure it, from its velocity through a
  first-order filter (``AccelerationFilter``), so planners that look ahead see it accelerate;
* the recording hook, called with every period whose telemetry was trusted.

The transports keep only message conversion (frames, stamps, units). ``FleetLoop`` is the same for a
network's ``NetworkStepper``: every relay's state built, checked and gated on its own, a relay whose
telemetry is stale or not trusted handed on as missing (it holds, then lands, the others planning
with its last state), every source's acceleration filtered.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from .commanded import CommandedState
from .frames import matrix_from_wxyz
from .network_controller import NetworkStepper
from .stepper import Command, RelayStepper, SourceState

# called every control period flown: (time s, the relay's measured state, the command, the source as the
# relay knew it, the state's age s)
StepHook = Callable[[float, np.ndarray, Command, SourceState, float], None]
# a fleet's: (time s, each relay's measured state, each relay's command, each source as known, the oldest state's age s)
FleetStepHook = Callable[[float, dict[str, np.ndarray], dict[str, Command], dict[str, SourceState], float], None]


@dataclass(frozen=True)
class Measured:
    """What an autopilot reports of the relay, in aerorelay's frames: position (m, world ENU), the
    rotation body FLU -> world ENU, velocity (m/s, world), body rates (rad/s, FLU), and when it was
    measured (s, the loop's clock)."""

    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    w: np.ndarray
    stamp: float


def rotation_from_quaternion(wxyz) -> np.ndarray:
    """The rotation of a quaternion (w, x, y, z); a quaternion that is not finite or not of unit norm
    (|q| off by more than 1%: a zero quaternion, a bad message) gives a rotation of NaNs, which the
    telemetry check names instead of flying it."""
    q = np.asarray(wxyz, float)
    n = float(np.linalg.norm(q)) if np.all(np.isfinite(q)) else math.nan
    if not abs(n - 1.0) <= 0.01:
        return np.full((3, 3), math.nan)
    return matrix_from_wxyz(q / n)


class AccelerationFilter:
    """An acceleration estimate from velocity samples: the finite difference between samples through
    a first-order filter of time constant ``tau_s`` (exact discretization for any sample spacing)."""

    def __init__(self, tau_s: float = 0.1):
        if not tau_s > 0:
            raise ValueError(f"tau_s must be > 0 s, got {tau_s}")
        self.tau = tau_s
        self.a = np.zeros(3)
        self._last: tuple[float, np.ndarray] | None = None

    def update(self, t: float, v) -> np.ndarray:
        """The estimate after the velocity ``v`` (m/s) measured at ``t`` (s); a sample not after the last is ignored."""
        v = np.asarray(v, float)
        if not np.all(np.isfinite(v)):
            return self.a.copy()
        if self._last is not None and t > self._last[0]:
            t0, v0 = self._last
            dt = t - t0
            self.a = self.a + (1.0 - math.exp(-dt / self.tau)) * ((v - v0) / dt - self.a)
        if self._last is None or t > self._last[0]:
            self._last = (t, v.copy())
        return self.a.copy()


class AutopilotLoop:
    """``tick(t, relay, source)`` every control period (see the module); ``reset()`` when the
    autopilot flew the relay itself for a while (a hold it was asked for) and the controller takes over
    again. ``measured_attitude``: the NMPC steps from the measured attitude (``flight.commanded``)."""

    def __init__(self, stepper: RelayStepper, *, measured_attitude: bool = False, on_step: StepHook | None = None,
                 hover_speeds: np.ndarray | None = None):
        self.stepper, self.on_step = stepper, on_step
        hover = stepper.vehicle.hover_speeds() if hover_speeds is None else np.asarray(hover_speeds, float)
        self.commanded = CommandedState(hover, measured_attitude=measured_attitude)
        self.waiting: str | None = "no relay state or source yet"  # why no command was given (None: one was)
        self.x: np.ndarray | None = None  # the NMPC's state the last command was stepped from (None: none)

    def reset(self) -> None:
        """Forget the rotor speeds and attitude last commanded (the autopilot flew in between)."""
        self.commanded.forget()

    def states(self, relay: Measured | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The relay's measured state and the NMPC's state from it (None, None without one)."""
        if relay is None:
            return None, None
        return self.commanded.states(relay.p, relay.R, relay.v, relay.w)

    def problem(self, t: float, relay: Measured | None, source: SourceState | None) -> str | None:
        """Why the inputs at ``t`` cannot start or resume the controller (stale, missing or not trusted); None when they can."""
        x = self.states(relay)[1]
        stamp = t if relay is None else relay.stamp
        return self.stepper.stale_reason(t, x, stamp, source) or self.stepper.check.problem(t, x, stamp, source)

    def tick(self, t: float, relay: Measured | None, source: SourceState | None) -> Command | None:
        """One control period at ``t`` (s, the mission's clock): the command, or None while no trusted
        relay state and source have arrived (``waiting`` says why)."""
        if not self.stepper.has_state:
            self.waiting = self.problem(t, relay, source)
            if self.waiting is not None:
                return None
        measured, x = self.states(relay)
        self.x = x
        cmd = self.stepper.step(t, x, source, state_stamp=None if relay is None else relay.stamp)
        self.waiting = None
        if self.on_step is not None and measured is not None and source is not None and relay is not None and cmd.rejected is None:
            self.on_step(t, measured, cmd, source, t - relay.stamp)
        self.commanded.commanded(cmd)
        return cmd


class FleetLoop:
    """``tick(t, relays, sources)`` every control period for a network (``NetworkStepper``): what the autopilots
    measured of each relay and what the network knows of each source in (``Measured`` or None, by name), every
    relay's command out (see the module). Nothing runs until every relay has a trusted state and every source
    has arrived (``waiting`` says why); afterwards a relay whose state is missing, stale or not trusted is
    handed on as missing (``rejected[relay]`` says why), so it holds and then lands while the others fly on.
    ``on_step`` gets the periods in which every relay in the network and every source were handed on. A relay without a
    trusted state for longer than its ``land_after_s`` leaves the network (the stepper's ``lost_at``): the others
    re-plan."""

    def __init__(self, stepper: NetworkStepper, *, measured_attitude: bool = False, on_step: FleetStepHook | None = None):
        self.stepper, self.on_step = stepper, on_step
        self.relays = {r.name: r for r in stepper.controller.relays}
        self.commanded = {n: CommandedState(r.vehicle.hover_speeds(), measured_attitude=measured_attitude)
                          for n, r in self.relays.items()}
        self.accel = {s: AccelerationFilter() for s in stepper.controller.sources}
        self.waiting: str | None = "no relay states or sources yet"
        self.rejected: dict[str, str] = {}  # each relay's reason this period, when its state was not handed on
        self.started = False
        self._bad_since: dict[str, float] = {}

    def _lose_the_silent(self, t: float) -> None:
        """A relay without a trusted state for longer than its ``land_after_s`` (it is landing) leaves the network:
        the others are planned again without it (unless it is the last one flying)."""
        for name in self.relays:
            if name in self.rejected:
                self._bad_since.setdefault(name, t)
            else:
                self._bad_since.pop(name, None)
        for name, since in self._bad_since.items():
            flying = [n for n in self.relays if n not in self.stepper.lost]
            if name in flying and t - since > self.relays[name].stepper.stale.land_after_s and len(flying) > 1:
                self.stepper.lose([name], t)

    def reset(self, relay: str) -> None:
        """Forget the rotor speeds and attitude last commanded to ``relay`` (its autopilot flew it in between)."""
        self.commanded[relay].forget()

    def _source(self, name: str, m: Measured | SourceState | None) -> SourceState | None:
        if isinstance(m, SourceState):  # known with its acceleration (a mission file, a MAVLink source's own estimate)
            ok = all(np.all(np.isfinite(np.asarray(v, float))) for v in (m.p, m.v, m.a))
            return m if ok and (m.stamp is None or np.isfinite(m.stamp)) else None
        if m is None or not (np.all(np.isfinite(m.p)) and np.all(np.isfinite(m.v)) and np.isfinite(m.stamp)):
            return None
        return SourceState(m.p, m.v, self.accel[name].update(m.stamp, m.v), stamp=m.stamp)

    def tick(self, t: float, relays: Mapping[str, Measured | None],
             sources: Mapping[str, Measured | SourceState | None]) -> dict[str, Command] | None:
        """One control period at ``t`` (s, the mission's clock): every relay's command, or None while the network
        cannot start (``waiting``). A source is measured (its acceleration filtered here) or known already."""
        known = {n: self._source(n, sources.get(n)) for n in self.accel}
        src = {n: s for n, s in known.items() if s is not None}
        states: dict[str, np.ndarray] = {}
        measured: dict[str, np.ndarray] = {}
        ages: list[float] = []
        self.rejected = {}
        any_source = next(iter(src.values()), None)
        for name, r in self.relays.items():
            m = relays.get(name)
            if m is None:
                self.rejected[name] = "no relay state"
                continue
            meas, x = self.commanded[name].states(m.p, m.R, m.v, m.w)
            why = r.stepper.check.problem(t, x, m.stamp, None) or r.stepper.stale_reason(t, x, m.stamp, any_source)
            if why is not None and why != "no source":
                self.rejected[name] = why
                continue
            r.stepper.check.trust(m.stamp, x)
            states[name], measured[name] = x, meas
            ages.append(t - m.stamp)
        hold_after = next(iter(self.relays.values())).stepper.stale.hold_after_s
        stale_sources = [n for n, s in src.items() if s.stamp is not None and t - s.stamp > hold_after]
        if not self.started:
            missing = [n for n in self.relays if n not in states]
            absent = [n for n in self.accel if n not in src or n in stale_sources]
            if missing or absent:
                self.waiting = "; ".join(([f"relays {missing}: " + ", ".join(sorted({self.rejected[n] for n in missing}))] if missing else [])
                                         + ([f"no fresh source {absent}"] if absent else []))
                return None
            self.started = True
        self.waiting = None
        self._lose_the_silent(t)
        given = {n: s for n, s in src.items() if n not in stale_sources}
        cmds = self.stepper.step(t, states, given)
        for name, cmd in cmds.items():
            if name in self.rejected:
                cmds[name] = replace(cmd, rejected=self.rejected[name])
            self.commanded[name].commanded(cmd)
        in_network = {n: m for n, m in measured.items() if n not in self.stepper.lost}
        if self.on_step is not None and len(in_network) == len(self.relays) - len(self.stepper.lost) and len(given) == len(self.accel):
            self.on_step(t, in_network, {n: cmds[n] for n in in_network}, given, max(ages))
        return cmds
