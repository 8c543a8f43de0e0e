"""RF channel of the relay network (paper Sec. V-B, VI-A).

Node indices follow the paper: 0 = ground base station (BS), 1 = relay MRAV-1, 2 = source
MRAV-2, J = jammer. Positions in m (world frame), rotations body-to-world, powers in W,
bandwidth normalized (B = 1 gives capacities in bit/s/Hz). Every node carries a dipole along
its body z; the jammer radiates isotropically. numpy inputs may be batched ``(..., 3)`` /
``(..., 3, 3)``; functions marked *dual* also take CasADi symbols.
"""

from __future__ import annotations

import numpy as np

from .antenna import AntennaPattern, DipolePattern, link_direction_cos
from .backend import ops

DIPOLE = DipolePattern()


def misalignment(p_i, R_i, p_j):
    """Squared directional cosine ``v_ij = <Delta_ij, R_i e3>^2`` in [0, 1] (eq. 10). *Dual*.

    0 when the link lies in node i's broadside plane (best), 1 along its antenna axis (null).
    """
    c = link_direction_cos(p_i, R_i, p_j)
    return c * c


def mutual_alignment(v_12, v_10):
    """Joint alignment ``(1 - v_12)(1 - v_10)`` of the relay toward MRAV-2 and BS (eq. 11)."""
    return (1.0 - v_12) * (1.0 - v_10)


def legitimate_gain_sq(p_tx, R_tx, p_rx, R_rx, pattern: AntennaPattern = DIPOLE, pattern_rx: AntennaPattern | None = None):
    """``H_ij^2 = G(th_D) G(th_A) / |p_j - p_i|^2`` (eq. 6), antennas along both body z axes
    (``pattern`` at the transmitter, ``pattern_rx`` at the receiver, default the same)."""
    d = np.asarray(p_rx, float) - np.asarray(p_tx, float)
    g_dep = pattern.gain_from_cos(link_direction_cos(np.asarray(p_tx, float), R_tx, np.asarray(p_rx, float)))
    g_arr = (pattern_rx or pattern).gain_from_cos(link_direction_cos(np.asarray(p_rx, float), R_rx, np.asarray(p_tx, float)))
    return g_dep * g_arr / np.sum(d * d, axis=-1)


def jammer_gain_sq(p_jam, p_rx, R_rx, pattern: AntennaPattern = DIPOLE):
    """``F_Jj^2 = G(th_A,J) / |p_J - p_j|^2`` (eq. 7): isotropic jammer, dipole receiver."""
    d = np.asarray(p_jam, float) - np.asarray(p_rx, float)
    g_arr = pattern.gain_from_cos(link_direction_cos(np.asarray(p_rx, float), R_rx, np.asarray(p_jam, float)))
    return g_arr / np.sum(d * d, axis=-1)


def sinr(h_sq, f_sq, *, tx_power: float, jam_power: float, noise_power: float):
    """``Gamma = H^2 P_U / (F^2 P_J + sigma^2)`` (eq. 5). *Dual*."""
    return h_sq * tx_power / (f_sq * jam_power + noise_power)


def link_sinr(
    p_tx,
    R_tx,
    p_rx,
    R_rx,
    p_jam,
    *,
    tx_power: float,
    jam_power: float,
    noise_power: float,
    pattern: AntennaPattern = DIPOLE,
    pattern_rx: AntennaPattern | None = None,
):
    """SINR of the link ``tx -> rx`` with real antenna gains (eq. 5-7): ``pattern`` at the
    transmitter, ``pattern_rx`` (default the same) at the receiver, for both of its links.

    Dipoles lie along each node's body z (rotation matrices ``R_tx``, ``R_rx``, body-to-world);
    the jammer at ``p_jam`` is isotropic; ``jam_power = 0`` means no jammer. Vectorized.
    """
    h_sq = legitimate_gain_sq(p_tx, R_tx, p_rx, R_rx, pattern, pattern_rx)
    f_sq = jammer_gain_sq(p_jam, p_rx, R_rx, pattern_rx or pattern) if jam_power > 0 else 0.0
    return sinr(h_sq, f_sq, tx_power=tx_power, jam_power=jam_power, noise_power=noise_power)


def spectral_efficiency(gamma):
    """Link spectral efficiency ``log2(1 + Gamma)`` in bit/s/Hz (eq. 8 with B = 1). *Dual*."""
    return ops(gamma).log2(1.0 + gamma)


def end_to_end_capacity(gamma_21, gamma_10, bandwidth: float = 1.0):
    """Balanced-bandwidth end-to-end capacity ``C = B a b / (a + b)`` (eq. 9).

    ``a = log2(1 + Gamma_21)``, ``b = log2(1 + Gamma_10)``. Zero when either link is dead.
    Vectorized over numpy arrays.
    """
    a = np.log2(1.0 + np.asarray(gamma_21, dtype=float))
    b = np.log2(1.0 + np.asarray(gamma_10, dtype=float))
    s = a + b
    return bandwidth * np.where(s > 0, a * b / np.where(s > 0, s, 1.0), 0.0)


def surrogate_sinr(p_tx, p_rx, p_jam, *, mu: float, g_bar: float, tx_power: float, jam_power: float, noise_power: float):
    """Conservative SINR ``Gamma_bar`` with ``H_bar = sqrt(mu) G_bar/d``, ``F_bar = sqrt(G_bar)/d_J`` (eq. 12-13). *Dual*."""
    o = ops(p_tx, p_rx, p_jam)
    d = p_rx - p_tx
    dj = p_jam - p_rx
    h_sq = mu * g_bar**2 / o.dot(d, d)
    f_sq = g_bar / o.dot(dj, dj)
    return sinr(h_sq, f_sq, tx_power=tx_power, jam_power=jam_power, noise_power=noise_power)


def inverse_capacity(p1, p2, p0, p_jam, *, mu: float, g_bar: float, tx_power: float, jam_power, noise_power: float,
                     bandwidth: float = 1.0):
    """Trajectory-generator cost ``f(kappa) = (1/B)(1/log2(1+G_21) + 1/log2(1+G_10))`` (eq. 15). *Dual*.

    Built on the conservative surrogate SINRs; ``kappa = (p1, p2)``; ``p0`` is the BS.
    """
    kw = dict(mu=mu, g_bar=g_bar, tx_power=tx_power, jam_power=jam_power, noise_power=noise_power)
    g21 = surrogate_sinr(p2, p1, p_jam, **kw)
    g10 = surrogate_sinr(p1, p0, p_jam, **kw)
    return (1.0 / spectral_efficiency(g21) + 1.0 / spectral_efficiency(g10)) / bandwidth
