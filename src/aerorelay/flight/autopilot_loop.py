"""One loop for every transport that flies the relay on an autopilot (the MAVLink bridge, the ROS 2
node): what the autopilot measured of the relay and what the relay knows of the source in, the
controller's command out. It owns what the transports must not each write again:

* the relay's state for the NMPC (``flight.commanded``: position and velocity measured, the rotor
  speeds last commanded, the NMPC's own attitude for the autopilot's attitude loop);
* the first step's gating: nothing runs until a fresh, trusted relay state *and* source have
  arrived (before that there is nothing to hold), and ``waiting`` says why;
* the first step's gating on the controller's telemetry check (``control.relay_step.TelemetryCheck``);
* the source's acceleration, when a transport does not measure it, from its velocity through a
  first-order filter (``AccelerationFilter``), so planners that look ahead see it accelerate;
* the recording hook, called with every period whose telemetry was trusted.

The transports keep only message conversion (frames, stamps, units). One loop for any number of relays:
every relay's state built, checked and gated on its own, a relay whose telemetry is stale or not trusted
holds, then lands, the others planning with its last state; every source's acceleration filtered.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..control.network import Controller
from ..control.relay_step import Command, SourceState
from .commanded import CommandedState
from .frames import matrix_from_wxyz

# called every control period flown: (time s, each relay's measured state, each relay's command, each source as
# known, the oldest state's age s)
StepHook = Callable[[float, dict[str, np.ndarray], dict[str, Command], dict[str, SourceState], float], None]


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
    """``tick(t, relays, sources)`` every control period for any network (``control.network.Controller``; one relay is a
    network of one): what the autopilots measured of each relay and what the network knows of each source in
    (``Measured``, a ``SourceState`` or None, by name), every relay's command out (see the module). Nothing runs until
    every relay has a trusted state and every source has arrived (``waiting`` says why); afterwards a relay whose
    state is missing, stale or not trusted holds, then lands while the others fly on (``rejected[relay]`` says why:
    the controller's telemetry check). ``on_step`` gets the periods in which every relay in the network and every
    source were fresh. A relay without a trusted state for longer than ``land_after_s`` leaves the network (the
    controller's ``lost_at``): the others re-plan; the last one flying stays. ``measured_attitude``: the NMPC steps
    from the measured attitude (``flight.commanded``)."""

    def __init__(self, controller: Controller, *, measured_attitude: bool = False, on_step: StepHook | None = None):
        controller = getattr(controller, "network", controller)  # ar.controller of one relay: its network's controller
        self.controller, self.on_step = controller, on_step
        self.relays = {r.name: r for r in controller.controller.relays}
        self.commanded = {n: CommandedState(r.vehicle.hover_speeds(), measured_attitude=measured_attitude)
                          for n, r in self.relays.items()}
        self.accel = {s: AccelerationFilter() for s in controller.sources}
        self.waiting: str | None = "no relay states or sources yet"
        self.rejected: dict[str, str] = {}  # each relay's reason this period, when its state was not flown
        self.x: dict[str, np.ndarray] = {}  # the NMPC's states the last commands were stepped from
        self.started = False
        self._bad_since: dict[str, float] = {}

    @property
    def period(self) -> float:
        return self.controller.period

    def _lose_the_silent(self, t: float) -> None:
        """A relay without a trusted state for longer than its ``land_after_s`` (it is landing) leaves the network:
        the others are planned again without it (unless it is the last one flying)."""
        for name in self.relays:
            if name in self.rejected:
                self._bad_since.setdefault(name, t)
            else:
                self._bad_since.pop(name, None)
        for name, since in self._bad_since.items():
            flying = [n for n in self.relays if n not in self.controller.lost]
            if name in flying and t - since > self.controller.stale.land_after_s and len(flying) > 1:
                self.controller.lose([name], t)

    def reset(self, relay: str) -> None:
        """Forget the rotor speeds and attitude last commanded to ``relay`` (its autopilot flew it in between)."""
        self.commanded[relay].forget()

    def _source(self, name: str, m: Measured | SourceState | None) -> SourceState | None:
        if m is None or isinstance(m, SourceState):  # known with its acceleration (a mission file, a MAVLink source's own)
            return m
        if not (np.all(np.isfinite(m.v)) and np.isfinite(m.stamp)):
            return SourceState(m.p, m.v, np.full(3, np.nan), stamp=m.stamp)  # the controller's check names it
        return SourceState(m.p, m.v, self.accel[name].update(m.stamp, m.v), stamp=m.stamp)

    def states(self, name: str, m: Measured | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Relay ``name``'s measured state and the NMPC's state from it (None, None without one)."""
        if m is None:
            return None, None
        return self.commanded[name].states(m.p, m.R, m.v, m.w)

    def problem(self, t: float, name: str, m: Measured | None) -> str | None:
        """Why relay ``name``'s measurement cannot be flown at ``t`` (missing, stale or not trusted); None when it can."""
        x = self.states(name, m)[1]
        return self.controller.problem(t, name, x, t if m is None else m.stamp)

    def tick(self, t: float, relays: Mapping[str, Measured | None],
             sources: Mapping[str, Measured | SourceState | None]) -> dict[str, Command] | None:
        """One control period at ``t`` (s, the mission's clock): every relay's command, or None while the network
        cannot start (``waiting``). A source is measured (its acceleration filtered here) or known already."""
        src = {n: self._source(n, sources.get(n)) for n in self.accel}
        built = {n: self.states(n, relays.get(n)) for n in self.relays}
        stamps = {n: m.stamp for n in self.relays if (m := relays.get(n)) is not None}
        self.rejected = {n: why for n in self.relays if (why := self.controller.problem(t, n, built[n][1], stamps.get(n, t)))}
        if not self.started:
            absent = {n: why for n, s in src.items() if (why := self.controller.source_problem(t, s)) is not None}
            if self.rejected or absent:
                self.waiting = "; ".join([f"{n}: {why}" for n, why in self.rejected.items()]
                                         + [f"source {n}: {why}" for n, why in absent.items()])
                return None
            self.started = True
        self.waiting = None
        self._lose_the_silent(t)
        cmds = self.controller.step(t, {n: x for n, (_, x) in built.items()}, src, stamps=stamps)
        self.x = {n: x for n, (_, x) in built.items() if x is not None and n not in self.rejected}
        for name, cmd in cmds.items():
            if name in self.rejected and cmd.rejected is None:
                cmds[name] = replace(cmd, rejected=self.rejected[name])
            self.commanded[name].commanded(cmds[name])
        in_network = {n: measured for n, (measured, _) in built.items() if n not in self.controller.lost and n not in self.rejected}
        sources_fresh = all(self.controller.source_problem(t, s) is None for s in src.values())
        if self.on_step is not None and sources_fresh and len(in_network) == len(self.relays) - len(self.controller.lost):
            ages = [t - stamps[n] for n in in_network]
            self.on_step(t, {n: m for n, m in in_network.items() if m is not None}, {n: cmds[n] for n in in_network},
                         {n: s for n, s in src.items() if s is not None}, max(ages))
        return cmds
