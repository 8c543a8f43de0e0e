"""Max-min trajectory generator via the inverse-capacity surrogate (paper Sec. VI-A, eq. 14-19).

At every control step the conservative inverse capacity ``f(kappa)``, ``kappa = (p1, p2)``, is
expanded to second order around the latest positions; its minimizer in ``p1`` gives the relay
references ``p_d, v_d, a_d`` (eq. 17-19). The raw Newton step can be metres long, so the NMPC
is fed through a reference governor that moves toward ``p_d`` at a bounded speed. Positions in
m (world), velocities m/s, accelerations m/s^2.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..models.channel import inverse_capacity
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


def _build_expansion(sp: SurrogateParams) -> ca.Function:
    """CasADi function z -> (f, g, vec(H)) by automatic differentiation, ``z = (p1, p2, p0, vec(pJ),
    P_J)`` (pJ 3 x nJ, column-major) and ``g``, ``H`` the gradient and Hessian in ``kappa = (p1, p2)``:
    one packed input and output so that a call through CasADi's buffer interface costs < 1 us."""
    nj = len(sp.jam_gains)
    z = ca.SX.sym("z", 9 + 4 * nj)
    p1, p2, p0 = z[0:3], z[3:6], z[6:9]
    pj, PJ = ca.reshape(z[9:9 + 3 * nj], 3, nj), z[9 + 3 * nj:]
    f = inverse_capacity(
        p1, p2, p0, [pj[:, k] for k in range(nj)], [PJ[k] for k in range(nj)], mu=sp.mu, g_bar=sp.g_bar,
        tx_power=sp.tx_power, noise_power=sp.noise_power, bandwidth=sp.bandwidth, jam_gains=sp.jam_gains,
    )
    H, g = ca.hessian(f, ca.vertcat(p1, p2))
    return ca.Function("surrogate_expansion", [z], [ca.densify(ca.vertcat(f, g, ca.vec(H)))], ["z"], ["fgH"])


