"""The paper's max-min trajectory generator over a network (eq. 14-19 with every hop of every route).

The conservative inverse network rate ``f(kappa) = (1/B) sum_s sum_{k in route s} 1/log2(1 +
Gamma_bar_{s,k})`` (``models.channel.network_inverse_capacity``), ``kappa = (relay positions,
source positions)``, is expanded to second order around the latest positions at every control
step; its minimizer in the relays' positions gives every relay's references at once (eq. 17-19
with the relays' block ``H_rr`` for ``H_11`` and the sources' block ``H_rs`` for ``H_12``), each
fed to its NMPC through the reference governor. For one route with one relay it is the paper's
generator (the same numbers: tested), but for the eigenvalue floor of ``H_rr``, relative to its largest
eigenvalue here (scale-free: in physical units the cost is in s/bit and every eigenvalue far below the
paper's absolute floor of 1, which froze the relays). Positions m (world), velocities m/s,
accelerations m/s^2.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import casadi as ca
import numpy as np

from ..models.channel import network_inverse_capacity
from ..store.codegen import BufferedCall
from .fleet import FleetInput
from .trajectory_generator import Reference, SurrogateParams, governed, regularized

log = logging.getLogger(__name__)


def network_hops(routes: Sequence[Sequence[str]]) -> list[tuple[str, str]]:
    """Every hop ``(tx, rx)`` of every route, in route order (a hop on two routes listed twice: each
    source's data crosses it in its own slot)."""
    return [(r[k], r[k + 1]) for r in routes for k in range(len(r) - 1)]


def _build_expansion(sp: SurrogateParams, relays: Sequence[str], sources: Sequence[str], bs: str, bs_position,
                     routes: Sequence[Sequence[str]]) -> ca.Function:
    """CasADi function ``z -> (f, g, vec(H))`` with ``z = (relay positions, source positions, vec(pJ),
    P_J)`` and ``g``, ``H`` in ``kappa = (relays, sources)`` (one packed input and output)."""
    nk, nj = 3 * (len(relays) + len(sources)), len(sp.jam_gains)
    z = ca.SX.sym("z", nk + 4 * nj)
    kappa = z[:nk]
    names = [*relays, *sources]
    at = {n: kappa[3 * i : 3 * i + 3] for i, n in enumerate(names)} | {bs: ca.DM(np.asarray(bs_position, float))}
    pj, PJ = ca.reshape(z[nk : nk + 3 * nj], 3, nj), z[nk + 3 * nj :]
    f = network_inverse_capacity([(at[tx], at[rx]) for tx, rx in network_hops(routes)], [pj[:, k] for k in range(nj)],
                                 [PJ[k] for k in range(nj)], mu=sp.mu, g_bar=sp.g_bar, tx_power=sp.tx_power,
                                 noise_power=sp.noise_power, bandwidth=sp.bandwidth, jam_gains=sp.jam_gains)
    H, g = ca.hessian(f, kappa)
    return ca.Function("network_surrogate_expansion", [z], [ca.densify(ca.vertcat(f, g, ca.vec(H)))], ["z"], ["fgH"])


class NetworkGenerator:
    """Every relay's reference from the surrogate's Newton step in all relay positions jointly, each
    through its own reference governor (stateful; one instance per mission). A fleet planner
    (``update(FleetInput) -> {relay: Reference}``); ``axis`` is left to eq. 20 (``rho_d`` from the
    acceleration reference) and the comms-aware NMPC's alignment terms toward each relay's route
    neighbours."""

    def __init__(self, surrogate: SurrogateParams, routes: Sequence[Sequence[str]], relays: Sequence[str], bs_position, *,
                 governor_speed: float | Mapping[str, float], eig_floor: float, workspace_min, workspace_max, max_ref_accel: float = 2.0,
                 boxes: Mapping[str, tuple] | None = None):
        """``boxes``: a relay's own workspace (min, max), m, where it has one (else ``workspace_min``/``max``)."""
        self.routes = [list(r) for r in routes]
        self.relays = list(relays)
        self.sources = list(dict.fromkeys(r[0] for r in self.routes))
        bs = {r[-1] for r in self.routes}
        if len(bs) != 1:
            raise ValueError(f"NetworkGenerator: every route must end at the one base station, got {sorted(bs)}")
        self.governor_speed, self.eig_floor, self.max_ref_accel = governor_speed, eig_floor, max_ref_accel
        own = boxes or {}
        self.lo = np.array([own.get(n, (workspace_min, workspace_max))[0] for n in self.relays], float)  # (K, 3)
        self.hi = np.array([own.get(n, (workspace_min, workspace_max))[1] for n in self.relays], float)
        self.nj = len(surrogate.jam_gains)
        self._call = BufferedCall(_build_expansion(surrogate, self.relays, self.sources, bs.pop(), bs_position, self.routes))
        self.refs: dict[str, np.ndarray] = {}

    @property
    def n_kappa(self) -> int:
        return 3 * (len(self.relays) + len(self.sources))

    def expansion(self, positions, p_jam, jam_power) -> tuple[float, np.ndarray, np.ndarray]:
        """``(f, g, H)`` of the surrogate at the nodes' ``positions`` (by name, m); ``g``, ``H`` over
        ``kappa = (relays, sources)`` in that order; jammers at ``p_jam`` ``(nJ, 3)`` m, ``jam_power`` ``(nJ,)`` W."""
        nk, nj = self.n_kappa, self.nj
        pj = np.asarray(p_jam, float).reshape(-1, 3)
        PJ = np.atleast_1d(np.asarray(jam_power, float))
        if pj.shape[0] != nj or PJ.shape != (nj,):
            raise ValueError(f"network generator: {nj} jammer(s) expected, got positions {pj.shape} and powers {PJ.shape}")
        z = self._call.arg
        z[:nk] = np.concatenate([np.asarray(positions[n], float) for n in (*self.relays, *self.sources)])
        z[nk : nk + 3 * nj], z[nk + 3 * nj :] = pj.ravel(), PJ
        out = self._call()
        return float(out[0]), out[1 : 1 + nk].copy(), out[1 + nk :].reshape(nk, nk, order="F").copy()

    def optimum(self, inp: FleetInput) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Eq. 17-19 for all relays jointly: ``p_opt`` (clipped to the workspace), ``v_d``, ``a_d``, each
        ``(K, 3)``; None when the expansion is not finite (a degenerate geometry)."""
        f, g, H = self.expansion(inp.positions, inp.jammer_positions, inp.jammer_powers)
        nr = 3 * len(self.relays)
        if not (np.isfinite(f) and np.all(np.isfinite(g[:nr])) and np.all(np.isfinite(H[:nr]))):
            return None
        Hrr, _ = regularized(H[:nr, :nr], self.eig_floor, relative=True)
        K = np.linalg.solve(Hrr, H[:nr, nr:])
        p_r = np.concatenate([np.asarray(inp.positions[n], float) for n in self.relays])
        zero = np.zeros(3)
        v_s = np.concatenate([np.asarray(inp.velocities.get(n, zero), float) for n in self.sources])
        a_s = np.concatenate([np.asarray(inp.accelerations.get(n, zero), float) for n in self.sources])
        p_opt = (p_r - np.linalg.solve(Hrr, g[:nr])).reshape(-1, 3)
        return np.clip(p_opt, self.lo, self.hi), (-K @ v_s).reshape(-1, 3), (-K @ a_s).reshape(-1, 3)

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        for n in self.relays:
            self.refs.setdefault(n, np.asarray(inp.positions[n], float).copy())
        opt = self.optimum(inp)
        if opt is None:
            log.warning("network generator: non-finite surrogate at t = %.2f s; holding the last references", inp.t)
            return {n: Reference(p_opt=self.refs[n].copy(), p_ref=self.refs[n].copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))
                    for n in self.relays}
        out = {}
        for i, n in enumerate(self.relays):
            p_opt, v_d, a_d = opt[0][i], opt[1][i], opt[2][i]
            self.refs[n], v_ref, a_ref = governed(self.refs[n], p_opt, v_d, a_d, inp.dt,
                                                    self.governor_speed[n] if isinstance(self.governor_speed, Mapping)
                                                    else self.governor_speed, self.max_ref_accel)
            out[n] = Reference(p_opt=p_opt, p_ref=self.refs[n].copy(), v_ref=v_ref, a_ref=a_ref)
        return out
