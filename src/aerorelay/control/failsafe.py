"""Fail-safe hover/brake law for any multirotor: what flies the relay while the NMPC cannot.

A geometric controller (Lee, Leok, McClamroch, 2010) on the vehicle's own allocation: a PD law
on position and velocity gives the desired force ``f_d = m (a_cmd + g e3)`` (world), the body z
axis is aligned with it (keeping the current heading), a PD law on the rotation error gives the desired moment,
and the motor speeds come from a bounded least-squares allocation ``[F; M] Omega^2 = [R' f_d;
M_d]`` with ``Omega`` in its bounds (a fully-actuated platform uses its lateral force too; a
coplanar one has zero rows there), made unique by a faint pull toward the rotors' speeds now
(``BrakeGains.allocation_reg``). The motors are driven toward those speeds at a rate inside
``[omega_dot_min, omega_dot_max]``.

Where and how stiffly it stops depends on the velocity at the hand-over (``BrakeLaw.hold``): a
critically damped PD law of natural frequency ``w`` from velocity ``v`` toward the point ``p + v/w``
decays as ``v exp(-w t)`` with no overshoot, peak acceleration ``w |v|`` and stopping distance
``|v|/w``. The frequency is raised (up to ``max_accel / |v|``) until that distance, plus the
distance coasted while the attitude turns (``attitude_lag_s``), fits before the workspace box shrunk
by ``margin_m``; the point is then clipped into that box. A hand-over at speed near a wall therefore
brakes hard and early instead of aiming at the hand-over position and overshooting past it. The allocation is prioritized: while the
body z axis is far from the desired one, the moment rows dominate and the collective thrust is
held at half the weight, so the law recovers from any attitude (an inverted relay included).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from ..models.geometry import E3, rotation_zyx
from ..models.state import unpack
from ..models.vehicle import Multirotor


@dataclass(frozen=True)
class BrakeGains:
    """Gains of the brake law: the position PD's natural frequency from rest and its ceiling
    (rad/s), attitude natural frequency (rad/s) and damping, acceleration limit (m/s^2), the same
    for a steep hand-over, coasting time while the body turns (s), motor time constant (s) and the
    allocation's weight of a moment row against a force row."""

    freq: float = 1.5  # position PD: kp = freq^2, kd = 2 freq (critically damped)
    attitude_freq: float = 8.0
    attitude_damping: float = 0.9
    max_accel: float = 6.0
    # a hand-over beyond this tilt recovers the attitude first, with softer attitude gains and
    # less acceleration for the whole episode (switching gains mid-recovery cycles)
    recovery_tilt_deg: float = 40.0
    recovery_attitude_freq: float = 6.0
    recovery_max_accel: float = 3.0
    attitude_lag_s: float = 0.3  # coasting while the body turns toward the braking force
    max_freq: float = 2.5  # a quarter of the attitude loop's: the cascade stays separated
    motor_time_constant: float = 0.05
    moment_weight: float = 10.0  # allocation: a moment row (N m) against a force row (N); moments first under saturation
    # allocation: a row per rotor weighting its squared speed's change from now (per Hz^2, against a force row's N): among
    # the allocations that give the wrench equally (8 rotors for 6 rows on the octocopter), the one nearest the rotors'
    # speeds now. Unique, so the C tree's BVLS finds Python's point (without it the two picked different ones of the
    # set: 82 Hz/s apart on one octocopter step); 1000 Hz^2 of change weighs 1e-3 N
    allocation_reg: float = 1e-6


@dataclass(frozen=True)
class Hold:
    """Where the brake law brings the relay to rest (m, world) and its position PD's natural
    frequency (rad/s)."""

    point: np.ndarray
    freq: float
    upright: bool = True  # False: the hand-over came at a steep attitude, the law recovers it gently


def _vee(S: np.ndarray) -> np.ndarray:
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


