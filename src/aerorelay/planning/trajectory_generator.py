"""Max-min trajectory generator via the inverse-capacity surrogate (paper Sec. VI-A, eq. 14-19), for K relays.

At every control step the conservative inverse network rate ``f(kappa) = (1/B) sum_s sum_{k in route s}
1/log2(1 + Gamma_bar_{s,k})`` (``models.channel.network_inverse_capacity``), ``kappa = (relay positions, source
positions)``, is expanded to second order around the latest positions; its minimizer in the relays' positions gives
every relay's references ``p_d, v_d, a_d`` at once (eq. 17-19). The paper's case is one relay and one source
(``kappa = (p1, p2)``). The raw Newton step can be metres long, so each NMPC is fed through a reference governor that
moves toward ``p_d`` at a bounded speed. Positions in m (world), velocities m/s, accelerations m/s^2.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..models.channel import network_inverse_capacity
from ..models.geometry import clip_norm
from ..models.radio import RadioScene
from ..store.codegen import BufferedCall

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SurrogateParams:
    """Link budget of the surrogate (eq. 12-13): ``mu``, ``g_bar``, powers in W, bandwidth."""

    mu: float
    g_bar: float
    tx_power: float
    noise_power: float
    bandwidth: float = 1.0
    jam_gains: tuple[float, ...] = (1.0,)  # each jammer's peak gain (1: the paper's isotropic jammer)

    @classmethod
    def of_scene(cls, scene: RadioScene, mu: float, g_bar: float) -> SurrogateParams:
        """The surrogate of ``scene``'s link budget with alignment ``mu`` and antenna gain ``g_bar``; each
        jammer at its peak gain (the surrogate's conservative jammer gain)."""
        b = scene.budget
        return cls(mu, g_bar, b.tx_power, b.noise_power, b.bandwidth, tuple(float(j.pattern.g_bar) for j in scene.jammers))


@dataclass(kw_only=True)
class Reference:
    """Output of one planner step (world frame): what the NMPC tracks."""

    p_opt: np.ndarray  # minimizer of the local quadratic model, eq. 17 (clipped to the workspace)
    p_ref: np.ndarray  # governed position reference fed to the NMPC
    v_ref: np.ndarray
    a_ref: np.ndarray
    taylor_rel_err: float = 0.0  # |f - f2| / |f| of the previous step's expansion, at the current kappa
    regularized: bool = False  # H11 needed an eigenvalue floor
    axis: np.ndarray | None = None  # desired antenna (body z) axis, unit, world; None: from a_ref (eq. 20)
    yaw: float = 0.0  # yaw reference psi, rad (the NMPC's yaw term)


def network_hops(routes: Sequence[Sequence[str]]) -> list[tuple[str, str]]:
    """Every hop ``(tx, rx)`` of every route, in route order (a hop on two routes listed twice: each
    source's data crosses it in its own slot)."""
    return [(r[k], r[k + 1]) for r in routes for k in range(len(r) - 1)]


def _build_expansion(sp: SurrogateParams, relays: Sequence[str], sources: Sequence[str], bs: str, bs_position,
                     routes: Sequence[Sequence[str]]) -> ca.Function:
    """CasADi function ``z -> (f, g, vec(H))`` by automatic differentiation, ``z = (relay positions, source
    positions, vec(pJ), P_J)`` (pJ 3 x nJ, column-major) and ``g``, ``H`` the gradient and Hessian in ``kappa =
    (relays, sources)``: one packed input and output, so a call through CasADi's buffer interface costs < 1 us (what
    ``aerorelay codegen`` writes as C too, for one relay and one source)."""
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
    return ca.Function("surrogate_expansion", [z], [ca.densify(ca.vertcat(f, g, ca.vec(H)))], ["z"], ["fgH"])


class TrajectoryGenerator:
    """The paper's generator for K relays (stateful; one instance per mission; K = 1 and one source: the paper's):
    every relay's reference from the surrogate's Newton step in all relay positions jointly (eq. 17-19 with the
    relays' block ``H_rr`` for ``H_11`` and the sources' block ``H_rs`` for ``H_12``), each through its own reference
    governor. A planner (``update(FleetInput) -> {relay: Reference}``); ``axis`` is left to eq. 20 (``rho_d`` from the
    acceleration reference) and the comms-aware NMPC's alignment terms toward each relay's route neighbours.

    ``routes``: ``[source, relay, ..., bs]``, all ending at the one base station at ``bs_position`` (m); ``relays``:
    the relays planned, in ``kappa``'s order; ``governor_speed`` (m/s): one for all or each relay's; ``boxes``: a
    relay's own workspace (min, max), m, where it has one (else ``workspace_min``/``max``). The eigenvalue floor of
    ``H_rr`` (``regularized``): ``relative_floor``, relative to its largest eigenvalue (scale-free: in physical units
    the cost is in s/bit and every eigenvalue far below the paper's floor, which freezes the relays), else the paper's
    (``eig_floor * max(1, |lambda|max)``); in the paper's normalized units the two are the same."""

    def __init__(self, surrogate: SurrogateParams, routes: Sequence[Sequence[str]], relays: Sequence[str], bs_position, *,
                 governor_speed: float | Mapping[str, float], eig_floor: float, workspace_min, workspace_max,
                 relative_floor: bool = True, max_ref_accel: float = 2.0, boxes: Mapping[str, tuple] | None = None):
        self.sp = surrogate
        self.routes = [list(r) for r in routes]
        self.relays = list(relays)
        self.sources = list(dict.fromkeys(r[0] for r in self.routes))
        bs = {r[-1] for r in self.routes}
        if len(bs) != 1:
            raise ValueError(f"TrajectoryGenerator: every route must end at the one base station, got {sorted(bs)}")
        self.p0 = np.asarray(bs_position, float)
        self.eig_floor, self.relative_floor, self.max_ref_accel = eig_floor, relative_floor, max_ref_accel
        self.governor_speed = {n: float(governor_speed[n] if isinstance(governor_speed, Mapping) else governor_speed)
                               for n in self.relays}
        own = boxes or {}
        self.lo = np.array([own.get(n, (workspace_min, workspace_max))[0] for n in self.relays], float)  # (K, 3)
        self.hi = np.array([own.get(n, (workspace_min, workspace_max))[1] for n in self.relays], float)
        self.nj = len(surrogate.jam_gains)
        self.function = _build_expansion(surrogate, self.relays, self.sources, bs.pop(), self.p0, self.routes)
        self._call = BufferedCall(self.function)
        self._prev: tuple | None = None  # (kappa_e, f, g, H, pJ, P_J) of the last expansion
        self.refs: dict[str, np.ndarray] = {}

    @property
    def n_kappa(self) -> int:
        return 3 * (len(self.relays) + len(self.sources))

    def _kappa(self, positions) -> np.ndarray:
        return np.concatenate([np.asarray(positions[n], float) for n in (*self.relays, *self.sources)])

    def _expand(self, kappa: np.ndarray, pj: np.ndarray, PJ: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        nk, nj = self.n_kappa, self.nj
        z = self._call.arg
        z[:nk], z[nk : nk + 3 * nj], z[nk + 3 * nj :] = kappa, pj.ravel(), PJ
        out = self._call()
        return float(out[0]), out[1 : 1 + nk].copy(), out[1 + nk :].reshape(nk, nk, order="F").copy()

    def _jammers(self, p_jam, jam_power) -> tuple[np.ndarray, np.ndarray]:
        pj = np.asarray(p_jam, float).reshape(-1, 3)
        PJ = np.atleast_1d(np.asarray(jam_power, float))
        if pj.shape[0] != self.nj or PJ.shape != (self.nj,):
            raise ValueError(f"trajectory generator: {self.nj} jammer(s) expected, got positions {pj.shape} and powers "
                             f"{PJ.shape}")
        return pj, PJ

    def expansion(self, positions, p_jam, jam_power) -> tuple[float, np.ndarray, np.ndarray]:
        """``(f, g, H)`` of the surrogate at the nodes' ``positions`` (by name, m); ``g``, ``H`` over
        ``kappa = (relays, sources)`` in that order; jammers at ``p_jam`` ``(nJ, 3)`` m, ``jam_power`` ``(nJ,)`` W."""
        return self._expand(self._kappa(positions), *self._jammers(p_jam, jam_power))

    def _taylor_error(self, kappa: np.ndarray, f_now: float, pj: np.ndarray, PJ: np.ndarray) -> float:
        """``|f - f2| / |f|`` at the new ``kappa`` for the previous step's expansion (eq. 20). Both sides use the
        previous step's jammer knowledge, so a change of the cost function itself (localization at tau_E, CSI noise on
        the jammer position) is not counted as approximation error."""
        if self._prev is None:
            return 0.0
        kappa_e, f_e, g_e, H_e, pj_e, PJ_e = self._prev
        if not np.array_equal(PJ_e, PJ) or not np.array_equal(pj_e, pj):
            f_now = self._expand(kappa, pj_e, PJ_e)[0]
        d = kappa - kappa_e
        f2 = f_e + g_e @ d + 0.5 * d @ H_e @ d
        return abs(f_now - f2) / abs(f_now)

    def optimum(self, inp) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, bool] | None:
        """Eq. 17-19 for all relays jointly at the expansion point ``kappa_e`` = the nodes' positions now (so
        ``delta_sources = 0``): ``p_opt`` (clipped to each relay's workspace), ``v_d``, ``a_d``, each ``(K, 3)``, the
        previous expansion's Taylor error here and whether ``H_rr`` needed its floor; None when the expansion is not
        finite (a degenerate geometry). ``inp``: a ``planning.fleet.FleetInput``."""
        pj, PJ = self._jammers(inp.jammer_positions, inp.jammer_powers)
        kappa = self._kappa(inp.positions)
        f, g, H = self._expand(kappa, pj, PJ)
        nr = 3 * len(self.relays)
        if not (np.isfinite(f) and np.all(np.isfinite(g[:nr])) and np.all(np.isfinite(H[:nr]))):
            return None
        err = self._taylor_error(kappa, f, pj, PJ)
        self._prev = (kappa, f, g, H, pj.copy(), PJ.copy())
        Hrr, reg = regularized(H[:nr, :nr], self.eig_floor, relative=self.relative_floor)
        K = np.linalg.solve(Hrr, H[:nr, nr:])
        zero = np.zeros(3)
        v_s = np.concatenate([np.asarray(inp.velocities.get(n, zero), float) for n in self.sources])
        a_s = np.concatenate([np.asarray(inp.accelerations.get(n, zero), float) for n in self.sources])
        p_opt = (kappa[:nr] - np.linalg.solve(Hrr, g[:nr])).reshape(-1, 3)
        return np.clip(p_opt, self.lo, self.hi), (-K @ v_s).reshape(-1, 3), (-K @ a_s).reshape(-1, 3), err, reg

    def update(self, inp) -> dict[str, Reference]:
        """One generator step of length ``inp.dt`` s from what the network knows (``planning.fleet.FleetInput``). A
        non-finite expansion (a degenerate geometry) holds the last references instead (logged)."""
        for n in self.relays:
            self.refs.setdefault(n, np.asarray(inp.positions[n], float).copy())
        opt = self.optimum(inp)
        if opt is None:
            log.warning("trajectory generator: non-finite surrogate at t = %.2f s; holding the last references", inp.t)
            return {n: Reference(p_opt=self.refs[n].copy(), p_ref=self.refs[n].copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))
                    for n in self.relays}
        p_opt, v_d, a_d, err, reg = opt
        out = {}
        for i, n in enumerate(self.relays):
            self.refs[n], v_ref, a_ref = governed(self.refs[n], p_opt[i], v_d[i], a_d[i], inp.dt, self.governor_speed[n],
                                                    self.max_ref_accel)
            out[n] = Reference(p_opt=p_opt[i], p_ref=self.refs[n].copy(), v_ref=v_ref, a_ref=a_ref, taylor_rel_err=err,
                               regularized=reg)
        return out


