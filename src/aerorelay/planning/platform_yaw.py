"""Yawing a tilted multirotor so its strongest tilt azimuth sits under the antenna axis it wants.

A tilted-rotor platform holds a tilted hover only up to a limit that depends on the tilt's
azimuth in its body frame (``Multirotor.hover_tilt_limits``: 9.6-17.8 deg for the nominal
hexarotor, peaks 120 deg apart). At zero yaw the holdable antenna axes are the body set ``A0``;
yawed by ``psi`` they are ``Rz(psi) A0``. ``PlatformYaw`` keeps a yaw goal (one of the yaws ``step``
apart within +-``span``, moved when another scores better by ``gain``), a yaw reference that follows it at <= ``rate``, and
clips an axis to what the platform holds at its measured yaw (so the NMPC is never asked for a
tilt the platform cannot hold while it turns; clipped at the reference's yaw instead, the relay
swung 2-6 m off its position reference). Angles in rad; axes unit, world.
"""

from __future__ import annotations

import numpy as np


def rotate_z(vectors: np.ndarray, psi: float) -> np.ndarray:
    """``Rz(psi) v`` for rows ``v`` ``(..., 3)``."""
    c, s = np.cos(psi), np.sin(psi)
    v = np.asarray(vectors, float)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]], axis=-1)


class PlatformYaw:
    """Yaw goal, yaw reference and the axis clip (see the module docstring)."""

    def __init__(self, body_axes: np.ndarray, azimuths: np.ndarray, limits: np.ndarray, *, rate: float,
                 step: float = np.radians(10.0), span: float = np.radians(60.0), gain: float = 0.005):
        self.body_axes = np.asarray(body_axes, float)
        self.azimuths, self.limits = np.asarray(azimuths, float), np.asarray(limits, float)
        self.rate, self.gain = rate, gain
        self.goal = 0.0  # rad; within +-span (the tilt limits repeat every 120 deg on the hexarotor)
        self.ref = 0.0
        n = int(round(span / step))
        self.yaws = step * np.arange(-n, n + 1)  # every yaw the goal may take
        self._all_axes = np.concatenate([self.axes(psi) for psi in self.yaws])

    def axes(self, psi: float | None = None) -> np.ndarray:
        """The holdable axes at yaw ``psi`` (the goal by default), world."""
        return rotate_z(self.body_axes, self.goal if psi is None else psi)

    def all_axes(self) -> np.ndarray:
        """``(len(yaws) * K, 3)``: the holdable axes at every yaw, yaw by yaw (computed once)."""
        return self._all_axes

    def better(self, capacities: np.ndarray, current: float) -> int | None:
        """Given the capacities of ``all_axes()`` at one position, the index of the best axis when it beats the
        goal's ``current`` best by the relative ``gain`` (its yaw: ``yaw_of``), else None; the goal unchanged."""
        k = int(np.argmax(capacities))
        return None if capacities[k] <= current * (1.0 + self.gain) else k

    def yaw_of(self, k: int) -> float:
        """The yaw (rad) of ``all_axes()[k]``."""
        return float(self.yaws[k // len(self.body_axes)])

    def choose(self, capacities: np.ndarray, current: float) -> int | None:
        """``better``, the goal moved to its yaw."""
        k = self.better(capacities, current)
        if k is not None:
            self.goal = self.yaw_of(k)
        return k

    def advance(self, dt: float) -> float:
        """The yaw reference after ``dt`` s toward the goal at <= ``rate``."""
        d = self.goal - self.ref
        self.ref += float(np.clip(d, -self.rate * dt, self.rate * dt))
        return self.ref

    def turn(self, axis: np.ndarray, psi: float, dt: float) -> tuple[float, np.ndarray]:
        """One control step: the yaw reference after ``dt`` s (``advance``) and ``axis`` clipped to what the
        platform holds at its measured yaw ``psi`` while it turns (``clip``)."""
        return self.advance(dt), self.clip(axis, psi)

    def clip(self, axis: np.ndarray, psi: float) -> np.ndarray:
        """``axis`` with its tilt reduced to what the platform holds at yaw ``psi`` (the measured one)."""
        b = rotate_z(axis, -psi)
        tilt = float(np.arccos(np.clip(b[2], -1.0, 1.0)))
        az = float(np.arctan2(b[1], b[0])) % (2 * np.pi)
        limit = float(np.interp(az, self.azimuths, self.limits, period=2 * np.pi))
        if tilt <= limit:
            return np.asarray(axis, float)
        h = np.hypot(b[0], b[1])
        clipped = np.array([np.sin(limit) * b[0] / h, np.sin(limit) * b[1] / h, np.cos(limit)])
        return rotate_z(clipped, psi)
