"""The controller's view of the channel (paper Sec. VI-A, VII): alignment and the generator's surrogate.

The true channel (eq. 5-9) is ``models.radio``. Here: the relay's directional cosines and mutual
alignment (eq. 10-11, the NMPC's terms) and the conservative surrogate the trajectory generator
optimizes (eq. 12-15). Node indices follow the paper: 0 = base station, 1 = relay MRAV-1,
2 = source MRAV-2. Positions m (world), rotations body-to-world, powers W, bandwidth normalized.
Functions marked *dual* also take CasADi symbols.
"""

from __future__ import annotations

import numpy as np

from .antenna import link_direction_cos
from .backend import ops
from .radio import route_capacity


def misalignment(p_i, R_i, p_j):
    """Squared directional cosine ``v_ij = <Delta_ij, R_i e3>^2`` in [0, 1] (eq. 10). *Dual*.

    0 when the link lies in node i's broadside plane (best), 1 along its antenna axis (null).
    """
    c = link_direction_cos(p_i, R_i, p_j)
    return c * c


def mutual_alignment(v_12, v_10):
    """Joint alignment ``(1 - v_12)(1 - v_10)`` of the relay toward MRAV-2 and BS (eq. 11)."""
    return (1.0 - v_12) * (1.0 - v_10)


def reachable_mutual_alignment(relay_positions, axes, p0, p2_path):
    """Largest mutual alignment (eq. 11) over relay ``positions`` ``(P, 3)`` and antenna ``axes``
    ``(K, 3)`` (unit, world), at each MRAV-2 position of ``p2_path`` ``(T, 3)``; BS at ``p0``. ``(T,)``.
    A relay position on the base station or on MRAV-2 has no link direction: it is left out (0 when
    no position is left)."""
    g = np.asarray(relay_positions, float)
    axes = np.asarray(axes, float)

    def cos_to(p):  # directional cosines (P, K) of the links from each relay position toward p (NaN at p itself)
        d = np.asarray(p, float) - g
        with np.errstate(invalid="ignore", divide="ignore"):
            return (d / np.linalg.norm(d, axis=1, keepdims=True)) @ axes.T

    s10 = 1.0 - cos_to(p0) ** 2

    def best(p2) -> float:
        a = s10 * (1.0 - cos_to(p2) ** 2)
        return float(np.max(a)) if not np.isnan(a).any() else float(np.nanmax(a, initial=0.0))

    return np.array([best(p2) for p2 in np.asarray(p2_path, float)])


def spectral_efficiency(gamma):
    """Link spectral efficiency ``log2(1 + Gamma)`` in bit/s/Hz (eq. 8 with B = 1), as the generator's
    surrogate writes it (``log(1 + x)/log 2`` symbolically). *Dual*."""
    return ops(gamma).log2(1.0 + gamma)


def end_to_end_capacity(gamma_21, gamma_10, bandwidth: float = 1.0):
    """Balanced-bandwidth end-to-end capacity of the paper's two hops (eq. 9): ``radio.route_capacity``."""
    return route_capacity([gamma_21, gamma_10], bandwidth)


def surrogate_sinr(p_tx, p_rx, p_jams, jam_powers, *, mu: float, g_bar: float, tx_power: float, noise_power: float,
                   jam_gains=None):
    """Conservative SINR ``Gamma_bar`` with ``H_bar = sqrt(mu) G_bar/d``, ``F_bar_j = sqrt(g_j G_bar)/d_j`` (eq. 12-13),
    the interference of every jammer ``j`` (positions ``p_jams``, powers ``jam_powers``, peak gains ``jam_gains``,
    1 for the paper's isotropic jammer) summed. *Dual*."""
    o = ops(p_tx, p_rx)
    d = p_rx - p_tx
    h_sq = mu * g_bar**2 / o.dot(d, d)
    interference = None
    for k, (pj, PJ) in enumerate(zip(p_jams, jam_powers, strict=True)):
        dj = pj - p_rx
        f_sq = g_bar / o.dot(dj, dj)
        if jam_gains is not None and jam_gains[k] != 1.0:
            f_sq = f_sq * jam_gains[k]
        term = f_sq * PJ
        interference = term if interference is None else interference + term
    return h_sq * tx_power / (noise_power if interference is None else interference + noise_power)  # eq. 5


def inverse_capacity(p1, p2, p0, p_jams, jam_powers, *, mu: float, g_bar: float, tx_power: float, noise_power: float,
                     bandwidth: float = 1.0, jam_gains=None):
    """Trajectory-generator cost ``f(kappa) = (1/B)(1/log2(1+G_21) + 1/log2(1+G_10))`` (eq. 15). *Dual*.

    Built on the conservative surrogate SINRs; ``kappa = (p1, p2)``; ``p0`` is the BS; one entry of
    ``p_jams`` / ``jam_powers`` per jammer. ``network_inverse_capacity`` for the hops (2, 1), (1, 0).
    """
    return network_inverse_capacity([(p2, p1), (p1, p0)], p_jams, jam_powers, mu=mu, g_bar=g_bar, tx_power=tx_power,
                                    noise_power=noise_power, bandwidth=bandwidth, jam_gains=jam_gains)


def network_inverse_capacity(hops, p_jams, jam_powers, *, mu: float, g_bar: float, tx_power: float, noise_power: float,
                             bandwidth: float = 1.0, jam_gains=None):
    """Eq. 15 over every hop of a network: ``f = (1/B) sum_hops 1/log2(1 + Gamma_bar_hop)``, the inverse of
    the network rate (``radio.network_rate``) on the conservative surrogate SINRs (eq. 12-13). ``hops``:
    ``(p_tx, p_rx)`` for every hop of every route, a hop shared by two routes listed once per route (m,
    world). *Dual*."""
    kw = dict(mu=mu, g_bar=g_bar, tx_power=tx_power, noise_power=noise_power, jam_gains=jam_gains)
    total = None
    for p_tx, p_rx in hops:
        term = 1.0 / spectral_efficiency(surrogate_sinr(p_tx, p_rx, p_jams, jam_powers, **kw))
        total = term if total is None else total + term
    if total is None:
        raise ValueError("network_inverse_capacity: no hop given")
    return total / bandwidth
