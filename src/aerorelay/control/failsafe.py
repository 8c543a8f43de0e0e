"""Fail-safe hover/brake law for any multirotor: what flies the relay while the NMPC cannot.

A geometric controller (Lee, Leok, McClamroch, 2010) on the vehicle's own allocation: a PD law
on position and velocity gives the desired force ``f_d = m (a_cmd + g e3)`` (world), the body z
axis is aligned with it (keeping the current heading), a PD law on the rotation error gives the desired moment,
and the motor speeds come from a bounded least-squares allocation ``[F; M] Omega^2 = [R' f_d;
M_d]`` with ``Omega`` in its bounds (a fully-actuated platform uses its lateral force too; a
coplanar one has zero rows there). The motors are driven toward those speeds at a rate inside
``[omega_dot_min, omega_dot_max]``. The hold point is the position where the law took over,
clipped into the workspace box shrunk by ``margin_m``. The allocation is prioritized: while the
body z axis is far from the desired one, the moment rows dominate and the collective thrust is
held at half the weight, so the law recovers from any attitude (an inverted relay included).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from ..models.geometry import E3, rotation_zyx
from ..models.vehicle import Multirotor


@dataclass(frozen=True)
class BrakeGains:
    """Gains of the brake law: position (1/s^2, 1/s), attitude natural frequency (rad/s) and
    damping, acceleration limit (m/s^2), motor time constant (s)."""

    kp: float = 2.25
    kd: float = 3.0
    attitude_freq: float = 6.0
    attitude_damping: float = 0.9
    max_accel: float = 3.0
    motor_time_constant: float = 0.05


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
        self.kR = J * self.g.attitude_freq**2
        self.kw = J * 2.0 * self.g.attitude_damping * self.g.attitude_freq

    def hold_point(self, position) -> np.ndarray:
        """Where to stop: ``position`` clipped into the shrunk workspace box."""
        return np.clip(np.asarray(position, float), self.lo, self.hi)

    def __call__(self, x: np.ndarray, hold: np.ndarray) -> np.ndarray:
        veh = self.veh
        if not np.all(np.isfinite(x)):
            return np.zeros(veh.n_rotors)  # nothing to measure: hold the motor speeds
        p, eta, v, w, speeds = x[0:3], x[3:6], x[6:9], x[9:12], x[12:]
        a_cmd = -self.g.kp * (p - hold) - self.g.kd * v
        n = np.linalg.norm(a_cmd)
        if n > self.g.max_accel:
            a_cmd *= self.g.max_accel / n
        f_d = veh.mass * (a_cmd + veh.gravity * E3)
        R = rotation_zyx(eta)
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
        M_d = -self.kR @ e_R - self.kw @ w + np.cross(w, J @ w)
        # prioritized allocation: far from the desired attitude (an inverted or steeply tilted
        # relay cannot push where f_d points) the moments come first and the collective thrust is
        # held at half the weight, so differential thrust can turn the vehicle back
        align = float(b3 @ R[:, 2])
        f_body = R.T @ f_d
        w_force = 1.0
        if align < 0.5:
            w_force, f_body = 0.1, np.array([0.0, 0.0, 0.5 * veh.mass * veh.gravity])
        rows = np.r_[np.full(3, w_force), np.ones(3)]
        target = np.concatenate([f_body, M_d])
        w2 = lsq_linear(self.A * rows[:, None], target * rows, bounds=self.bounds, method="bvls").x
        u = (np.sqrt(w2) - speeds) / self.g.motor_time_constant
        return np.clip(u, veh.omega_dot_min, veh.omega_dot_max)
