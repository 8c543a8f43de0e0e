"""Bounds of a link's geometry over a box of displacements: what a certified bound needs to hold for
every position in a grid cell, not only at its centre (``planning.network_bound``).

A link from ``a`` to ``b`` with ``a`` anywhere in one box and ``b`` anywhere in another has its
displacement ``d = b - a`` anywhere in the box ``[d_lo, d_hi]`` (componentwise: the first box's
corners subtracted from the second's). Over such a box:

- ``distance_range``: the least and largest ``|d|`` (m), exact (the nearest and farthest points of an
  axis-aligned box);
- ``elevation_range``: the least and largest ``sin e = d_z / |d|``, exact: ``d_z / sqrt(h^2 + d_z^2)``
  grows with ``d_z`` and, for ``d_z > 0``, falls with the horizontal distance ``h`` (rises for ``d_z < 0``),
  and ``h`` ranges over ``[h_min, h_max]`` independently of ``d_z`` on a box (a box holding the origin, a
  link of zero length, is given every direction, ``[-1, 1]``);
- ``axis_cos_range``: an interval holding every ``cos`` of the angle between ``d`` and a fixed unit
  ``axis``: the box lies in the cone of half-angle ``asin(rho / |c|)`` about its centre ``c`` (``rho`` its
  half-diagonal), so the angle to the axis is within that of the centre's (``[-1, 1]`` when the box
  holds the origin's ball of ``rho``);
- ``cone_cos_range``: the cosines a link at elevations ``[e_lo, e_hi]`` makes with an antenna axis tilted
  up to ``tilt`` from vertical at any yaw, ``[sin(e_lo - tilt), sin(e_hi + tilt)]`` (``u . a = sin e cos t +
  cos e sin t cos(dpsi)`` spans ``[sin(e - tilt), sin(e + tilt)]`` for one ``e``), angles clipped to
  ``[-pi/2, pi/2]``.
"""

from __future__ import annotations

import numpy as np


def _nearest_farthest(d_lo: np.ndarray, d_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, the least and largest ``|d_i|`` over the boxes ``[d_lo, d_hi]`` ``(..., 3)``."""
    nearest = np.where((d_lo <= 0.0) & (d_hi >= 0.0), 0.0, np.minimum(np.abs(d_lo), np.abs(d_hi)))
    return nearest, np.maximum(np.abs(d_lo), np.abs(d_hi))


def distance_range(d_lo, d_hi) -> tuple[np.ndarray, np.ndarray]:
    """The least and largest ``|d|`` (m) over the boxes ``[d_lo, d_hi]`` ``(..., 3)``."""
    nearest, farthest = _nearest_farthest(np.asarray(d_lo, float), np.asarray(d_hi, float))
    return np.linalg.norm(nearest, axis=-1), np.linalg.norm(farthest, axis=-1)


def _sin_elevation(h, z):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((h == 0.0) & (z == 0.0), 0.0, z / np.hypot(h, z))


def elevation_range(d_lo, d_hi) -> tuple[np.ndarray, np.ndarray]:
    """The least and largest ``sin e = d_z / |d|`` over the boxes ``[d_lo, d_hi]`` ``(..., 3)``; a box
    holding the origin spans ``[-1, 1]`` (every direction)."""
    d_lo, d_hi = np.asarray(d_lo, float), np.asarray(d_hi, float)
    return _elevation(d_lo, d_hi, *_nearest_farthest(d_lo, d_hi))


def link_ranges(d_lo, d_hi) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``distance_range`` and ``elevation_range`` of the boxes ``[d_lo, d_hi]`` at once (the nearest and farthest
    points found once): least and largest ``|d|`` (m), least and largest ``sin e``. The reverse link's (``-d``)
    sines are ``-sin_hi, -sin_lo``."""
    d_lo, d_hi = np.asarray(d_lo, float), np.asarray(d_hi, float)
    nearest, farthest = _nearest_farthest(d_lo, d_hi)
    return (np.linalg.norm(nearest, axis=-1), np.linalg.norm(farthest, axis=-1),
            *_elevation(d_lo, d_hi, nearest, farthest))


def _elevation(d_lo, d_hi, nearest, farthest) -> tuple[np.ndarray, np.ndarray]:
    h_min, h_max = np.hypot(nearest[..., 0], nearest[..., 1]), np.hypot(farthest[..., 0], farthest[..., 1])
    z_lo, z_hi = d_lo[..., 2], d_hi[..., 2]
    # largest: the highest z with the nearest horizontal distance when it is >= 0, the farthest when below (the
    # distance chosen first, one sine computed)
    top = _sin_elevation(np.where(z_hi >= 0.0, h_min, h_max), z_hi)
    bottom = _sin_elevation(np.where(z_lo <= 0.0, h_min, h_max), z_lo)
    holds_origin = np.all(nearest == 0.0, axis=-1)  # every axis's nearest 0: the box straddles the origin
    top = np.where(holds_origin | ((h_min == 0.0) & (z_hi > 0.0)), 1.0, top)
    bottom = np.where(holds_origin | ((h_min == 0.0) & (z_lo < 0.0)), -1.0, bottom)
    return bottom, top


def axis_cos_range(d_lo, d_hi, axis) -> tuple[np.ndarray, np.ndarray]:
    """An interval holding ``cos`` of the angle between every ``d`` of the boxes ``[d_lo, d_hi]`` and the
    unit ``axis`` (``(3,)`` or broadcast ``(..., 3)``): the centre's angle widened by the box's angular radius."""
    d_lo, d_hi = np.asarray(d_lo, float), np.asarray(d_hi, float)
    centre, half = 0.5 * (d_lo + d_hi), 0.5 * (d_hi - d_lo)
    rho, dist = np.linalg.norm(half, axis=-1), np.linalg.norm(centre, axis=-1)
    a = np.asarray(axis, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        theta = np.arccos(np.clip(np.einsum("...i,...i->...", centre, a) / dist, -1.0, 1.0))
        alpha = np.arcsin(np.clip(rho / dist, 0.0, 1.0))
    wide = ~(dist > rho)  # the box reaches the origin's ball: every direction
    lo = np.where(wide, -1.0, np.cos(np.minimum(np.pi, theta + alpha)))
    hi = np.where(wide, 1.0, np.cos(np.maximum(0.0, theta - alpha)))
    return lo, hi


def cone_cos_range(sin_lo, sin_hi, tilt: float) -> tuple[np.ndarray, np.ndarray]:
    """The cosines a link at elevations with sines in ``[sin_lo, sin_hi]`` makes with an axis tilted at most
    ``tilt`` (rad) from vertical, any yaw."""
    e_lo, e_hi = np.arcsin(np.clip(sin_lo, -1.0, 1.0)), np.arcsin(np.clip(sin_hi, -1.0, 1.0))
    return (np.sin(np.clip(e_lo - tilt, -np.pi / 2, np.pi / 2)), np.sin(np.clip(e_hi + tilt, -np.pi / 2, np.pi / 2)))
