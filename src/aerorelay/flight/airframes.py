"""What flies behind the in-repo MAVLink vehicle (``flight.mavlink_vehicle``): an airframe with its
own low-level autopilot, given a ``Target`` each step (world ENU, body FLU, like the rest of
aerorelay; the vehicle converts from NED/FRD on the wire).

* ``PointMass``: an ideal autopilot on a point mass. A position target is tracked with its
  velocity and acceleration feed-forward (``a = a_ff + kp (p - x) + kd (v - x_dot)``), an attitude
  target's thrust is applied along its body z (``a = R e3 g thrust - g e3``, ``thrust`` normalized to
  hover); its attitude is the one its acceleration implies. It tests the protocol, not dynamics.
* ``RotorpyQuadrotor``: RotorPy's multirotor (``rotorpy.vehicles.multirotor.Multirotor``: rigid
  body, first-order motors, parasitic and rotor drag, translational lift; RotorPy's hummingbird by
  default), an independent simulator: position targets and holds through RotorPy's geometric SE(3)
  controller (``SE3Control``, the autopilot's position loop), attitude targets through its
  ``cmd_ctatt`` attitude loop, each at ``max_step_s``. RotorPy's world and body frames are z-up like
  ENU/FLU; its quaternions are ``[x, y, z, w]``. ``wind(t, p)`` (m/s, world) is the air it flies in.
* ``MultirotorAirframe``: aerorelay's own plant for the scenario's platform (the tilted hexarotor)
  under a multirotor autopilot's cascade (position, attitude, allocation, motors), thrust along body z.
* ``MissionFlyer``: the inspection drone on its mission path, for a second MAVLink system.

Disarmed, an airframe sits where it is (no integration).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from ..models.geometry import E3, attitude_from_thrust, rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.state import ETA, OMEGA, ROTORS, P, V
from ..models.vehicle import Multirotor

GRAVITY = 9.81
TARGET_KINDS = ("idle", "hold", "position", "attitude")


@dataclass(frozen=True)
class Target:
    """What the autopilot flies this step. ``idle``: disarmed; ``hold``: stay at ``p`` (m) with yaw
    ``yaw`` (rad, ENU); ``position``: ``p`` (m), ``v`` (m/s), ``a`` (m/s^2 feed-forward), ``yaw``;
    ``attitude``: ``R`` (body FLU to world ENU) and ``thrust`` (collective thrust over the hover thrust)."""

    kind: str
    p: np.ndarray = field(default_factory=lambda: np.zeros(3))
    v: np.ndarray = field(default_factory=lambda: np.zeros(3))
    a: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    thrust: float = 1.0

    def __post_init__(self):
        if self.kind not in TARGET_KINDS:
            raise ValueError(f"Target.kind must be one of {TARGET_KINDS}, got {self.kind!r}")


def substeps(dt: float, max_step_s: float) -> tuple[int, float]:
    """The autopilot's sub-steps over a step of ``dt`` s: how many, none longer than ``max_step_s``, and their length (s)."""
    n = max(1, math.ceil(dt / max_step_s - 1e-9))
    return n, dt / n


class Airframe(Protocol):
    """An airframe with its autopilot: position ``p`` (m), velocity ``v`` (m/s), attitude ``R``, body
    rates ``rates`` (rad/s), ``mav_type`` (MAVLink's MAV_TYPE in its heartbeat); ``fly(target, t, dt)``."""

    mav_type: int

    @property
    def p(self) -> np.ndarray: ...

    @property
    def v(self) -> np.ndarray: ...

    @property
    def R(self) -> np.ndarray: ...

    @property
    def rates(self) -> np.ndarray: ...

    def fly(self, target: Target, t: float, dt: float) -> None: ...


@dataclass
class PointMassGains:
    """The point mass's position gain (1/s^2) and velocity gain (1/s)."""

    kp: float = 4.0
    kd: float = 4.0


class PointMass:
    """An ideal autopilot on a point mass (see the module)."""

    mav_type = 13  # MAV_TYPE_HEXAROTOR: it stands in for aerorelay's relay

    def __init__(self, position, gains: PointMassGains = PointMassGains()):
        self.p, self.v = np.asarray(position, float).copy(), np.zeros(3)
        self.R, self.rates, self.gains = np.eye(3), np.zeros(3), gains
        self.yaw = 0.0

    def _acceleration(self, tg: Target) -> np.ndarray:
        g = self.gains
        if tg.kind == "position":
            return tg.a + g.kp * (tg.p - self.p) + g.kd * (tg.v - self.v)
        if tg.kind == "attitude":
            return tg.R @ E3 * GRAVITY * tg.thrust - GRAVITY * E3
        return g.kp * (tg.p - self.p) - g.kd * self.v

    def fly(self, target: Target, t: float, dt: float) -> None:
        if target.kind == "idle":
            return
        a = self._acceleration(target)
        if target.kind == "attitude":
            self.R = target.R
        else:
            self.yaw = target.yaw
            self.R = rotation_zyx(attitude_from_thrust(a + GRAVITY * E3, self.yaw))
        self.p = self.p + self.v * dt + 0.5 * a * dt**2
        self.v = self.v + a * dt


