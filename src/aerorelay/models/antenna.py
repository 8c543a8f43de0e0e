"""Antenna radiation patterns (paper Appendix A) and link elevation angles.

A pattern maps the elevation angle ``theta`` in [0, pi] between a link direction and the
antenna axis (body z) to a power gain. Patterns are doughnut shaped: zero on the axis, peak
``g_bar`` broadside. Internally patterns are evaluated from ``c = cos(theta)``, which is
smooth and avoids the 0/0 of the dipole formula on the axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import casadi as ca
import numpy as np

from .backend import ops

_AXIS_EPS = 1e-12
# sin^2(theta) regularization of the symbolic dipole (an NLP needs it smooth on the axis, where
# the exact gain is 0/0); the numeric form is exact
SYMBOLIC_AXIS_EPS = 1e-6


class AntennaPattern(Protocol):
    """Interface for a pluggable pattern: gain from the cosine of the elevation angle."""

    @property
    def g_bar(self) -> float: ...

    def gain_from_cos(self, c):
        """Power gain for ``c = cos(theta)``, in [0, g_bar]. numpy arrays (vectorized)."""
        ...

    def symbolic_gain_from_cos(self, c):
        """The same gain for a CasADi expression ``c`` (smooth enough for an NLP)."""
        ...


def _doughnut_bounds(pattern, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """A gain even in ``c`` and non-increasing in ``|c|``: its least at the largest ``|c|`` of ``[lo, hi]``,
    its largest at the smallest."""
    lo, hi = np.clip(np.asarray(lo, float), -1.0, 1.0), np.clip(np.asarray(hi, float), -1.0, 1.0)
    nearest = np.where((lo <= 0.0) & (hi >= 0.0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    farthest = np.maximum(np.abs(lo), np.abs(hi))
    return pattern.gain_from_cos(farthest), pattern.gain_from_cos(nearest)


def gain_bounds(pattern: AntennaPattern, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """The least and the largest gain of ``pattern`` over the cosines ``[lo, hi]`` (arrays, broadcast):
    exact for the built-in patterns (each one's ``gain_bounds``); a pattern without it is a ValueError
    (a bound over it cannot be certified)."""
    bounds = getattr(pattern, "gain_bounds", None)
    if bounds is None:
        raise ValueError(f"{type(pattern).__name__}: no gain_bounds(lo, hi): its least and largest gain over an interval "
                         "of cosines are not known exactly")
    return bounds(lo, hi)


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

    def symbolic_gain_from_cos(self, c):
        return self.g_bar * (ca.cos(0.5 * np.pi * c) ** 2 / (1.0 - c * c + SYMBOLIC_AXIS_EPS))

    def gain_bounds(self, lo, hi):
        """Least and largest gain over the cosines ``[lo, hi]``: even in ``c``, non-increasing in ``|c|``."""
        return _doughnut_bounds(self, lo, hi)


@dataclass(frozen=True)
class SinPowerPattern:
    """Generic doughnut ``G = g_bar sin(theta)^n`` (n = 2 is a short dipole)."""

    exponent: float = 2.0
    g_bar: float = 1.0

    def gain_from_cos(self, c):
        c = np.clip(np.asarray(c, dtype=float), -1.0, 1.0)
        return self.g_bar * (1.0 - c * c) ** (0.5 * self.exponent)

    def symbolic_gain_from_cos(self, c):
        return self.g_bar * (1.0 - c * c + SYMBOLIC_AXIS_EPS) ** (0.5 * self.exponent)

    def gain_bounds(self, lo, hi):
        """Least and largest gain over the cosines ``[lo, hi]``: even in ``c``, non-increasing in ``|c|``."""
        return _doughnut_bounds(self, lo, hi)


@dataclass(frozen=True)
class IsotropicPattern:
    """The same gain ``g_bar`` in every direction (e.g. a base station whose antenna the paper does
    not specify)."""

    g_bar: float = 1.0

    def gain_from_cos(self, c):
        return np.full(np.shape(c), self.g_bar, dtype=float)

    def symbolic_gain_from_cos(self, c):
        return self.g_bar

    def gain_bounds(self, lo, hi):
        g = np.full(np.broadcast(np.asarray(lo), np.asarray(hi)).shape, self.g_bar, dtype=float)
        return g, g


@dataclass(frozen=True)
class CosinePattern:
    """Directional (e.g. a jammer's panel or horn): ``G(psi) = g_max max(max(cos psi, 0)^n, back_lobe)``
    with ``psi`` the angle off boresight (the antenna axis). ``g_max = 1, n = 0, back_lobe = 1`` is
    isotropic. Here ``c = cos(psi)``."""

    g_max: float = 1.0
    exponent: float = 0.0
    back_lobe: float = 0.0

    @property
    def g_bar(self) -> float:
        return self.g_max

    def gain_from_cos(self, c):
        c = np.clip(np.asarray(c, dtype=float), -1.0, 1.0)
        return self.g_max * np.maximum(np.maximum(c, 0.0) ** self.exponent, self.back_lobe)

    def symbolic_gain_from_cos(self, c):
        return self.g_max * ca.fmax(ca.fmax(c, 0.0) ** self.exponent, self.back_lobe)

    def gain_bounds(self, lo, hi):
        """Least and largest gain over the cosines ``[lo, hi]``: non-decreasing in ``c``."""
        return self.gain_from_cos(lo), self.gain_from_cos(hi)


@dataclass(frozen=True)
class FlippedPattern:
    """``inner`` mounted along body -z, said as a pattern about body +z: an antenna's gain depends on the cosine ``c``
    of the angle between its axis and the direction, and reversing the axis reverses ``c``, so
    ``G(c) = inner.G(-c)``. Every consumer that takes a relay's antenna along body z (the planners' axis references,
    the bounds' axis cones, the NMPC) then honours a downward antenna exactly."""

    inner: AntennaPattern

    @property
    def g_bar(self) -> float:
        return self.inner.g_bar

    def gain_from_cos(self, c):
        return self.inner.gain_from_cos(-np.asarray(c, dtype=float))

    def symbolic_gain_from_cos(self, c):
        return self.inner.symbolic_gain_from_cos(-c)

    def gain_bounds(self, lo, hi):
        """Least and largest gain over the cosines ``[lo, hi]``: the inner pattern's over ``[-hi, -lo]``."""
        return gain_bounds(self.inner, -np.asarray(hi, float), -np.asarray(lo, float))


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

    def symbolic_gain_from_cos(self, c):
        lut = ca.interpolant("pattern", "linear", [list(self.theta_deg)], list(self.gain))
        return lut(ca.acos(ca.fmin(ca.fmax(c, -1.0), 1.0)) * (180.0 / np.pi))

    def gain_bounds(self, lo, hi):
        """Least and largest gain over the cosines ``[lo, hi]``: linear in the angle between nodes, so the
        extremes are at the interval's ends or at a tabulated angle inside it."""
        lo, hi = np.broadcast_arrays(np.clip(np.asarray(lo, float), -1.0, 1.0), np.clip(np.asarray(hi, float), -1.0, 1.0))
        t_lo, t_hi = np.degrees(np.arccos(hi)), np.degrees(np.arccos(lo))  # the angles' interval
        ends = np.stack([np.interp(t_lo, self.theta_deg, self.gain), np.interp(t_hi, self.theta_deg, self.gain)])
        nodes, gains = np.asarray(self.theta_deg, float), np.asarray(self.gain, float)
        inside = (nodes[:, None] >= t_lo.ravel()[None, :]) & (nodes[:, None] <= t_hi.ravel()[None, :])
        g = gains[:, None]
        least = np.minimum(ends.min(axis=0).ravel(), np.where(inside, g, np.inf).min(axis=0)).reshape(lo.shape)
        most = np.maximum(ends.max(axis=0).ravel(), np.where(inside, g, -np.inf).max(axis=0)).reshape(lo.shape)
        return least, most


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