class TrajectoryGenerator:
    """Relay reference generator with a reference governor (stateful; one instance per mission)."""

    def __init__(
        self,
        surrogate: SurrogateParams,
        bs_position,
        *,
        governor_speed: float,
        eig_floor: float,
        workspace_min,
        workspace_max,
        max_ref_accel: float = 2.0,
    ):
        self.sp = surrogate
        self.p0 = np.asarray(bs_position, float)
        self.governor_speed = governor_speed
        self.eig_floor = eig_floor
        self.lo, self.hi = np.asarray(workspace_min, float), np.asarray(workspace_max, float)
        self.max_ref_accel = max_ref_accel
        self.function = _build_expansion(surrogate)  # z -> (f, g, vec(H)): what aerorelay codegen writes as C too
        self._call = BufferedCall(self.function)
        self._z = self._call.arg
        self._z[6:9] = self.p0
        self._prev: tuple | None = None  # (kappa_e, f, g, H) of the last expansion
        self.p_ref: np.ndarray | None = None

    def _expand(self, p1, p2, p_jam, jam_power) -> tuple[float, np.ndarray, np.ndarray]:
        """``(f, g (6,), H (6, 6))`` at ``kappa = (p1, p2)`` (one buffered CasADi call)."""
        nj = (len(self._z) - 9) // 4
        pj = np.asarray(p_jam, float).reshape(-1, 3)
        PJ = np.atleast_1d(np.asarray(jam_power, float))
        if pj.shape[0] != nj or PJ.shape != (nj,):
            raise ValueError(f"trajectory generator: {nj} jammer(s) expected, got positions {pj.shape} and powers {PJ.shape}")
        self._z[0:3], self._z[3:6] = p1, p2
        self._z[9:9 + 3 * nj], self._z[9 + 3 * nj:] = pj.ravel(), PJ
        out = self._call()
        return float(out[0]), out[1:7].copy(), out[7:].reshape(6, 6, order="F").copy()

    def expansion(self, p1, p2, p_jam, jam_power):
        """Value, gradient blocks and Hessian blocks of ``f`` at ``kappa = (p1, p2)``; jammers at
        ``p_jam`` ``(nJ, 3)`` (or one ``(3,)``) radiating ``jam_power`` ``(nJ,)`` W."""
        f, g, H = self._expand(p1, p2, p_jam, jam_power)
        return f, g[:3], g[3:], H[:3, :3], H[:3, 3:], H[3:, 3:]

    def _taylor_error(self, p1, p2, f_now: float, p_jam, jam_power) -> float:
        """``|f - f2| / |f|`` at the new ``kappa`` for the previous step's expansion (eq. 20).

        Both sides use the previous step's jammer knowledge, so a change of the cost function
        itself (localization at tau_E, CSI noise on the jammer position) is not counted as
        approximation error.
        """
        if self._prev is None:
            return 0.0
        kappa_e, f_e, g_e, H_e, pj_e, PJ_e = self._prev
        if not np.array_equal(PJ_e, jam_power) or not np.array_equal(pj_e, p_jam):
            f_now = self._expand(p1, p2, pj_e, PJ_e)[0]
        d = np.concatenate([p1, p2]) - kappa_e
        f2 = f_e + g_e @ d + 0.5 * d @ H_e @ d
        return abs(f_now - f2) / abs(f_now)

    def optimum(self, p1, p2, v2, a2, p_jam, jam_power):
        """Eq. 17-19 at the expansion point ``kappa_e = (p1, p2)`` (so ``delta_2 = 0``)."""
        f, g, H = self._expand(p1, p2, p_jam, jam_power)
        if not (np.isfinite(f) and np.all(np.isfinite(g[:3])) and np.all(np.isfinite(H[:3]))):
            raise NonFinite
        err = self._taylor_error(p1, p2, f, p_jam, jam_power)
        self._prev = (np.concatenate([p1, p2]), f, g, H, np.array(p_jam, float), np.array(jam_power, float))
        H11r, reg = regularized(H[:3, :3], self.eig_floor)
        K = np.linalg.solve(H11r, H[:3, 3:])
        p_opt = np.clip(p1 - np.linalg.solve(H11r, g[:3]), self.lo, self.hi)
        return p_opt, -K @ v2, -K @ a2, err, reg

    def update(self, dt: float, p1, p2, v2, a2, p_jam, jam_power) -> Reference:
        """One generator step of length ``dt`` s from the relay position ``p1`` and MRAV-2's state.
        A non-finite expansion (a degenerate geometry) holds the last reference instead (logged)."""
        p1, p2, v2, a2 = (np.asarray(a, float) for a in (p1, p2, v2, a2))
        try:
            p_opt, v_d, a_d, err, reg = self.optimum(p1, p2, v2, a2, np.asarray(p_jam, float), np.asarray(jam_power, float))
        except NonFinite:
            log.warning("trajectory generator: non-finite surrogate at p1 = %s; holding the last reference", np.round(p1, 2))
            hold = self.p_ref.copy() if self.p_ref is not None else p1.copy()
            self.p_ref = hold
            return Reference(p_opt=hold, p_ref=hold.copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))
        if self.p_ref is None:
            self.p_ref = p1.copy()
        self.p_ref, v_ref, a_ref = governed(self.p_ref, p_opt, v_d, a_d, dt, self.governor_speed, self.max_ref_accel)
        return Reference(p_opt=p_opt, p_ref=self.p_ref.copy(), v_ref=v_ref, a_ref=a_ref, taylor_rel_err=err, regularized=reg)

def regularized(H: np.ndarray, eig_floor: float, relative: bool = False) -> tuple[np.ndarray, bool]:
    """Eigenvalue floor: ``H`` made safely positive definite (every eigenvalue at least ``eig_floor``
    times the largest magnitude, or than 1 when that is smaller and not ``relative``; the paper perturbs
    kappa_e instead); whether it had to. ``relative``: scale-free (a cost in s/bit in physical units
    has eigenvalues far below 1)."""
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


class NonFinite(ArithmeticError):
    """The surrogate's expansion is not finite at this geometry."""