class MissionFlyer:
    """The inspection drone flying its own mission (``trajectory``, the scenario's source path) exactly,
    on the vehicle's clock: its attitude follows its acceleration at zero yaw (aerorelay's source
    model); the vehicle's arming and modes do not drive it (``aerorelay sitl --source``)."""

    mav_type = 2  # MAV_TYPE_QUADROTOR

    def __init__(self, trajectory: SourceTrajectory):
        self.trajectory = trajectory
        self.rates = np.zeros(3)
        self._at(0.0)

    def _at(self, t: float) -> None:
        s = self.trajectory.state(t)
        self.p, self.v = np.asarray(s.p, float), np.asarray(s.v, float)
        self.R = rotation_zyx(s.attitude(GRAVITY))

    def fly(self, target: Target, t: float, dt: float) -> None:
        self._at(t + dt)


@dataclass
class AutopilotGains:
    """A multirotor autopilot's gains: position (1/s^2) and velocity (1/s) per axis, attitude (1/s^2)
    and body rate (1/s), and the motors' first-order time constant (s). The defaults fly the paper's
    2.57 kg tilted hexarotor within its motor bounds (a 1 m step settles in ~2 s; RotorPy's gains for
    its 0.5 kg quadrotor saturate its motors and diverge)."""

    kp_pos: tuple[float, float, float] = (3.0, 3.0, 6.0)
    kd_pos: tuple[float, float, float] = (3.0, 3.0, 5.0)
    kp_att: float = 150.0
    kd_att: float = 25.0
    motor_time_constant_s: float = 0.02


class MultirotorAirframe:
    """aerorelay's own plant (``models.vehicle.Multirotor``, eq. 1: any rotor layout, the tilted
    hexarotor by default) under an autopilot of the usual cascade, as PX4 flies a multirotor: a position
    target (or a hold) becomes a force (``m (a_ff + kp e_p + kd e_v + g e3)``) whose direction the body z
    axis is turned to (at the target's yaw) and whose component along it is the collective thrust; an
    attitude target is tracked with its thrust along body z. Attitude by the geometric law
    ``tau = J (-kp e_R - kd omega) + omega x J omega``; the wrench allocated to squared rotor speeds
    (least squares, within the speed bounds), each motor following its speed as a first-order lag
    within its acceleration bounds; the plant integrated by RK4 at ``max_step_s``. Its thrust stays
    along body z, as an autopilot flies it: the lateral forces a tilted hexarotor's rotors can make,
    which aerorelay's NMPC plans with, are not used."""

    def __init__(self, vehicle: Multirotor, position, gains: AutopilotGains = AutopilotGains(), *, max_step_s: float = 0.0025):
        self.vehicle, self.gains, self.max_step = vehicle, gains, max_step_s
        self.x = vehicle.hover_state(np.asarray(position, float))
        F, M = vehicle.allocation()
        self._wrench_to_speeds2 = np.linalg.pinv(np.vstack([F, M]))
        self._bounds2 = (vehicle.omega_min**2, vehicle.omega_max**2)
        self.mav_type = 13 if vehicle.n_rotors == 6 else 14 if vehicle.n_rotors == 8 else 2  # hexa, octo, quad

    @property
    def p(self) -> np.ndarray:
        return self.x[P]

    @property
    def v(self) -> np.ndarray:
        return self.x[V]

    @property
    def R(self) -> np.ndarray:
        return rotation_zyx(self.x[ETA])

    @property
    def rates(self) -> np.ndarray:
        return self.x[OMEGA]

    def _wrench(self, tg: Target) -> np.ndarray:
        """The body force and torque (N, N m) the autopilot asks for now."""
        veh, g = self.vehicle, self.gains
        R, w = self.R, self.rates
        if tg.kind == "attitude":
            R_d, thrust = tg.R, tg.thrust * veh.mass * veh.gravity
        else:
            v_d, a_d = (tg.v, tg.a) if tg.kind == "position" else (np.zeros(3), np.zeros(3))
            force = veh.mass * (a_d + np.asarray(g.kp_pos) * (tg.p - self.p) + np.asarray(g.kd_pos) * (v_d - self.v)
                                + veh.gravity * E3)
            R_d = rotation_zyx(attitude_from_thrust(force, tg.yaw))
            thrust = float(force @ (R @ E3))
        S = 0.5 * (R_d.T @ R - R.T @ R_d)
        e_R = np.array([S[2, 1], S[0, 2], S[1, 0]])
        J = veh.inertia
        torque = J @ (-g.kp_att * e_R - g.kd_att * w) + np.cross(w, J @ w)
        return np.concatenate([[0.0, 0.0, thrust], torque])

    def fly(self, target: Target, t: float, dt: float) -> None:
        if target.kind == "idle":
            return
        veh = self.vehicle
        n, h = substeps(dt, self.max_step)
        for _ in range(n):
            speeds2 = np.clip(self._wrench_to_speeds2 @ self._wrench(target), *self._bounds2)
            u = np.clip((np.sqrt(speeds2) - self.x[ROTORS]) / self.gains.motor_time_constant_s, veh.omega_dot_min, veh.omega_dot_max)
            self.x = np.asarray(veh.rk4_step(self.x, u, h), float).ravel()


