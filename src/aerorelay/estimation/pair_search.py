"""Joint search for two jammers over the estimator's grid cells, their powers profiled out.

The grid filter (``jammer_estimator.py``) finds jammers one after the other, each in what the
earlier ones leave as estimated when each measurement came in; Gauss-Newton then holds whatever
mode it starts in. Two jammers whose contributions overlap can leave both in a wrong, mutually
compensating mode (measured: 10-15 m off at a reported std below 1 m, with the base station's
readings making both knowable). This search scores every pair of cells on the window at once.

For cells ``a, b`` with gains ``g_a, g_b`` ``(M,)`` to the window's rows, the excess power ``e``
(W: reading minus noise minus the other jammers) is fitted as ``P_a g_a + P_b g_b`` by weighted
least squares (relative errors, weights ``w``); the fit's drop of ``0.5 sum w e^2`` is

    gain(a, b) = 0.5 [b_a b_b] S^-1 [b_a b_b]^T,  S = [[S_aa, S_ab], [S_ab, S_bb]],
    S_ab = sum w g_a g_b,  b_a = sum w g_a e

when both powers are positive, else the better cell alone (``0.5 b_a^2 / S_aa`` for ``b_a > 0``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_DEGENERATE = 1e-9  # a pair whose gain vectors are this close to parallel (1 - cos^2) is scored as one cell


@dataclass(frozen=True)
class PairFit:
    """The best pair: cell indices ``a, b``, their powers (W) and the weighted fit's drop ``gain``."""

    a: int
    b: int
    power_a: float
    power_b: float
    gain: float


def best_pair(gains: np.ndarray, weights: np.ndarray, excess: np.ndarray, keep: int | None = None) -> PairFit:
    """The pair of cells that best explains ``excess`` ``(M,)`` (W) with gains ``gains`` ``(K, M)`` and
    row weights ``weights`` ``(M,)`` (1/W^2). ``keep``: score pairs among the ``keep`` cells with the
    best single-cell fit only (``K^2 M`` work otherwise)."""
    if gains.ndim != 2 or gains.shape[1] != excess.size or weights.size != excess.size:
        raise ValueError(f"best_pair: gains {gains.shape}, weights {weights.shape} and excess {excess.shape} disagree")
    gw = gains * weights
    b = gw @ excess
    d = np.einsum("km,km->k", gw, gains)
    single = np.where((b > 0) & (d > 0), 0.5 * b * b / np.where(d > 0, d, 1.0), 0.0)
    cells = np.arange(gains.shape[0]) if keep is None or keep >= gains.shape[0] else np.argsort(single)[::-1][:keep]
    gw, b, d, single = gw[cells], b[cells], d[cells], single[cells]
    S = gw @ gains[cells].T
    dd = np.outer(d, d)
    det = dd - S * S
    # the powers' numerators (their signs are the powers' where det > 0): P_a = num_a / det
    num_a = d[None, :] * b[:, None]
    num_a -= S * b[None, :]
    num_b = d[:, None] * b[None, :]
    num_b -= S * b[:, None]
    both = (det > _DEGENERATE * dd) & (num_a > 0) & (num_b > 0)
    gain = num_a * b[:, None]
    gain += num_b * b[None, :]
    gain *= 0.5
    gain /= np.where(both, det, 1.0)
    gain = np.where(both, gain, np.maximum(single[:, None], single[None, :]))
    np.fill_diagonal(gain, -np.inf)
    i, k = np.unravel_index(int(np.argmax(gain)), gain.shape)
    if both[i, k]:
        return PairFit(int(cells[i]), int(cells[k]), float(num_a[i, k] / det[i, k]), float(num_b[i, k] / det[i, k]),
                       float(gain[i, k]))
    one, other = (i, k) if single[i] >= single[k] else (k, i)
    power = float(b[one] / d[one]) if single[one] > 0 else 0.0
    return PairFit(int(cells[one]), int(cells[other]), power, 0.0, float(gain[i, k]))
