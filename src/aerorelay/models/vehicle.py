"""Generically-tilted multirotor (GTMR) dynamics (paper Sec. V-A, eq. 1-2).

State ``x = (p, eta, v, omega, Omega)`` with ``12 + N_p`` entries: position p (m, world),
ZYX Euler angles eta (rad), velocity v (m/s, world), body rate omega (rad/s, body), motor
speeds Omega (Hz = rev/s). Input ``u = Omega_dot`` (Hz/s). Rotor i at body position ``p_m_i``
with unit axis ``z_P_i`` and spin ``s_i = +-1`` produces thrust ``c_xi Omega_i^2 z_P_i`` and
moment ``(c_xi p_m_i x z_P_i + s_i c_tau z_P_i) Omega_i^2``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from .backend import is_symbolic, ops
from .geometry import E3, euler_rate_matrix, rotation_zyx
from .state import ROTORS, P, unpack

# Representative arm length of a medium-scale research hexarotor (the paper does not give one).
HEXAROTOR_ARM_LENGTH_M = 0.35


class HoverInfeasibleError(ValueError):
    """The layout cannot balance gravity with zero moment inside the motor-speed bounds."""


# hover_tilt_limits by what decides them (the allocation, weight, motor range and azimuths): a pure function, kept
# for the process (a fleet's planners are built per relay, a campaign's per run)
_TILT_LIMITS: dict[tuple, np.ndarray] = {}


@dataclass(frozen=True)
class Multirotor:
    """A GTMR: rotor layout plus rigid-body and actuator parameters (SI units, speeds in Hz)."""

    positions: np.ndarray  # (N_p, 3) rotor centres in the body frame, m
    axes: np.ndarray  # (N_p, 3) unit thrust axes in the body frame
    spins: np.ndarray  # (N_p,) +1 / -1: sign of the drag moment along the axis
    mass: float = 2.57
    inertia: np.ndarray = field(default_factory=lambda: np.diag([0.11, 0.11, 0.19]))
    gravity: float = 9.81
    c_xi: float = 1.18e-3  # thrust coefficient, N/Hz^2
    c_tau: float = 2.5e-5  # drag-moment coefficient, N m/Hz^2
    omega_min: float = 16.0  # Hz
    omega_max: float = 100.0  # Hz
    omega_dot_min: float = -300.0  # Hz/s
    omega_dot_max: float = 400.0  # Hz/s

    @property
    def n_rotors(self) -> int:
        return int(self.positions.shape[0])

    @property
    def nx(self) -> int:
        return 12 + self.n_rotors

    def allocation(self) -> tuple[np.ndarray, np.ndarray]:
        """Allocation matrices ``F, M`` (3 x N_p): body force and moment per unit ``Omega_i^2``."""
        return self._allocation

    @cached_property
    def _allocation(self) -> tuple[np.ndarray, np.ndarray]:
        F = self.c_xi * self.axes.T
        M = (self.c_xi * np.cross(self.positions, self.axes) + self.c_tau * self.spins[:, None] * self.axes).T
        return F, M

    def hover_speeds(self) -> np.ndarray:
        """Motor speeds (Hz) holding a level hover: ``F w = m g e3``, ``M w = 0``, ``w = Omega^2``.

        Minimum-norm least squares when the layout is redundant. Raises HoverInfeasibleError
        when no such ``w`` exists or a speed falls outside ``[omega_min, omega_max]``.
        """
        F, M = self.allocation()
        A = np.vstack([F, M])
        b = np.concatenate([self.mass * self.gravity * E3, np.zeros(3)])
        w, *_ = np.linalg.lstsq(A, b, rcond=None)
        if np.linalg.norm(A @ w - b) > 1e-6 * np.linalg.norm(b) or np.any(w <= 0):
            raise HoverInfeasibleError("hover infeasible: the rotor layout cannot balance gravity with zero moment")
        speeds = np.sqrt(w)
        if speeds.min() < self.omega_min or speeds.max() > self.omega_max:
            raise HoverInfeasibleError(
                f"hover infeasible: hover needs motor speeds in [{speeds.min():.1f}, {speeds.max():.1f}] Hz, "
                f"outside the allowed range [{self.omega_min}, {self.omega_max}] Hz"
            )
        return speeds

    def can_hover_tilted(self, tilt: float, azimuth: float) -> bool:
        """Whether the vehicle can hold a hover with its body z tilted by ``tilt`` rad from
        vertical toward body azimuth ``azimuth`` rad: some ``w = Omega^2`` inside the motor bounds
        gives ``F w = m g R' e3`` and ``M w = 0`` (a linear feasibility problem)."""
        from scipy.optimize import linprog

        F, M = self.allocation()
        v = np.array([-np.sin(tilt) * np.cos(azimuth), -np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])  # R' e3
        A = np.vstack([F, M])
        b = np.concatenate([self.mass * self.gravity * v, np.zeros(3)])
        res = linprog(np.zeros(self.n_rotors), A_eq=A, b_eq=b, bounds=[(self.omega_min**2, self.omega_max**2)] * self.n_rotors,
                      method="highs")
        return bool(res.status == 0)

    def _tilt_limit_toward(self, azimuth: float, known: float = 0.0) -> float:
        """Largest hover tilt (rad) toward body ``azimuth``, bisection to 0.1 deg; ``known``: a tilt
        already found elsewhere, returned unchanged when this azimuth cannot beat it."""
        if not self.can_hover_tilted(known + np.radians(0.1), azimuth):
            return known
        lo, hi = known, np.radians(89.0)
        while hi - lo > np.radians(0.1):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.can_hover_tilted(mid, azimuth) else (lo, mid)
        return lo

    def hover_tilt_limits(self, azimuths) -> np.ndarray:
        """Largest hover tilt (rad) toward each body azimuth (rad), bisection to 0.1 deg: with zero
        yaw, the antenna axis tilts the vehicle can hold toward each world azimuth. Found once per
        process for equal vehicles (``_TILT_LIMITS``: about 400 LPs, 0.6 s, for 36 azimuths)."""
        az = np.asarray(azimuths, float)
        key = self._hover_key + (az.tobytes(),)
        if key not in _TILT_LIMITS:
            _TILT_LIMITS[key] = np.array([self._tilt_limit_toward(a) for a in az])
            _TILT_LIMITS[key].setflags(write=False)
        return _TILT_LIMITS[key]

    @cached_property
    def _hover_key(self) -> tuple:
        """What decides whether a tilted hover is holdable (``can_hover_tilted``): the allocation, weight, motor range."""
        F, M = self.allocation()
        return (F.tobytes(), M.tobytes(), self.mass, self.gravity, self.omega_min, self.omega_max)

    @cached_property
    def hover_tilt_limit(self) -> float:
        """Largest body tilt (rad) the vehicle can hold in hover toward its best body azimuth (yaw
        free, so any world azimuth): 0 for a coplanar layout. Bisection to 0.1 deg over 72 azimuths
        (found once per process for equal vehicles)."""
        key = self._hover_key + ("best",)
        if key not in _TILT_LIMITS:
            best = 0.0
            for az in np.radians(np.arange(0.0, 360.0, 5.0)):
                best = self._tilt_limit_toward(az, best)
            _TILT_LIMITS[key] = np.array(best)
        return float(_TILT_LIMITS[key])

    def hover_state(self, position=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Equilibrium state at ``position`` with zero attitude, velocity and body rate."""
        x = np.zeros(self.nx)
        x[P] = position
        x[ROTORS] = self.hover_speeds()
        return x

    def dynamics(self, x, u, a_ext=None):
        """``x_dot = f(x, u)`` (eq. 1 with ``Omega_dot = u``); ``a_ext``: an external acceleration
        (m/s^2, world) added to the translational one. *Dual*: numpy arrays or CasADi."""
        o = ops(x, u)
        sym = is_symbolic(x, u)
        F, M = self.allocation()
        _, eta, v, w, Om = unpack(x)
        Om2 = Om * Om
        R = rotation_zyx(eta)
        J = self.inertia
        if sym:
            force_body = ca.mtimes(ca.DM(F), Om2)
            moment_body = ca.mtimes(ca.DM(M), Om2)
            Jw = ca.mtimes(ca.DM(J), w)
            wdot = ca.solve(ca.DM(J), moment_body - o.cross(w, Jw))
            acc = ca.mtimes(R, force_body) / self.mass - self.gravity * ca.DM(E3)
            if a_ext is not None:
                acc = acc + a_ext
            return ca.vertcat(v, ca.mtimes(euler_rate_matrix(eta), w), acc, wdot, u)
        x = np.asarray(x, float)
        force_body, moment_body = F @ Om2, M @ Om2
        wdot = np.linalg.solve(J, moment_body - np.cross(w, J @ w))
        acc = R @ force_body / self.mass - self.gravity * E3
        if a_ext is not None:
            acc = acc + np.asarray(a_ext, float)
        return np.concatenate([v, euler_rate_matrix(eta) @ w, acc, wdot, np.asarray(u, float)])

    def rk4_step(self, x, u, dt: float, a_ext=None):
        """One classical Runge-Kutta-4 step of length ``dt`` s with ``u`` (and ``a_ext``) held. *Dual*."""
        k1 = self.dynamics(x, u, a_ext)
        k2 = self.dynamics(x + 0.5 * dt * k1, u, a_ext)
        k3 = self.dynamics(x + 0.5 * dt * k2, u, a_ext)
        k4 = self.dynamics(x + dt * k3, u, a_ext)
        return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    def shaft_power(self, speeds) -> np.ndarray:
        """Aerodynamic shaft power ``sum_i c_tau Omega_i^2 * 2 pi Omega_i`` in W (speeds in Hz)."""
        s = np.asarray(speeds, float)
        return np.sum(self.c_tau * s**3 * 2.0 * np.pi, axis=-1)


def star_layout(n_rotors: int, tilt_deg: float = 0.0, arm_length: float = HEXAROTOR_ARM_LENGTH_M):
    """Star rotor layout: ``n_rotors`` arms evenly spaced starting on body +x.

    Rotor i (0-based) sits at ``L (cos b_i, sin b_i, 0)`` with ``b_i = i * 360 deg / n``; its axis
    is body z rotated about the arm by ``(-1)^i * tilt`` (alternating, as in Ryll et al.); its spin
    is ``s_i = (-1)^i`` so the drag moments cancel in hover (use an even count for that).
    """
    i = np.arange(n_rotors)
    beta = 2.0 * np.pi * i / n_rotors
    arm = np.stack([np.cos(beta), np.sin(beta), np.zeros(n_rotors)], axis=-1)
    alpha = np.radians(tilt_deg) * (-1.0) ** i
    # Rodrigues about the (horizontal) arm axis a: z_P = cos(alpha) e3 + sin(alpha) (a x e3).
    axes = np.cos(alpha)[:, None] * E3 + np.sin(alpha)[:, None] * np.cross(arm, E3)
    spins = (-1.0) ** i
    return arm_length * arm, axes, spins


def hexarotor_layout(tilt_deg: float = 0.0, arm_length: float = HEXAROTOR_ARM_LENGTH_M):
    """The paper's hexarotor layout: ``star_layout(6, ...)`` (arms every 60 deg)."""
    return star_layout(6, tilt_deg, arm_length)


def star_multirotor(n_rotors: int, tilt_deg: float = 0.0, arm_length: float = HEXAROTOR_ARM_LENGTH_M,
                    **params) -> Multirotor:
    """A multirotor with the star layout of ``star_layout``."""
    positions, axes, spins = star_layout(n_rotors, tilt_deg, arm_length)
    return Multirotor(positions=positions, axes=axes, spins=spins, **params)


def hexarotor(tilt_deg: float = 0.0, arm_length: float = HEXAROTOR_ARM_LENGTH_M, **params) -> Multirotor:
    """The paper's hexarotor: ``tilt_deg=0`` coplanar, ``tilt_deg=20`` tilted (fully actuated)."""
    return star_multirotor(6, tilt_deg, arm_length, **params)
