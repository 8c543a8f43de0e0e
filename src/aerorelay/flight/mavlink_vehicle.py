"""An in-repo MAVLink vehicle (``aerorelay sitl``) for tests and demos: it speaks the PX4 subset the
offboard bridge uses (``flight/px4.py``): heartbeats with PX4's custom modes, arming and mode commands
with acknowledgements and PX4's refusals (OFFBOARD only after a setpoint stream), the offboard loss
timeout (to a hold), LOCAL_POSITION_NED and ATTITUDE_QUATERNION telemetry, or ODOMETRY (NED/FRD on the
wire).

What flies is an airframe with its own autopilot (``flight.airframes``): an ideal point mass (the
default: it tests the protocol, the frames, the rates and the timeouts) or RotorPy's quadrotor (an
independent simulator with its own position and attitude loops). In OFFBOARD it flies the last
position or attitude target; in a hold (also POSCTL with the sticks centred) it stays where it
entered it; in AUTO.LAND it descends from there at 0.5 m/s to z = 0; disarmed it sits. It tests our bridge against our PX4 subset, **not PX4**.
``step(dt)`` advances it by ``dt`` (lockstep: the caller owns time); ``run_realtime`` steps it on
the wall clock.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..models.geometry import quaternion_wxyz
from .airframes import Airframe, PointMass, Target
from .frames import (
    enu_to_ned,
    flu_to_frd,
    matrix_from_wxyz,
    ned_to_enu,
    rotation_enu_flu_to_ned_frd,
    rotation_ned_frd_to_enu_flu,
    yaw_ned_to_enu,
)
from .mavlink import MAV, connect, drain
from .px4 import OFFBOARD_LOSS_S, OFFBOARD_MIN_RATE_HZ, OFFBOARD_PROOF_S, PX4_AUTO_SUB_MODE, PX4_MAIN_MODE, custom_mode

LAND_SPEED_M_S = 0.5  # AUTO.LAND's descent (PX4's MPC_LAND_SPEED default)


@dataclass
class VehicleSettings:
    """The vehicle's hover throttle (PX4's ``MPC_THR_HOVER``: an attitude target's thrust over it is
    the thrust over hover), the telemetry rate (Hz) and the heartbeat period (s)."""

    hover_throttle: float = 0.5
    telemetry: str = "local_position"  # LOCAL_POSITION_NED + ATTITUDE_QUATERNION, or "odometry" (ODOMETRY, velocity in body FRD)
    telemetry_hz: float = 50.0
    heartbeat_s: float = 1.0


class MavlinkVehicle:
    """A PX4-like vehicle on ``url`` (e.g. ``udpin:127.0.0.1:14540``) flying ``airframe`` (default: a
    point mass starting at ``position``, m, ENU)."""

    def __init__(self, url: str, position=(0.0, 0.0, 0.0), settings: VehicleSettings = VehicleSettings(), system: int = 1,
                 airframe: Airframe | None = None):
        self.link = connect(url, system=system, component=1)
        self.s = settings
        self.t = 0.0
        self.airframe: Airframe = airframe if airframe is not None else PointMass(position)
        self.yaw = 0.0  # the heading a hold keeps, rad ENU
        self.armed = False
        self.mode = "POSCTL"
        self.hold_point = self.airframe.p.copy()
        self.setpoint_times: list[float] = []
        self.target: dict | None = None
        self.acks: list[tuple[int, int]] = []  # (command, result) sent, for tests
        self._next_heartbeat = 0.0
        self._next_telemetry = 0.0
        self.heard = False  # a peer has sent something (udpin learns where to answer)

    # -- the protocol -------------------------------------------------------------------------------
    def _custom(self) -> int:
        if self.mode == "OFFBOARD":
            return custom_mode("OFFBOARD")
        if self.mode == "HOLD":
            return custom_mode("AUTO", "LOITER")
        if self.mode == "LAND":
            return custom_mode("AUTO", "LAND")
        return custom_mode("POSCTL")

    def _proof_of_life(self) -> bool:
        """Setpoints for the last ``OFFBOARD_PROOF_S`` at >= 2 Hz (no gap longer than 0.5 s)."""
        ts = [t for t in self.setpoint_times if t >= self.t - OFFBOARD_PROOF_S - 1e-9]
        if not ts or ts[0] > self.t - OFFBOARD_PROOF_S + 1.0 / OFFBOARD_MIN_RATE_HZ:
            return False
        gaps = np.diff([*ts, self.t])
        return bool(np.all(gaps <= 1.0 / OFFBOARD_MIN_RATE_HZ + 1e-9))

    def _ack(self, command: int, result: int) -> None:
        self.acks.append((command, result))
        self.link.mav.command_ack_send(command, result)
        self._next_heartbeat = self.t  # the new arming state or mode goes out with the next step

    def _command(self, msg) -> None:
        if msg.command == MAV.MAV_CMD_COMPONENT_ARM_DISARM:
            self.armed = msg.param1 > 0.5
            if self.armed:
                self.hold_point = self.airframe.p.copy()
            self._ack(msg.command, MAV.MAV_RESULT_ACCEPTED)
        elif msg.command == MAV.MAV_CMD_DO_SET_MODE:
            main = int(msg.param2)
            if main == PX4_MAIN_MODE["OFFBOARD"]:
                if not self._proof_of_life():  # PX4: no OFFBOARD without a setpoint stream
                    self._ack(msg.command, MAV.MAV_RESULT_DENIED)
                    return
                self.mode = "OFFBOARD"
            elif main == PX4_MAIN_MODE["AUTO"]:
                land = int(msg.param3) == PX4_AUTO_SUB_MODE["LAND"]
                self.mode, self.hold_point = "LAND" if land else "HOLD", self.airframe.p.copy()
            else:
                self.mode = "POSCTL"
            self._ack(msg.command, MAV.MAV_RESULT_ACCEPTED)
        else:
            self._ack(msg.command, MAV.MAV_RESULT_UNSUPPORTED)

    def _receive(self) -> None:
        for msg in drain(self.link):
            self.heard = True
            kind = msg.get_type()
            if kind == "COMMAND_LONG":
                self._command(msg)
            elif kind == "SET_POSITION_TARGET_LOCAL_NED":
                self.setpoint_times.append(self.t)
                self.target = {"kind": "position", "p": ned_to_enu([msg.x, msg.y, msg.z]), "v": ned_to_enu([msg.vx, msg.vy, msg.vz]),
                               "a": ned_to_enu([msg.afx, msg.afy, msg.afz]), "yaw": yaw_ned_to_enu(msg.yaw)}
            elif kind == "SET_ATTITUDE_TARGET":
                self.setpoint_times.append(self.t)
                R = rotation_ned_frd_to_enu_flu(matrix_from_wxyz(msg.q))
                self.target = {"kind": "attitude", "R": R, "thrust": float(msg.thrust)}
        self.setpoint_times = [t for t in self.setpoint_times if t >= self.t - 2 * OFFBOARD_PROOF_S]

    # -- the flight -----------------------------------------------------------------------------------
    @property
    def p(self) -> np.ndarray:
        return self.airframe.p

    @property
    def v(self) -> np.ndarray:
        return self.airframe.v

    def _target(self) -> Target:
        if not self.armed:
            return Target("idle")
        tg = self.target
        if self.mode == "OFFBOARD" and tg is not None:
            if tg["kind"] == "position":
                self.yaw = float(tg["yaw"])
                return Target("position", p=tg["p"], v=tg["v"], a=tg["a"], yaw=self.yaw)
            return Target("attitude", R=tg["R"], thrust=tg["thrust"] / self.s.hover_throttle)
        return Target("hold", p=self.hold_point, yaw=self.yaw)  # a hold (also POSCTL with sticks centred)

    def step(self, dt: float) -> None:
        """Read what arrived, apply PX4's offboard timeout, fly ``dt`` s, send what is due."""
        self._receive()
        if self.mode == "OFFBOARD" and (not self.setpoint_times or self.t - self.setpoint_times[-1] > OFFBOARD_LOSS_S):
            self.mode, self.hold_point = "HOLD", self.airframe.p.copy()  # offboard lost: PX4 holds
        if self.mode == "LAND":  # AUTO.LAND: straight down at LAND_SPEED_M_S to z = 0
            self.hold_point[2] = max(0.0, self.hold_point[2] - LAND_SPEED_M_S * dt)
        self.airframe.fly(self._target(), self.t, dt)
        self.t += dt
        self._send_due()

    def _send_due(self) -> None:
        if not self.heard:
            return
        boot_ms = int(round(self.t * 1e3))
        if self.t >= self._next_heartbeat - 1e-9:
            base = MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (MAV.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
            self.link.mav.heartbeat_send(self.airframe.mav_type, MAV.MAV_AUTOPILOT_PX4, base, self._custom(), MAV.MAV_STATE_ACTIVE)
            self._next_heartbeat = self.t + self.s.heartbeat_s
        if self.t >= self._next_telemetry - 1e-9:
            af = self.airframe
            R_ned = rotation_enu_flu_to_ned_frd(af.R)
            q = quaternion_wxyz(R_ned)
            if self.s.telemetry == "odometry":
                nan = [math.nan] * 21
                self.link.mav.odometry_send(int(round(self.t * 1e6)), MAV.MAV_FRAME_LOCAL_NED, MAV.MAV_FRAME_BODY_FRD,
                                            *enu_to_ned(af.p), q, *(R_ned.T @ enu_to_ned(af.v)), *flu_to_frd(af.rates), nan, nan)
            else:
                self.link.mav.local_position_ned_send(boot_ms, *enu_to_ned(af.p), *enu_to_ned(af.v))
                self.link.mav.attitude_quaternion_send(boot_ms, *q, *flu_to_frd(af.rates))
            self._next_telemetry = self.t + 1.0 / self.s.telemetry_hz

    def run_realtime(self, dt: float = 0.005, duration_s: float | None = None) -> None:
        """Step on the wall clock (a demo's vehicle) until ``duration_s`` (None: forever)."""
        start = time.monotonic()
        while duration_s is None or self.t < duration_s:
            self.step(dt)
            time.sleep(max(0.0, start + self.t - time.monotonic()))
