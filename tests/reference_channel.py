"""An independent reference of the paper's channel (eq. 5-9), written from the paper's formulas with
rotation matrices and elevation angles (``antenna.link_direction_cos``), not with ``models.radio``:
the tests cross-check the radio scene against it."""

from __future__ import annotations

import numpy as np

from aerorelay.models.antenna import DipolePattern, link_direction_cos

DIPOLE = DipolePattern()


def legitimate_gain_sq(p_tx, R_tx, p_rx, R_rx, pattern=DIPOLE, pattern_rx=None):
    """``H_ij^2 = G(th_D) G(th_A) / |p_j - p_i|^2`` (eq. 6), antennas along both body z axes."""
    p_tx, p_rx = np.asarray(p_tx, float), np.asarray(p_rx, float)
    d = p_rx - p_tx
    g_dep = pattern.gain_from_cos(link_direction_cos(p_tx, R_tx, p_rx))
    g_arr = (pattern_rx or pattern).gain_from_cos(link_direction_cos(p_rx, R_rx, p_tx))
    return g_dep * g_arr / np.sum(d * d, axis=-1)


def jammer_gain_sq(p_jam, p_rx, R_rx, pattern=DIPOLE):
    """``F_Jj^2 = G(th_A,J) / |p_J - p_j|^2`` (eq. 7): isotropic jammer."""
    p_jam, p_rx = np.asarray(p_jam, float), np.asarray(p_rx, float)
    d = p_jam - p_rx
    return pattern.gain_from_cos(link_direction_cos(p_rx, R_rx, p_jam)) / np.sum(d * d, axis=-1)


def link_sinr(p_tx, R_tx, p_rx, R_rx, p_jam, *, tx_power, jam_power, noise_power, pattern=DIPOLE, pattern_rx=None):
    """``Gamma = H^2 P_U / (F^2 P_J + sigma^2)`` (eq. 5) with an isotropic jammer at ``p_jam``."""
    h_sq = legitimate_gain_sq(p_tx, R_tx, p_rx, R_rx, pattern, pattern_rx)
    f_sq = jammer_gain_sq(p_jam, p_rx, R_rx, pattern_rx or pattern) if jam_power > 0 else 0.0
    return h_sq * tx_power / (f_sq * jam_power + noise_power)


def end_to_end_capacity(g21, g10, bandwidth=1.0):
    """``C = B a b / (a + b)`` (eq. 9)."""
    a, b = np.log2(1.0 + np.asarray(g21, float)), np.log2(1.0 + np.asarray(g10, float))
    s = a + b
    return bandwidth * np.where(s > 0, a * b / np.where(s > 0, s, 1.0), 0.0)
