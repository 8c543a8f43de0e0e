"""The MAVLink offboard bridge (``aerorelay fly SCENARIO --mavlink URL``): the relay's controller
(``flight.stepper``) flying a PX4 vehicle in OFFBOARD.

It waits for the autopilot's heartbeat; streams setpoints before it asks for OFFBOARD (PX4 accepts
OFFBOARD only after a setpoint stream of >= 2 Hz for 1 s); arms only when told to; then every
control period reads the vehicle's state (LOCAL_POSITION_NED and ATTITUDE_QUATERNION, or ODOMETRY in
the local NED frame with its velocity in body FRD or local NED; NED/FRD on the wire, ENU/FLU
inside), steps the controller and sends the setpoint it computed in that period (never an older
one): SET_POSITION_TARGET_LOCAL_NED with velocity and acceleration feed-forward
(``setpoint = "position"``) or SET_ATTITUDE_TARGET with body rates and thrust (``"attitude"``; PX4's
thrust is a fraction of full throttle: the controller's thrust over hover times ``hover_throttle``).
Until the vehicle reports OFFBOARD the bridge streams a hold where the vehicle is (the proof of life
PX4 wants) and the controller does not run; the mission's clock starts when OFFBOARD is entered.
When telemetry goes stale or is not trusted (``flight.stepper.TelemetryCheck``: non-finite, stamped
ahead of the clock or backwards, a jump no vehicle can make) the controller's hold setpoint is sent and
the vehicle is asked for a hold (AUTO.LOITER); while it holds the controller does not run and no
period is logged as flown by it. Once telemetry has been good for PX4's 1 s of streamed setpoints the
bridge asks for OFFBOARD again (every second, ``OFFBOARD_RETRIES`` times at most, then the flight
ends). Input that stays bad for ``land_after_s`` asks the vehicle to land (AUTO.LAND) and ends the
flight; a vehicle that leaves OFFBOARD without the bridge asking (a pilot, a failsafe, another ground
station) ends it too: the bridge never fights a mode change it did not make. ``ended`` says why a
flight ended early. ``hand_back()`` (on Ctrl-C) asks for a hold. Only the vehicle's own system and
component are read (telemetry from any other system on the link is ignored and counted).

The NMPC's state, the first step's gating and the telemetry check: ``flight.autopilot_loop`` (shared
with the ROS 2 node); this module converts messages and keeps PX4's mode rules.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..models.mission import SourceTrajectory
from .autopilot_loop import AutopilotLoop, Measured, StepHook, rotation_from_quaternion
from .frames import (
    enu_to_ned,
    euler_zyx,
    flu_to_frd,
    frd_to_flu,
    matrix_from_wxyz,
    ned_to_enu,
    quaternion_wxyz,
    rotation_enu_flu_to_ned_frd,
    rotation_ned_frd_to_enu_flu,
    yaw_enu_to_ned,
)
from .mavlink import MAV, connect, drain
from .px4 import ATTITUDE_TARGET_MASK, OFFBOARD_PROOF_S, POSITION_TARGET_MASK, PX4_AUTO_SUB_MODE, PX4_MAIN_MODE, mode_name
from .sources import MavlinkSource, MissionSource
from .stepper import Command, RelayStepper, SourceState

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


class OffboardBridge(VehicleLink):
    """``connect()``, then ``tick(t)`` every control period (lockstep: the caller's clock) or
    ``run(duration_s)`` on the wall clock. ``source``: the inspection drone: its path (its mission file),
    or a ``flight.sources.MavlinkSource`` (a second MAVLink system);
    ``on_step``: called with every control period flown in OFFBOARD (a ``sim.flight_record`` recorder)."""

    def __init__(self, url: str, stepper: RelayStepper, source: SourceTrajectory | MissionSource | MavlinkSource,
                 hover_speeds: np.ndarray, *,
                 arm: bool = False, setpoint: str = "position", hover_throttle: float = 0.5, system: int = 255,
                 on_step: StepHook | None = None, measured_attitude: bool = False):
        super().__init__(url, setpoint=setpoint, hover_throttle=hover_throttle, system=system)
        self.stepper, self.arm = stepper, arm
        self.source = MissionSource(source) if isinstance(source, SourceTrajectory) else source
        # the NMPC's state, the first step's gating, the telemetry check and the recording hook
        self.loop = AutopilotLoop(stepper, measured_attitude=measured_attitude, on_step=on_step, hover_speeds=hover_speeds)
        self.t0: float | None = None  # when streaming began (bridge time)
        self.mission_t0: float | None = None  # when the vehicle entered OFFBOARD: the mission's clock starts
        self.log: list[dict] = []
        self.phase = "stream"  # stream (before OFFBOARD), offboard, held (the bridge asked for a hold), ended
        self.ended: str | None = None  # why the flight ended early (None: it did not)
        self._good_since: float | None = None  # in a hold: since when telemetry has been good (bridge time)
        self._offboard_asks: list[float] = []  # when OFFBOARD was asked again after a hold (bridge time)

    @property
    def on_step(self) -> StepHook | None:
        """Called with every control period flown in OFFBOARD on trusted telemetry (a recorder)."""
        return self.loop.on_step

    @on_step.setter
    def on_step(self, hook: StepHook | None) -> None:
        self.loop.on_step = hook

    def tick(self, t: float) -> Command | None:
        """One control period at bridge time ``t`` (s): read; before OFFBOARD stream a hold where the
        vehicle is and ask (arm if told, then OFFBOARD) once the stream is 1 s old; in OFFBOARD step the
        controller and send its setpoint (a hold when telemetry is stale or not trusted, and the vehicle
        asked to hold); in a hold the controller's hold setpoint, OFFBOARD asked again once telemetry is
        good (see the module). None while streaming and once the flight ended."""
        self._read(t)
        if self.state.position is None:
            raise RuntimeError("tick: no telemetry from the vehicle yet (LOCAL_POSITION_NED or ODOMETRY)")
        if self.t0 is None:
            self.t0 = t
        if self.phase == "ended":
            self._row(t, "ended")
            return None
        if self.phase == "stream" and self.offboard:
            self.mission_t0, self.phase = t, "offboard"
        if self.phase == "stream":
            self.source.known(t, 0.0)  # a second MAVLink system hears the bridge and starts reporting
            self._send_hold(self.state.position, t)
            if t - self.t0 >= OFFBOARD_PROOF_S + 0.1:  # PX4's rule: stream first, then ask
                if self.arm and not self.state.armed and "ARM" not in self.requested:
                    self._command_long(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
                    self.requested.add("ARM")
                if "OFFBOARD" not in self.requested and (self.state.armed or not self.arm):
                    self.request_mode("OFFBOARD")
            self._row(t, "stream")
            return None
        assert self.mission_t0 is not None
        tm = t - self.mission_t0  # the mission's clock
        src = self.source.known(t, tm)
        relay = self.measured(self.mission_t0)
        if self.phase == "held" and self.offboard and self._offboard_asks:  # it took OFFBOARD back: the controller flies again
            self.phase = "offboard"
            self.loop.reset()
            self._offboard_asks.clear()
        if self.phase == "offboard" and not self.offboard:
            return self._end(t, f"the vehicle left OFFBOARD for {mode_name(self.state.custom_mode)} at mission time {tm:.2f} s "
                                "without the bridge asking (a pilot, a failsafe or another ground station): the flight ends")
        if self.phase == "held":
            return self._held(t, tm, relay, src)
        cmd = self.loop.tick(tm, relay, src)
        if cmd is None:
            self._send_hold(self.state.position, t)  # no trusted telemetry or source yet: keep the stream alive where it is
            self._row(t, "wait", rejected=self.loop.waiting)
            return None
        self._send(cmd, t)
        if cmd.mode in ("hold", "land"):
            self.hand_back()
            self.phase, self._good_since = "held", None
        self._row(t, cmd.mode, x=self.loop.x, cmd=cmd)
        return cmd

    def _held(self, t: float, tm: float, relay: Measured | None, src: SourceState | None) -> Command | None:
        """A period in the hold the bridge asked for (the vehicle has not taken OFFBOARD back): the
        controller's hold (or landing) setpoint keeps the stream alive; OFFBOARD asked again once telemetry
        has been good for PX4's proof time; land and end when the input stays bad."""
        problem = self.loop.problem(tm, relay, src)
        self._good_since = (self._good_since if self._good_since is not None else t) if problem is None else None
        cmd = self.stepper.step(tm, None, None)  # the hold (then the landing) where the relay last was trusted
        self._send(cmd, t)
        if cmd.mode == "land":
            self.request_mode("AUTO", "LAND")
            return self._end(t, f"telemetry stale or not trusted for {self.stepper.stale.land_after_s:g} s "
                                f"({problem or 'stale'}): the vehicle was asked to land", cmd)
        if self._good_since is not None and t - self._good_since >= OFFBOARD_PROOF_S and \
                (not self._offboard_asks or t - self._offboard_asks[-1] >= 1.0):
            if len(self._offboard_asks) >= OFFBOARD_RETRIES:
                return self._end(t, f"the vehicle did not take OFFBOARD back after {OFFBOARD_RETRIES} requests: the flight ends", cmd)
            self.request_mode("OFFBOARD")
            self._offboard_asks.append(t)
        self._row(t, cmd.mode, cmd=cmd, rejected=problem)
        return cmd

    def _end(self, t: float, why: str, cmd: Command | None = None) -> Command | None:
        """End the flight (``ended`` says why): logged, and the period's command (if one was sent) returned."""
        log.warning("flight ended: %s", why)
        self.phase, self.ended = "ended", why
        self._row(t, "ended", cmd=cmd)
        return cmd

    def _row(self, t: float, mode: str, *, x: np.ndarray | None = None, cmd: Command | None = None, rejected: str | None = None) -> None:
        why = rejected if rejected is not None else (cmd.rejected if cmd is not None else None)
        self.log.append({"t": t, "mode": mode, "x": None if x is None else x.copy(),
                         "compute_ms": cmd.compute_ms if cmd is not None else math.nan,
                         "deadline_met": cmd.deadline_met if cmd is not None else None, "armed": self.state.armed,
                         "custom_mode": self.state.custom_mode, "rejected": why or ""})

    def run(self, duration_s: float) -> None:
        """Tick on the wall clock at the controller's period for ``duration_s`` once the vehicle's telemetry
        arrives; hand back at the end or on Ctrl-C."""
        self.wait_for_telemetry()
        period = self.stepper.period
        start = time.monotonic()
        try:
            k = 0
            while k * period < duration_s and self.phase != "ended":
                self.tick(time.monotonic() - start)
                k += 1
                time.sleep(max(0.0, start + k * period - time.monotonic()))
        finally:
            self.hand_back()


def _boot_ms(t: float) -> int:
    """MAVLink's ``time_boot_ms`` (uint32, wrapping) from a time in seconds."""
    return int(round(t * 1e3)) & 0xFFFFFFFF
