"""The true end-to-end capacity over relay poses: positions x antenna axes, vectorized (eq. 5-9).

For one instant (MRAV-2 at ``p2`` with antenna axis ``b2``, the BS at ``p0`` with axis ``b0``,
the jammer at ``pj`` radiating ``jam_power``), ``relay_capacity`` evaluates the end-to-end
capacity for every relay position (``(M, 3)``, m, world) and every relay antenna axis
(``(K, 3)`` unit vectors, world): dipole gains at all four link ends and at the relay's jammer
link, as in ``channel.link_sinr``. A dipole's gain depends on its axis only (not on yaw), so a
relay attitude enters only through its body z axis.
"""

from __future__ import annotations

import numpy as np

from .antenna import AntennaPattern


def axis_cone(max_tilt: float, step: float) -> np.ndarray:
    """Unit axes within ``max_tilt`` rad of vertical: rings every ``step`` rad of tilt (and one at
    ``max_tilt``), azimuths spaced about ``step`` along each ring. ``(K, 3)``; vertical first."""
    tilts = [0.0] + [t for t in np.arange(step, max_tilt, step)] + ([max_tilt] if max_tilt > 1e-9 else [])
    axes = [np.array([0.0, 0.0, 1.0])]
    for tilt in tilts[1:]:
        n = max(6, int(np.ceil(2 * np.pi * np.sin(tilt) / step)))
        az = 2 * np.pi * np.arange(n) / n
        axes.extend(np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.full(n, np.cos(tilt))]))
    return np.array(axes)


def axis_set(azimuths: np.ndarray, limits: np.ndarray, step: float) -> np.ndarray:
    """Unit axes with tilt <= ``limits`` (rad) toward each of ``azimuths`` (rad, increasing over a
    full turn), on tilt rings every ``step`` rad with azimuths about ``step`` apart. Vertical first."""
    axes = [np.array([0.0, 0.0, 1.0])]
    for tilt in np.arange(step, max(float(np.max(limits)), 0.0) + 1e-9, step):
        n = max(6, int(np.ceil(2 * np.pi * np.sin(tilt) / step)))
        az = 2 * np.pi * np.arange(n) / n
        ok = tilt <= np.interp(az, azimuths, limits, period=2 * np.pi) + 1e-9
        axes.extend(np.column_stack([np.sin(tilt) * np.cos(az[ok]), np.sin(tilt) * np.sin(az[ok]), np.full(ok.sum(), np.cos(tilt))]))
    return np.array(axes)


def _unit(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n2 = np.sum(d * d, axis=-1)
    return d / np.sqrt(n2)[..., None], n2


def relay_capacity(positions, axes, *, p2, b2, p0, b0, pj, jam_power: float, pattern: AntennaPattern,
                   tx_power: float, noise_power: float, bandwidth: float = 1.0,
                   pattern_source: AntennaPattern | None = None, pattern_bs: AntennaPattern | None = None) -> np.ndarray:
    """End-to-end capacity ``(M, K)`` for relay positions ``(M, 3)`` and relay axes ``(K, 3)``;
    ``pattern`` is the relay's, MRAV-2's and the BS's default to it."""
    src_pat, bs_pat = pattern_source or pattern, pattern_bs or pattern
    P = np.atleast_2d(np.asarray(positions, float))
    B = np.atleast_2d(np.asarray(axes, float))
    u2, d2sq = _unit(np.asarray(p2, float) - P)  # relay -> MRAV-2
    u0, d0sq = _unit(np.asarray(p0, float) - P)  # relay -> BS
    uj, djsq = _unit(np.asarray(pj, float) - P)  # relay -> jammer
    g_far2 = src_pat.gain_from_cos(-u2 @ np.asarray(b2, float))  # at MRAV-2, toward the relay
    g_far0 = bs_pat.gain_from_cos(-u0 @ np.asarray(b0, float))  # at the BS, toward the relay
    g_r2, g_r0 = pattern.gain_from_cos(u2 @ B.T), pattern.gain_from_cos(u0 @ B.T)  # (M, K) at the relay
    h21 = g_far2[:, None] * g_r2 / d2sq[:, None]  # eq. 6
    h10 = g_far0[:, None] * g_r0 / d0sq[:, None]
    interference1 = jam_power * pattern.gain_from_cos(uj @ B.T) / djsq[:, None] if jam_power > 0 else 0.0  # eq. 7
    # the BS's jammer link does not depend on the relay: F_J0^2 = G(at BS toward jammer) / |pJ - p0|^2
    dj0 = np.asarray(pj, float) - np.asarray(p0, float)
    f0 = float(bs_pat.gain_from_cos(np.dot(dj0, b0) / np.linalg.norm(dj0))) / float(dj0 @ dj0)
    g21 = h21 * tx_power / (interference1 + noise_power)  # eq. 5
    g10 = h10 * tx_power / (f0 * jam_power + noise_power)
    a, b = np.log2(1.0 + g21), np.log2(1.0 + g10)
    s = a + b
    return bandwidth * np.where(s > 0, a * b / np.where(s > 0, s, 1.0), 0.0)  # eq. 9
