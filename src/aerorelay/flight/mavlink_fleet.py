"""A relay network flown through MAVLink (``aerorelay fly`` on a scenario with ``[[relays]]``): one PX4
vehicle per relay, each on its own link (``flight.mavlink_bridge.VehicleLink``: its own system's telemetry,
its own modes), one controller for the fleet (``NetworkStepper`` through ``flight.autopilot_loop.FleetLoop``:
the relays' plans exchanged inside).

Before the mission every vehicle is streamed a hold where it is and, after PX4's 1 s of proof, armed (when
told) and asked for OFFBOARD, each on its own; the mission's clock starts once every vehicle reports
OFFBOARD. Then every control period each vehicle's telemetry is read and every relay's command sent to its
vehicle. A vehicle whose telemetry goes stale or cannot be trusted is sent its hold (``FleetLoop`` hands it
on as missing) and asked to hold (AUTO.LOITER); while it holds its setpoints keep streaming, and once its
telemetry has been good for PX4's proof time OFFBOARD is asked again (once a second). Input that stays bad
for ``land_after_s``: the vehicle is asked to land (AUTO.LAND) and the relay leaves the network (the others
re-plan without it: ``NetworkStepper.lose``). A vehicle that leaves OFFBOARD without the bridge asking
leaves the network too (the bridge never fights a mode change it did not make). The flight ends when every
vehicle has. ``events`` names each relay's hold, landing and departure with its mission time.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping

import numpy as np

from ..models.mission import SourceTrajectory
from .autopilot_loop import FleetLoop, FleetStepHook
from .mavlink import MAV
from .mavlink_bridge import OFFBOARD_RETRIES, VehicleLink
from .network_controller import NetworkStepper
from .px4 import OFFBOARD_PROOF_S, mode_name
from .sources import MavlinkSource, MissionSource
from .stepper import Command

log = logging.getLogger(__name__)


class FleetBridge:
    """``connect()``, then ``tick(t)`` every control period (lockstep: the caller's clock) or ``run(duration_s)``
    on the wall clock. ``urls``: each relay's vehicle's link by the relay's name; ``sources``: each source's path
    or a ``MavlinkSource``; ``on_step``: called with every control period flown (a ``sim.flight_record`` recorder)."""

    def __init__(self, urls: Mapping[str, str], stepper: NetworkStepper,
                 sources: Mapping[str, SourceTrajectory | MissionSource | MavlinkSource], *, arm: bool = False,
                 setpoint: str = "position", hover_throttle: float = 0.5, on_step: FleetStepHook | None = None):
        missing = [n for n in stepper.relays if n not in urls]
        unknown = [n for n in urls if n not in stepper.relays]
        if missing or unknown:
            raise ValueError(f"fleet bridge: one vehicle link per relay ({', '.join(stepper.relays)}); "
                             + (f"none for {missing}" if missing else f"no relay {unknown}"))
        self.stepper, self.arm = stepper, arm
        self.links = {n: VehicleLink(urls[n], setpoint=setpoint, hover_throttle=hover_throttle) for n in stepper.relays}
        self.sources = {n: MissionSource(s) if isinstance(s, SourceTrajectory) else s for n, s in sources.items()}
        self.loop = FleetLoop(stepper, on_step=on_step)
        self.phase = dict.fromkeys(self.links, "stream")  # stream, offboard, held (asked to hold), ended (landing or gone)
        self.t0: float | None = None  # when streaming began (bridge time)
        self.mission_t0: float | None = None  # when the last vehicle entered OFFBOARD: the mission's clock starts
        self.log: list[dict] = []
        self.events: list[tuple[float, str, str]] = []  # (mission time s, relay, what happened)
        self.ended: str | None = None
        self._good_since: dict[str, float] = {}
        self._offboard_asks: dict[str, list[float]] = {n: [] for n in self.links}

    @property
    def period(self) -> float:
        return self.stepper.period

    def connect(self, timeout_s: float = 10.0) -> None:
        """Announce the bridge on every link until each vehicle's heartbeat arrives; TimeoutError naming the silent ones."""
        end = time.monotonic() + timeout_s
        waiting = set(self.links)
        while waiting and time.monotonic() < end:
            for n in sorted(waiting):
                self.links[n].announce()
                if self.links[n].heard_vehicle(0.05):
                    waiting.discard(n)
        if waiting:
            raise TimeoutError(f"no autopilot heartbeat within {timeout_s:g} s from the vehicles of {sorted(waiting)}")

    def _event(self, tm: float, relay: str, what: str) -> None:
        log.warning("relay %s at mission time %.2f s: %s", relay, tm, what)
        self.events.append((tm, relay, what))

    def tick(self, t: float) -> dict[str, Command] | None:
        """One control period at bridge time ``t`` (s): read every link; stream and ask before the mission; then
        step the fleet and send each vehicle its relay's command (see the module). None before the mission."""
        for link in self.links.values():
            link._read(t)
        silent = [n for n, link in self.links.items() if link.state.position is None]
        if silent:
            raise RuntimeError(f"tick: no telemetry yet from the vehicles of {silent} (LOCAL_POSITION_NED or ODOMETRY)")
        if self.t0 is None:
            self.t0 = t
        if self.mission_t0 is None:
            self._stream(t)
            return None
        tm = t - self.mission_t0
        known = {n: s.known(t, tm) for n, s in self.sources.items()}
        measured = {n: link.measured(self.mission_t0) if self.phase[n] in ("offboard", "held") else None
                    for n, link in self.links.items()}
        for n, link in self.links.items():
            if self.phase[n] == "offboard" and not link.offboard:
                self._leave(tm, n, f"left OFFBOARD for {mode_name(link.state.custom_mode)} without the bridge asking")
            elif self.phase[n] == "held" and link.offboard and self._offboard_asks[n]:
                self.phase[n] = "offboard"  # it took OFFBOARD back: its relay's controller flies it again
                self.loop.reset(n)
                self._offboard_asks[n].clear()
                self._event(tm, n, "took OFFBOARD back")
        cmds = self.loop.tick(tm, {n: m for n, m in measured.items() if self.phase[n] != "ended"}, known)
        if cmds is None:
            for n, link in self.links.items():
                link._send_hold(np.asarray(link.state.position, float), t)
                self._row(t, n, "wait", rejected=self.loop.waiting)
            return None
        for n, link in self.links.items():
            cmd = cmds[n]
            if self.phase[n] == "ended":
                continue
            link._send(cmd, t)
            why = self.loop.rejected.get(n)
            if cmd.mode == "land" or n in self.stepper.lost:
                link.request_mode("AUTO", "LAND")
                self._leave(tm, n, f"input stale or not trusted for {self.loop.relays[n].stepper.stale.land_after_s:g} s "
                                   f"({why or 'stale'}): asked to land")
            elif cmd.mode == "hold" and self.phase[n] == "offboard":
                link.hand_back()
                self.phase[n] = "held"
                self._good_since.pop(n, None)
                self._event(tm, n, f"holding ({why or 'stale'})")
            elif self.phase[n] == "held":
                self._ask_back(t, tm, n, why)
            self._row(t, n, cmd.mode, cmd=cmd, rejected=why)
        if all(p == "ended" for p in self.phase.values()):
            self.ended = "every relay's vehicle left the flight: " + "; ".join(f"{n} at {tm_:.2f} s ({w})" for tm_, n, w in self.events)
        return cmds

    def _stream(self, t: float) -> None:
        """Before the mission: a hold where each vehicle is, then (after PX4's proof time) arm and OFFBOARD, each its own."""
        for n, link in self.links.items():
            for s in self.sources.values():
                s.known(t, 0.0)  # a MAVLink source hears the bridge and starts reporting
            link._send_hold(np.asarray(link.state.position, float), t)
            assert self.t0 is not None
            if t - self.t0 >= OFFBOARD_PROOF_S + 0.1:
                if self.arm and not link.state.armed and "ARM" not in link.requested:
                    link._command_long(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
                    link.requested.add("ARM")
                if "OFFBOARD" not in link.requested and (link.state.armed or not self.arm):
                    link.request_mode("OFFBOARD")
            self._row(t, n, "stream")
        if all(link.offboard for link in self.links.values()):
            self.mission_t0 = t
            self.phase = dict.fromkeys(self.links, "offboard")

    def _ask_back(self, t: float, tm: float, n: str, why: str | None) -> None:
        """A held vehicle: OFFBOARD asked again once its telemetry has been good for PX4's proof time."""
        if why is not None:
            self._good_since.pop(n, None)
            return
        since = self._good_since.setdefault(n, t)
        asks = self._offboard_asks[n]
        if t - since >= OFFBOARD_PROOF_S and (not asks or t - asks[-1] >= 1.0):
            if len(asks) >= OFFBOARD_RETRIES:
                self.links[n].request_mode("AUTO", "LAND")
                self._leave(tm, n, f"did not take OFFBOARD back after {OFFBOARD_RETRIES} requests: asked to land")
                return
            self.links[n].request_mode("OFFBOARD")
            asks.append(t)

    def _leave(self, tm: float, n: str, why: str) -> None:
        """Relay ``n``'s vehicle is out of the flight: it leaves the network (unless it is the last one flying)."""
        if self.phase[n] == "ended":
            return
        self.phase[n] = "ended"
        self._event(tm, n, why)
        flying = [r for r, p in self.phase.items() if p != "ended"]
        if flying and n not in self.stepper.lost:
            self.stepper.lose([n], tm)

    def _row(self, t: float, relay: str, mode: str, *, cmd: Command | None = None, rejected: str | None = None) -> None:
        link = self.links[relay]
        self.log.append({"t": t, "relay": relay, "mode": mode, "x": None if link.state.position is None else
                         np.r_[link.state.position, np.zeros(3)], "compute_ms": cmd.compute_ms if cmd is not None else math.nan,
                         "deadline_met": cmd.deadline_met if cmd is not None else None, "armed": link.state.armed,
                         "custom_mode": link.state.custom_mode, "rejected": rejected or ""})

    def hand_back(self) -> None:
        """Ask every vehicle still flying to hold (AUTO.LOITER): on Ctrl-C, the end of the run."""
        for n, link in self.links.items():
            if self.phase[n] != "ended":
                link.hand_back()

    def run(self, duration_s: float) -> None:
        """Tick on the wall clock at the controller's period for ``duration_s`` of mission once every vehicle's
        telemetry arrives; hand back at the end or on Ctrl-C."""
        for link in self.links.values():
            link.wait_for_telemetry()
        start = time.monotonic()
        try:
            k = 0
            while (self.mission_t0 is None or k * self.period - self.mission_t0 < duration_s) and self.ended is None:
                self.tick(time.monotonic() - start)
                k += 1
                time.sleep(max(0.0, start + k * self.period - time.monotonic()))
        finally:
            self.hand_back()