def regularized(H: np.ndarray, eig_floor: float, *, relative: bool = True) -> tuple[np.ndarray, bool]:
    """Eigenvalue floor: ``H`` made safely positive definite (every eigenvalue at least ``eig_floor`` times the largest
    magnitude, ``relative``; or times ``max(1, largest magnitude)``, the paper's; the paper perturbs kappa_e instead);
    whether it had to. Relative is scale-free: a cost in s/bit in physical units has eigenvalues far below 1, where
    the paper's floor of ``eig_floor`` freezes the relays."""
    lam, V = np.linalg.eigh(0.5 * (H + H.T))
    top = float(np.max(np.abs(lam)))
    floor = eig_floor * (top if relative else max(1.0, top))
    if lam.min() >= floor:
        return H, False
    return (V * np.maximum(lam, floor)) @ V.T, True


def governed(p_ref: np.ndarray, p_opt: np.ndarray, v_d: np.ndarray, a_d: np.ndarray, dt: float, speed: float,
             max_accel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference governor: ``p_ref`` (m) moved toward ``p_opt`` by at most ``speed * dt``; the
    velocity reference that step's (m/s) when it is capped, else ``v_d`` capped at ``speed``; ``a_d``
    capped at ``max_accel`` (m/s^2). Returns ``(p_ref, v_ref, a_ref)``."""
    step = p_opt - p_ref
    max_step = speed * dt
    n = np.linalg.norm(step)
    if n > max_step:
        step *= max_step / n
    v_ref = step / dt if n > max_step else clip_norm(v_d, speed)
    return p_ref + step, v_ref, clip_norm(a_d, max_accel)
