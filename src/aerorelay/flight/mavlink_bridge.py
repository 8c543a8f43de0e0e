"""The MAVLink offboard bridge (``aerorelay fly SCENARIO --mavlink URL``, ``--mavlink NAME=URL`` per relay of a
network): the scenario's controller (``control.network.Controller``) flying one PX4 vehicle per relay in OFFBOARD,
each on its own link (``VehicleLink``: its own system's telemetry, its own modes); one relay is a network of one.

It waits for every autopilot's heartbeat; streams a hold where each vehicle is before it asks for OFFBOARD (PX4
accepts OFFBOARD only after a setpoint stream of >= 2 Hz for 1 s); arms only when told to; the mission's clock
starts once every vehicle reports OFFBOARD. Then every control period it reads each vehicle's state
(LOCAL_POSITION_NED and ATTITUDE_QUATERNION, or ODOMETRY in the local NED frame with its velocity in body FRD or
local NED; NED/FRD on the wire, ENU/FLU inside), steps the controller and sends each vehicle its relay's setpoint
computed in that period (never an older one): SET_POSITION_TARGET_LOCAL_NED with velocity and acceleration
feed-forward (``setpoint = "position"``) or SET_ATTITUDE_TARGET with body rates and thrust (``"attitude"``; PX4's
thrust is a fraction of full throttle: the controller's thrust over hover times ``hover_throttle``).

A vehicle whose telemetry goes stale or is not trusted (the controller's telemetry check: non-finite, stamped ahead
of the clock or backwards, a jump no vehicle can make) is sent its relay's hold and asked to hold (AUTO.LOITER);
while it holds its relay's controller does not run (its hold, then landing, setpoints keep streaming) and no period
of it is logged as flown. Once its telemetry has been good for PX4's 1 s of proof the bridge asks for OFFBOARD again
(once a second, ``OFFBOARD_RETRIES`` times at most, then it is asked to land). Input that stays bad for
``land_after_s``: the vehicle is asked to land (AUTO.LAND) and its relay leaves the network (the others re-plan
without it: ``Controller.lose``). A vehicle that leaves OFFBOARD without the bridge asking (a pilot, a failsafe,
another ground station) leaves the flight too: the bridge never fights a mode change it did not make. The flight
ends when every vehicle has (``ended`` says why); ``events`` names each relay's hold, landing and departure with its
mission time. ``hand_back()`` (on Ctrl-C, at the end) asks every vehicle still flying to hold. Only each vehicle's
own system and component are read (telemetry from any other system on its link is ignored and counted).

The NMPC's state, the first step's gating and the source's acceleration: ``flight.autopilot_loop`` (shared with
the ROS 2 node); this module converts messages and keeps PX4's mode rules.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..control.network import Controller
from ..control.relay_step import Command
from ..models.geometry import quaternion_wxyz
from ..models.mission import SourceTrajectory
from .autopilot_loop import AutopilotLoop, Measured, StepHook, rotation_from_quaternion
from .frames import (
    enu_to_ned,
    euler_zyx,
    flu_to_frd,
    frd_to_flu,
    matrix_from_wxyz,
    ned_to_enu,
    rotation_enu_flu_to_ned_frd,
    rotation_ned_frd_to_enu_flu,
    yaw_enu_to_ned,
)
from .mavlink import MAV, connect, drain
from .px4 import ATTITUDE_TARGET_MASK, OFFBOARD_PROOF_S, POSITION_TARGET_MASK, PX4_AUTO_SUB_MODE, PX4_MAIN_MODE, mode_name
from .sources import MavlinkSource, MissionSource

log = logging.getLogger(__name__)



@dataclass
class BridgeState:
    """What the bridge knows and did: the latest telemetry (ENU/FLU) with the bridge time it arrived,
    whether it is armed / in OFFBOARD as the vehicle reports, the acknowledgements it received."""

    position: np.ndarray | None = None
    velocity: np.ndarray | None = None
    R: np.ndarray | None = None
    rates: np.ndarray = field(default_factory=lambda: np.zeros(3))
    received_at: float = -math.inf
    armed: bool = False
    custom_mode: int = 0
    acks: list[tuple[int, int]] = field(default_factory=list)
    foreign: int = 0  # telemetry messages from another system or component, ignored


OFFBOARD_RETRIES = 5  # OFFBOARD asked again after a hold at most this many times (once a second) before the flight ends


class VehicleLink:
    """One vehicle's MAVLink link as a ground station sees it: its heartbeat and telemetry read (only its
    own system's and component's), modes asked, setpoints sent (``setpoint``: ``position`` or
    ``attitude``); what every bridge, one relay's or a fleet's, does with each vehicle."""

    def __init__(self, url: str, *, setpoint: str = "position", hover_throttle: float = 0.5, system: int = 255):
        if setpoint not in ("position", "attitude"):
            raise ValueError(f"setpoint must be 'position' or 'attitude', got {setpoint!r}")
        self.link = connect(url, system=system, component=190)
        self.setpoint, self.hover_throttle = setpoint, hover_throttle
        self.state = BridgeState()
        self.requested: set[str] = set()
        self.target = (1, 1)

    def announce(self) -> None:
        """A GCS heartbeat (a vehicle listening with ``udpin`` learns where to answer)."""
        self.link.mav.heartbeat_send(MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID, 0, 0, MAV.MAV_STATE_ACTIVE)

    def heard_vehicle(self, wait_s: float = 0.0) -> bool:
        """Whether an autopilot's heartbeat arrived (waiting up to ``wait_s``); it sets the target system."""
        msg = self.link.recv_match(type="HEARTBEAT", blocking=wait_s > 0, timeout=wait_s or None)
        if msg is None or msg.autopilot == MAV.MAV_AUTOPILOT_INVALID:
            return False
        self.target = (msg.get_srcSystem(), msg.get_srcComponent())
        self._heartbeat(msg)
        return True

    def connect(self, timeout_s: float = 10.0) -> None:
        """Announce the bridge until the vehicle's heartbeat arrives; TimeoutError after ``timeout_s``."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self.announce()
            if self.heard_vehicle(0.1):
                return
        raise TimeoutError(f"no autopilot heartbeat within {timeout_s:g} s")

    def _heartbeat(self, msg) -> None:
        self.state.armed = bool(msg.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
        self.state.custom_mode = int(msg.custom_mode)

    def _read(self, t: float) -> None:
        st = self.state
        for msg in drain(self.link):
            kind = msg.get_type()
            if kind in ("LOCAL_POSITION_NED", "ODOMETRY", "ATTITUDE_QUATERNION", "COMMAND_ACK") and \
                    (msg.get_srcSystem(), msg.get_srcComponent()) != self.target:
                st.foreign += 1  # another system on the link (a second vehicle, a replayed log): never the relay
                continue
            if kind == "LOCAL_POSITION_NED":
                st.position, st.velocity = ned_to_enu([msg.x, msg.y, msg.z]), ned_to_enu([msg.vx, msg.vy, msg.vz])
                st.received_at = t
            elif kind == "ODOMETRY" and msg.frame_id == MAV.MAV_FRAME_LOCAL_NED:  # pose and twist in one message
                R_ned = rotation_from_quaternion(msg.q)  # body FRD to NED (NaN for a quaternion that is not one)
                v = np.array([msg.vx, msg.vy, msg.vz])
                st.position, st.R = ned_to_enu([msg.x, msg.y, msg.z]), rotation_ned_frd_to_enu_flu(R_ned)
                st.velocity = ned_to_enu(R_ned @ v if msg.child_frame_id == MAV.MAV_FRAME_BODY_FRD else v)
                st.rates = frd_to_flu([msg.rollspeed, msg.pitchspeed, msg.yawspeed])
                st.received_at = t
            elif kind == "ATTITUDE_QUATERNION":
                st.R = rotation_ned_frd_to_enu_flu(rotation_from_quaternion([msg.q1, msg.q2, msg.q3, msg.q4]))
                st.rates = frd_to_flu([msg.rollspeed, msg.pitchspeed, msg.yawspeed])
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == self.target[0]:
                self._heartbeat(msg)
            elif kind == "COMMAND_ACK":
                st.acks.append((int(msg.command), int(msg.result)))

    def measured(self, clock_offset: float) -> Measured | None:
        """The relay as its telemetry reports it, stamped on a clock ``clock_offset`` s after the bridge's
        (the mission's); None before telemetry."""
        st = self.state
        if st.position is None or st.R is None or st.velocity is None:
            return None
        return Measured(st.position, st.R, st.velocity, st.rates, st.received_at - clock_offset)

    @property
    def offboard(self) -> bool:
        """Whether the vehicle's last heartbeat reports OFFBOARD."""
        return (self.state.custom_mode >> 16) & 0xFF == PX4_MAIN_MODE["OFFBOARD"]

    def _command_long(self, command: int, *params: float) -> None:
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        self.link.mav.command_long_send(*self.target, command, 0, *p)

    def request_mode(self, main: str, sub: str | None = None) -> None:
        self._command_long(MAV.MAV_CMD_DO_SET_MODE, MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, PX4_MAIN_MODE[main],
                           PX4_AUTO_SUB_MODE[sub] if sub else 0)
        self.requested.add(main if sub is None else f"{main}.{sub}")

    def hand_back(self) -> None:
        """Ask the vehicle to hold (AUTO.LOITER): on Ctrl-C, stale telemetry, the end of the run."""
        self.request_mode("AUTO", "LOITER")

    def _send_position(self, t: float, p, v, a, yaw_enu: float) -> None:
        """SET_POSITION_TARGET_LOCAL_NED from ENU position (m), velocity (m/s), acceleration (m/s^2), yaw (rad)."""
        self.link.mav.set_position_target_local_ned_send(_boot_ms(t), *self.target, MAV.MAV_FRAME_LOCAL_NED, POSITION_TARGET_MASK,
                                                         *enu_to_ned(p), *enu_to_ned(v), *enu_to_ned(a), yaw_enu_to_ned(yaw_enu), 0.0)

    def _send_hold(self, position: np.ndarray, t: float) -> None:
        zero = np.zeros(3)
        self._send_position(t, position, zero, zero, 0.0)

    def _send(self, cmd: Command, t: float) -> None:
        if self.setpoint == "attitude" and cmd.mode in ("nmpc", "fallback"):
            R = matrix_from_wxyz(cmd.attitude_wxyz)
            q = quaternion_wxyz(rotation_enu_flu_to_ned_frd(R))
            rates = flu_to_frd(cmd.body_rates_rad_s)
            self.link.mav.set_attitude_target_send(_boot_ms(t), *self.target, ATTITUDE_TARGET_MASK, q, *rates,
                                                   min(1.0, cmd.thrust_normalized * self.hover_throttle))
            return
        self._send_position(t, cmd.position_m, cmd.velocity_m_s, cmd.acceleration_m_s2,
                            euler_zyx(matrix_from_wxyz(cmd.attitude_wxyz))[2])

    def wait_for_telemetry(self, timeout_s: float = 5.0) -> None:
        """Read until the vehicle's position arrives; TimeoutError naming the messages after ``timeout_s``."""
        end = time.monotonic() + timeout_s
        while self.state.position is None:
            if time.monotonic() > end:
                raise TimeoutError(f"no LOCAL_POSITION_NED or ODOMETRY from the vehicle within {timeout_s:g} s")
            self._read(0.0)
            time.sleep(0.005)


class OffboardBridge:
    """``connect()``, then ``tick(t)`` every control period (lockstep: the caller's clock) or ``run(duration_s)``
    on the wall clock. ``urls``: each relay's vehicle's link by the relay's name; ``sources``: each source's path
    or a ``MavlinkSource``; ``on_step``: called with every control period flown (a ``sim.flight_record`` recorder)."""

    def __init__(self, urls: Mapping[str, str], controller: Controller,
                 sources: Mapping[str, SourceTrajectory | MissionSource | MavlinkSource], *, arm: bool = False,
                 setpoint: str = "position", hover_throttle: float = 0.5, on_step: StepHook | None = None,
                 measured_attitude: bool = False, system: int = 255):
        missing = [n for n in controller.relays if n not in urls]
        unknown = [n for n in urls if n not in controller.relays]
        if missing or unknown:
            raise ValueError(f"bridge: one vehicle link per relay ({', '.join(controller.relays)}); "
                             + (f"none for {missing}" if missing else f"no relay {unknown}"))
        absent = [n for n in controller.sources if n not in sources]
        if absent:
            raise ValueError(f"bridge: no source for {absent} (a mission path or a MAVLink source each)")
        self.controller, self.arm = controller, arm
        self.links = {n: VehicleLink(urls[n], setpoint=setpoint, hover_throttle=hover_throttle, system=system)
                      for n in controller.relays}
        self.sources = {n: MissionSource(s) if isinstance(s, SourceTrajectory) else s for n, s in sources.items()}
        self.loop = AutopilotLoop(controller, on_step=on_step, measured_attitude=measured_attitude)
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
        return self.controller.period

    @property
    def on_step(self) -> StepHook | None:
        """Called with every control period flown in OFFBOARD on trusted telemetry (a recorder)."""
        return self.loop.on_step

    @on_step.setter
    def on_step(self, hook: StepHook | None) -> None:
        self.loop.on_step = hook

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
        if self.mission_t0 is None and all(link.offboard for link in self.links.values()):
            self.mission_t0 = t  # every vehicle in OFFBOARD: the mission's clock starts, its first period flown now
            self.phase = dict.fromkeys(self.links, "offboard")
        if self.mission_t0 is None:
            self._stream(t)
            return None
        if self.ended is not None:
            for n in self.links:
                self._row(t, n, "ended")
            return None
        tm = t - self.mission_t0
        known = {n: s.known(t, tm) for n, s in self.sources.items()}
        measured = {n: link.measured(self.mission_t0) if self.phase[n] in ("offboard", "held") else None
                    for n, link in self.links.items()}
        # a held vehicle's autopilot flies it: its controller does not run (its hold, then landing, streams on)
        held_why = {n: self.loop.problem(tm, n, measured[n]) for n in self.links if self.phase[n] == "held"}
        for n, link in self.links.items():
            if self.phase[n] == "offboard" and not link.offboard:
                self._leave(tm, n, f"left OFFBOARD for {mode_name(link.state.custom_mode)} without the bridge asking")
            elif self.phase[n] == "held" and link.offboard and self._offboard_asks[n]:
                self.phase[n] = "offboard"  # it took OFFBOARD back: its relay's controller flies it again
                self.loop.reset(n)
                self._offboard_asks[n].clear()
                self._event(tm, n, "took OFFBOARD back")
        cmds = self.loop.tick(tm, {n: m for n, m in measured.items() if self.phase[n] == "offboard"}, known)
        if cmds is None:
            for n, link in self.links.items():
                link._send_hold(np.asarray(link.state.position, float), t)
                self._row(t, n, "wait", rejected=self.loop.waiting)
            return None
        for n, link in self.links.items():
            cmd = cmds[n]
            if self.phase[n] == "ended":
                self._row(t, n, "ended")
                continue
            link._send(cmd, t)
            why = held_why[n] if n in held_why else self.loop.rejected.get(n)
            if cmd.mode == "land" or n in self.controller.lost:
                link.request_mode("AUTO", "LAND")
                self._leave(tm, n, f"input stale or not trusted for {self.controller.stale.land_after_s:g} s "
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
        if flying and n not in self.controller.lost:
            self.controller.lose([n], tm)

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


def _boot_ms(t: float) -> int:
    """MAVLink's ``time_boot_ms`` (uint32, wrapping) from a time in seconds."""
    return int(round(t * 1e3)) & 0xFFFFFFFF