class BrakeLaw:
    """``u = law(x, hold)``: motor accelerations (Hz/s) that bring ``x`` to rest at ``hold``."""

    def __init__(self, vehicle: Multirotor, workspace_min, workspace_max, *, margin_m: float = 0.5,
                 gains: BrakeGains | None = None):
        self.veh = vehicle
        self.g = gains or BrakeGains()
        lo, hi = np.asarray(workspace_min, float), np.asarray(workspace_max, float)
        margin = np.minimum(margin_m, 0.25 * (hi - lo))
        self.lo, self.hi = lo + margin, hi - margin
        F, M = vehicle.allocation()
        self.A = np.vstack([F, M])
        self.bounds = (np.full(vehicle.n_rotors, vehicle.omega_min**2), np.full(vehicle.n_rotors, vehicle.omega_max**2))
        J = np.asarray(vehicle.inertia, float)
        self.cos_recovery = float(np.cos(np.radians(self.g.recovery_tilt_deg)))
        # attitude PD gains (N m / rad, N m s / rad): upright, recovering
        self.gains = {up: (J * f**2, J * 2.0 * self.g.attitude_damping * f)
                      for up, f in ((True, self.g.attitude_freq), (False, self.g.recovery_attitude_freq))}

    def hold(self, position, velocity=None, attitude=None) -> Hold:
        """Where and how stiffly to stop from ``position`` (m) at ``velocity`` (m/s, world) and
        ``attitude`` (ZYX Euler angles, rad; None: level): the overshoot-free stop ``position +
        velocity / freq``, the frequency raised so that it fits inside the shrunk box, the point
        clipped into it. A steep attitude gets the gentle recovery law, aimed where it is."""
        p = np.asarray(position, float)
        v = np.zeros(3) if velocity is None or not np.all(np.isfinite(velocity)) else np.asarray(velocity, float)
        upright = attitude is None or not np.all(np.isfinite(attitude)) or rotation_zyx(attitude)[2, 2] > self.cos_recovery
        speed = float(np.linalg.norm(v))
        if not upright or speed < 1e-9:
            return Hold(np.clip(p, self.lo, self.hi), self.g.freq, upright)
        room = np.where(v > 0.0, self.hi - p, p - self.lo) - np.abs(v) * self.g.attitude_lag_s
        need = np.abs(v) / np.maximum(room, 1e-3)
        freq = float(np.clip(need.max(), self.g.freq, max(self.g.freq, min(self.g.max_freq, self.g.max_accel / speed))))
        return Hold(np.clip(p + v / freq, self.lo, self.hi), freq)

    def hold_point(self, position) -> np.ndarray:
        """Where to stop from rest: ``position`` clipped into the shrunk workspace box."""
        return self.hold(position).point

    def __call__(self, x: np.ndarray, hold: Hold) -> np.ndarray:
        veh = self.veh
        if not np.all(np.isfinite(x)):
            return np.zeros(veh.n_rotors)  # nothing to measure: hold the motor speeds
        p, eta, v, w, speeds = unpack(x)
        R = rotation_zyx(eta)
        a_cmd = -hold.freq**2 * (p - hold.point) - 2.0 * hold.freq * v
        n, a_max = np.linalg.norm(a_cmd), self.g.max_accel if hold.upright else self.g.recovery_max_accel
        if n > a_max:
            a_cmd *= a_max / n
        f_d = veh.mass * (a_cmd + veh.gravity * E3)
        b3 = f_d / np.linalg.norm(f_d)
        # keep the current heading (a brake needs no yaw; a 180 deg yaw error would take the
        # moments the tilt needs): body x projected off the desired body z
        heading = R[:, 0] if abs(R[:, 0] @ b3) < 0.95 else R[:, 1]
        b2 = np.cross(b3, heading)
        b2 /= np.linalg.norm(b2)
        Rd = np.column_stack([np.cross(b2, b3), b2, b3])  # body z along f_d
        e_R = 0.5 * _vee(Rd.T @ R - R.T @ Rd)
        z = R[:, 2]
        if z @ b3 < 0.0:  # beyond 90 deg Lee's error shrinks toward its 180 deg singularity: turn body z by the angle itself
            axis = np.cross(z, b3)
            n_axis = np.linalg.norm(axis)
            axis = axis / n_axis if n_axis > 1e-6 else R[:, 0]
            e_R = -np.arccos(np.clip(z @ b3, -1.0, 1.0)) * (R.T @ axis)
        J = np.asarray(veh.inertia, float)
        kR, kw = self.gains[hold.upright]
        M_d = -kR @ e_R - kw @ w + np.cross(w, J @ w)
        # prioritized allocation: far from the desired attitude (an inverted or steeply tilted
        # relay cannot push where f_d points) the moments come first and the collective thrust is
        # held at half the weight, so differential thrust can turn the vehicle back
        align = float(b3 @ R[:, 2])
        f_body = R.T @ f_d
        w_force = 1.0
        if align < 0.5:
            w_force, f_body = 0.1, np.array([0.0, 0.0, 0.5 * veh.mass * veh.gravity])
        rows = np.r_[np.full(3, w_force), np.full(3, self.g.moment_weight)]
        target = np.concatenate([f_body, M_d])
        reg = self.g.allocation_reg
        A = np.vstack([self.A * rows[:, None], reg * np.eye(veh.n_rotors)])
        b = np.concatenate([target * rows, reg * speeds**2])
        w2 = lsq_linear(A, b, bounds=self.bounds, method="bvls").x
        u = (np.sqrt(w2) - speeds) / self.g.motor_time_constant
        return np.clip(u, veh.omega_dot_min, veh.omega_dot_max)
