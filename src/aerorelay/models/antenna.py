"""Antenna radiation patterns (paper Appendix A) and link elevation angles.

A pattern maps the elevation angle ``theta`` in [0, pi] between a link direction and the
antenna axis (body z) to a power gain. Patterns are doughnut shaped: zero on the axis, peak
``g_bar`` broadside. Internally patterns are evaluated from ``c = cos(theta)``, which is
smooth and avoids the 0/0 of the dipole formula on the axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .backend import ops

_AXIS_EPS = 1e-12


class AntennaPattern(Protocol):
    """Interface for a pluggable pattern: gain from the cosine of the elevation angle."""

    @property
    def g_bar(self) -> float: ...

    def gain_from_cos(self, c):
        """Power gain for ``c = cos(theta)``, in [0, g_bar]. numpy arrays (vectorized)."""
        ...


def dipole_gain(theta, g_bar: float = 1.0):
    """Half-wave dipole gain ``G = g_bar (cos(pi/2 cos th) / sin th)^2`` (paper App. A).

    ``theta`` in rad (vectorized); ``G(0) = G(pi) = 0`` and ``G(pi/2) = g_bar``.
    """
    return DipolePattern(g_bar).gain_from_cos(np.cos(np.asarray(theta, dtype=float)))


@dataclass(frozen=True)
class DipolePattern:
    """Half-wave dipole along body z; ``g_bar`` is the broadside (maximum) gain."""

    g_bar: float = 1.0

    def gain_from_cos(self, c):
        c = np.clip(np.asarray(c, dtype=float), -1.0, 1.0)
        s2 = 1.0 - c * c  # sin^2(theta)
        num = np.cos(0.5 * np.pi * c) ** 2
        safe = np.where(s2 > _AXIS_EPS, s2, 1.0)
        return self.g_bar * np.where(s2 > _AXIS_EPS, num / safe, 0.0)


@dataclass(frozen=True)
class SinPowerPattern:
    """Generic doughnut ``G = g_bar sin(theta)^n`` (n = 2 is a short dipole)."""

    exponent: float = 2.0
    g_bar: float = 1.0

    def gain_from_cos(self, c):
        c = np.clip(np.asarray(c, dtype=float), -1.0, 1.0)
        return self.g_bar * (1.0 - c * c) ** (0.5 * self.exponent)


@dataclass(frozen=True)
class IsotropicPattern:
    """The same gain ``g_bar`` in every direction (e.g. a base station whose antenna the paper does
    not specify)."""

    g_bar: float = 1.0

    def gain_from_cos(self, c):
        return np.full(np.shape(c), self.g_bar, dtype=float)


@dataclass(frozen=True)
class NodePatterns:
    """The antenna pattern of each node: relay (MRAV-1), source (MRAV-2), base station."""

    relay: AntennaPattern
    source: AntennaPattern
    bs: AntennaPattern


@dataclass(frozen=True)
class TabulatedPattern:
    """Measured pattern: gains at elevation angles (deg, ascending in [0, 180]), interpolated."""

    theta_deg: tuple[float, ...]
    gain: tuple[float, ...]

    @property
    def g_bar(self) -> float:
        return float(max(self.gain))

    def gain_from_cos(self, c):
        theta = np.degrees(np.arccos(np.clip(np.asarray(c, dtype=float), -1.0, 1.0)))
        return np.interp(theta, self.theta_deg, self.gain)


def link_direction_cos(p_from, R_from, p_to):
    """Cosine of the elevation angle of the link ``p_from -> p_to`` at node ``p_from``.

    ``c = a_z`` with ``a = R_from^T (p_to - p_from)/|p_to - p_from|`` (paper App. A): the link
    direction expressed in the node's body frame, projected on its antenna axis. *Dual*.
    """
    o = ops(p_from, R_from, p_to)
    d = p_to - p_from
    a = o.matTvec(R_from, d)
    return o.component(a, 2) / o.norm(d)


def elevation_angle(p_from, R_from, p_to):
    """Elevation angle ``theta = arccos(a_z)`` in rad, in [0, pi] (paper App. A). *Dual*."""
    o = ops(p_from, R_from, p_to)
    return o.arccos(link_direction_cos(p_from, R_from, p_to))