WindField = Callable[[float, np.ndarray], np.ndarray]  # (t s, position m) -> wind m/s, world


def still_air(t: float, p: np.ndarray) -> np.ndarray:
    return np.zeros(3)


class RotorpyQuadrotor:
    """RotorPy's multirotor and its controllers (see the module); ``params``: a RotorPy parameter dict
    (default: its hummingbird); ``wind``: the air; ``max_step_s``: the autopilot's period (s)."""

    mav_type = 2  # MAV_TYPE_QUADROTOR

    def __init__(self, position, params: dict | None = None, *, wind: WindField = still_air, max_step_s: float = 0.005):
        from rotorpy.controllers.quadrotor_control import SE3Control  # noqa: PLC0415 - an optional dependency
        from rotorpy.vehicles.hummingbird_params import quad_params  # noqa: PLC0415
        from rotorpy.vehicles.multirotor import Multirotor  # noqa: PLC0415

        self.params = dict(quad_params if params is None else params)
        hover = math.sqrt(self.params["mass"] * GRAVITY / (self.params["num_rotors"] * self.params["k_eta"]))
        self.state = {"x": np.asarray(position, float).copy(), "v": np.zeros(3), "q": np.array([0.0, 0.0, 0.0, 1.0]),
                      "w": np.zeros(3), "wind": np.zeros(3), "rotor_speeds": np.full(self.params["num_rotors"], hover)}
        self._speeds = Multirotor(self.params, initial_state=self.state, control_abstraction="cmd_motor_speeds")
        self._attitude = Multirotor(self.params, initial_state=self.state, control_abstraction="cmd_ctatt")
        self._se3 = SE3Control(self.params)
        self.wind, self.max_step = wind, max_step_s
        self.weight_n = self.params["mass"] * GRAVITY

    @property
    def p(self) -> np.ndarray:
        return self.state["x"]

    @property
    def v(self) -> np.ndarray:
        return self.state["v"]

    @property
    def R(self) -> np.ndarray:
        return Rotation.from_quat(self.state["q"]).as_matrix()

    @property
    def rates(self) -> np.ndarray:
        return self.state["w"]

    def _flat(self, tg: Target) -> dict:
        zero = np.zeros(3)
        v, a = (tg.v, tg.a) if tg.kind == "position" else (zero, zero)
        return {"x": tg.p, "x_dot": v, "x_ddot": a, "x_dddot": zero, "x_ddddot": zero, "yaw": tg.yaw, "yaw_dot": 0.0,
                "yaw_ddot": 0.0}

    def fly(self, target: Target, t: float, dt: float) -> None:
        if target.kind == "idle":
            return
        n, h = substeps(dt, self.max_step)
        for i in range(n):
            self.state["wind"] = np.asarray(self.wind(t + i * h, self.state["x"]), float)
            if target.kind == "attitude":
                q = Rotation.from_matrix(target.R).as_quat()
                self.state = self._attitude.step(self.state, {"cmd_thrust": target.thrust * self.weight_n, "cmd_q": q}, h)
            else:
                cmd = self._se3.update(t + i * h, self.state, self._flat(target))
                self.state = self._speeds.step(self.state, {"cmd_motor_speeds": cmd["cmd_motor_speeds"]}, h)
