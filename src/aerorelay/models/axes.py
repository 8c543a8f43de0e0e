"""Relay antenna axes to search: cones of unit axes within a tilt limit (the bound, the capacity planner).

A dipole's gain depends on its axis only (not on yaw), so a relay attitude enters the channel
(``models.radio``) only through its body z axis; these sets sample the axes a platform can hold.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .backend import is_symbolic


def tilted_axes(tilt, azimuth):
    """Unit axes tilted ``tilt`` rad from vertical toward ``azimuth`` rad (world). *Dual*: numpy
    scalars or arrays that broadcast give ``(..., 3)``; CasADi scalars give a ``(3, 1)`` expression."""
    if is_symbolic(tilt, azimuth):
        return ca.vertcat(ca.sin(tilt) * ca.cos(azimuth), ca.sin(tilt) * ca.sin(azimuth), ca.cos(tilt))
    tilt, azimuth = np.broadcast_arrays(np.asarray(tilt, float), np.asarray(azimuth, float))
    return np.stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)], axis=-1)


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


def axis_set(azimuths: np.ndarray, limits: np.ndarray, step: float, boundary: bool = False) -> np.ndarray:
    """Unit axes with tilt <= ``limits`` (rad) toward each of ``azimuths`` (rad, increasing over a
    full turn), on tilt rings every ``step`` rad with azimuths about ``step`` apart. Vertical first.
    ``boundary``: also the axes at the limit itself (azimuths about ``step`` apart along it, where
    it lies beyond the last ring by more than a tenth of ``step``): the strongest holdable tilt
    toward every azimuth, which the rings miss by up to ``step``."""
    axes = [np.array([0.0, 0.0, 1.0])]
    top = max(float(np.max(limits)), 0.0)
    for tilt in np.arange(step, top + 1e-9, step):
        n = max(6, int(np.ceil(2 * np.pi * np.sin(tilt) / step)))
        az = 2 * np.pi * np.arange(n) / n
        ok = tilt <= np.interp(az, azimuths, limits, period=2 * np.pi) + 1e-9
        axes.extend(np.column_stack([np.sin(tilt) * np.cos(az[ok]), np.sin(tilt) * np.sin(az[ok]), np.full(ok.sum(), np.cos(tilt))]))
    if boundary and top > 0.0:
        n = max(6, int(np.ceil(2 * np.pi * np.sin(top) / step)))
        az = 2 * np.pi * np.arange(n) / n
        lim = np.interp(az, azimuths, limits, period=2 * np.pi)
        ok = (lim > 0.0) & (lim - np.floor(lim / step + 1e-9) * step > 0.1 * step)
        tilt = lim[ok]
        axes.extend(np.column_stack([np.sin(tilt) * np.cos(az[ok]), np.sin(tilt) * np.sin(az[ok]), np.cos(tilt)]))
    return np.array(axes)
