"""Communications-aware NMPC solved by real-time iteration (one QP per control step).

Preparation: the OCP of ``ocp.py`` is linearized around the shifted previous solution
(Gauss-Newton Hessian, exact constraint Jacobians) by a function compiled from CasADi-generated C.
Feedback: the structured QP is solved by HPIPM through ``casadi.conic``. A QP failure (status,
NaN) is counted and answered with the shifted previous plan's input, clipped to the bounds.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .codegen import compiled
from .ocp import NP, OcpSpec, ParamIndex, alignment_constraint, discrete_dynamics, stage_residual, terminal_residual

log = logging.getLogger(__name__)
INF = 1e8
HESSIAN_REG = 1e-8


@dataclass
class StepInfo:
    """What one controller step did (times in ms)."""

    u: np.ndarray
    ok: bool
    status: str
    prep_ms: float
    qp_ms: float
    slack_max: float
    qp_iters: int = 0

    @property
    def solve_ms(self) -> float:
        return self.prep_ms + self.qp_ms


def _stage_linearization(spec: OcpSpec) -> ca.Function:
    xa, w, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("w", spec.nw), ca.SX.sym("p", NP)
    z = ca.vertcat(xa, w)
    xn = discrete_dynamics(spec, xa, w)
    r = stage_residual(spec, xa, w, p)
    Jr = ca.jacobian(r, z)
    H = ca.mtimes(Jr.T, Jr)
    g = ca.mtimes(Jr.T, r)
    outs = [xn, ca.jacobian(xn, xa), ca.jacobian(xn, w), H, g]
    if spec.constrained:
        h = alignment_constraint(spec, xa, w, p)
        outs += [h, ca.jacobian(h, z)]
    return ca.Function("stage_lin", [xa, w, p], outs)


def _terminal_linearization(spec: OcpSpec) -> ca.Function:
    xa, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("p", NP)
    r = terminal_residual(spec, xa, p)
    J = ca.jacobian(r, xa)
    return ca.Function("term_lin", [xa, p], [ca.mtimes(J.T, J), ca.mtimes(J.T, r)])


def _pack_mx(X, W):
    """``z = [xa_0; w_0; ...; xa_(N-1); w_(N-1); xa_N]`` from state and control matrices."""
    N = W.shape[1]
    return ca.vertcat(ca.vec(ca.vertcat(X[:, :N], W)), X[:, N])


def pack_plan(X: np.ndarray, W: np.ndarray) -> np.ndarray:
    """numpy twin of ``_pack_mx``: ``z = [xa_0; w_0; ...; xa_N]`` from ``(nx, N+1)`` and ``(nw, N)``."""
    N = W.shape[1]
    return np.concatenate([np.vstack([X[:, :N], W]).T.reshape(-1), X[:, N]])


def absolute_bounds(spec: OcpSpec) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on ``z`` in absolute coordinates: motor speeds and workspace on states k >= 1,
    motor accelerations on inputs, slack ``pi_k >= 0`` for k >= 1 (fixed to 0 at k = 0 and in the
    unconstrained variant). Unbounded entries are +-INF."""
    v, N, nx, nw, nr = spec.vehicle, spec.horizon, spec.nx, spec.nw, spec.vehicle.n_rotors
    lbx, ubx = -INF * np.ones((nx, N + 1)), INF * np.ones((nx, N + 1))
    lbx[0:3, 1:] = np.array(spec.workspace_min)[:, None]
    ubx[0:3, 1:] = np.array(spec.workspace_max)[:, None]
    lbx[12 : 12 + nr, 1:], ubx[12 : 12 + nr, 1:] = v.omega_min, v.omega_max
    lbw, ubw = np.zeros((nw, N)), np.zeros((nw, N))
    lbw[:nr], ubw[:nr] = v.omega_dot_min, v.omega_dot_max
    if spec.constrained:
        ubw[nr, 1:] = INF
    return pack_plan(lbx, lbw), pack_plan(ubx, ubw)


def build_preparation(spec: OcpSpec) -> ca.Function:
    """MX function ``(Xb, Wb, P, xa0) -> (H, g, A, lba, uba, lbx, ubx)``: the QP in the step ``dz``
    around the guess ``(Xb, Wb)``, in HPIPM's stage structure, with the initial state fixed to ``xa0``."""
    N, nx, nw = spec.horizon, spec.nx, spec.nw
    Xb, Wb, P = ca.MX.sym("Xb", nx, N + 1), ca.MX.sym("Wb", nw, N), ca.MX.sym("P", NP, N + 1)
    xa0 = ca.MX.sym("xa0", nx)
    outs = _stage_linearization(spec).map(N, "serial")(Xb[:, :N], Wb, P[:, :N])
    xn, Ak, Bk, Hk, gk = outs[:5]
    HN, gN = _terminal_linearization(spec)(Xb[:, N], P[:, N])
    nz = spec.nz
    blocks_H, blocks_g, rows, lb, ub = [], [], [], [], []
    negI = -ca.DM.eye(nx)
    for k in range(N):
        off = k * (nx + nw)
        blocks_H.append(Hk[:, k * (nx + nw) : (k + 1) * (nx + nw)])
        blocks_g.append(gk[:, k])
        dyn = ca.horzcat(Ak[:, k * nx : (k + 1) * nx], Bk[:, k * nw : (k + 1) * nw], negI)
        rows.append(ca.horzcat(ca.MX(nx, off), dyn, ca.MX(nx, nz - off - dyn.shape[1])))
        gap = -(xn[:, k] - Xb[:, k + 1])
        lb.append(gap)
        ub.append(gap)
        if spec.constrained and k >= 1:
            hk, Jh = outs[5][:, k], outs[6][:, k * (nx + nw) : (k + 1) * (nx + nw)]
            rows.append(ca.horzcat(ca.MX(1, off), Jh, ca.MX(1, nz - off - (nx + nw))))
            lb.append(P[ParamIndex.mu, k] - hk)
            ub.append(ca.MX(ca.DM(INF)))
    H = ca.diagcat(*blocks_H, HN) + HESSIAN_REG * ca.DM.eye(nz)
    g = ca.vertcat(*blocks_g, gN)
    A = ca.vertcat(*rows)
    lbz, ubz = absolute_bounds(spec)
    zb = _pack_mx(Xb, Wb)
    x0_step = xa0 - Xb[:, 0]
    lbx = ca.vertcat(x0_step, ca.DM(lbz[nx:]) - zb[nx:])
    ubx = ca.vertcat(x0_step, ca.DM(ubz[nx:]) - zb[nx:])
    return ca.Function("nmpc_prep", [Xb, Wb, P, xa0], [H, g, A, ca.vertcat(*lb), ca.vertcat(*ub), lbx, ubx],
                       ["Xb", "Wb", "P", "xa0"], ["H", "g", "A", "lba", "uba", "lbx", "ubx"])


def build_update(spec: OcpSpec) -> ca.Function:
    """MX function ``(Xb, Wb, dz) -> (X_shift, W_shift, u0, slack_max, check)``: apply the QP step,
    shift the plan one stage for the next guess, read the first input; ``check`` is NaN when ``dz`` is."""
    N, nx, nw, nr = spec.horizon, spec.nx, spec.nw, spec.vehicle.n_rotors
    Xb, Wb, dz = ca.MX.sym("Xb", nx, N + 1), ca.MX.sym("Wb", nw, N), ca.MX.sym("dz", spec.nz)
    body = ca.reshape(dz[: N * (nx + nw)], nx + nw, N)
    X = Xb + ca.horzcat(body[:nx, :], dz[N * (nx + nw) :])
    W = Wb + body[nx:, :]
    Xs = ca.horzcat(X[:, 1:], X[:, N])
    Ws = ca.horzcat(W[:, 1:], W[:, N - 1])
    slack = ca.mmax(W[nr, 1:]) if N > 1 else ca.MX(0)
    return ca.Function("nmpc_update", [Xb, Wb, dz], [X, W, Xs, Ws, W[:nr, 0], slack, ca.sum1(dz)],
                       ["Xb", "Wb", "dz"], ["X", "W", "Xs", "Ws", "u0", "slack", "check"])


@dataclass
class NmpcSettings:
    qp_solver: str = "hpipm"
    # res_m_max 1e-4 (complementarity) + warm start: 4.6 instead of 8.9 IPM iterations per step on
    # the nominal mission, same capacities to 3 digits (measured, see the issue note / README)
    qp_options: dict = field(
        default_factory=lambda: {"hpipm": {"mode": "speed_abs", "iter_max": 50, "res_m_max": 1e-4, "warm_start": 1}}
    )
    compile: bool = True


class NMPC:
    """Real-time-iteration NMPC. Call ``step(x, u_prev, P)`` once per control period.

    ``x`` is the plant state ``(p, eta, v, omega, Omega)``, ``u_prev`` the last applied input
    (Hz/s), ``P`` the ``(NP, N+1)`` parameter matrix (see ``ocp.ParamIndex``; the ``u_prev``
    rows are filled here). The plan is kept as CasADi matrices between steps so that each step
    is three compiled calls (prepare, QP, update) with little Python in between.
    """

    def __init__(self, spec: OcpSpec, settings: NmpcSettings | None = None):
        self.spec = spec
        self.settings = settings or NmpcSettings()
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        prep = build_preparation(spec)
        self.prep = compiled(prep, spec.key()) if self.settings.compile else prep
        self.update = build_update(spec)
        sp = {"h": prep.sparsity_out("H"), "a": prep.sparsity_out("A")}
        ng = [0] + [1 if spec.constrained else 0] * (N - 1) + [0]
        opts = dict(self.settings.qp_options)
        if self.settings.qp_solver == "hpipm":
            opts.update({"N": N, "nx": [nx] * (N + 1), "nu": [nw] * N + [0], "ng": ng})
        opts.setdefault("error_on_fail", False)
        self.qp = ca.conic("nmpc_qp", self.settings.qp_solver, sp, opts)
        self.nz = spec.nz
        self.na = prep.sparsity_out("A").size1()
        self._lbz, self._ubz = absolute_bounds(spec)
        self._dz0 = ca.DM.zeros(self.nz)
        self.Xb: ca.DM | None = None
        self.Wb = ca.DM.zeros(nw, N)
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)
        self.failures = 0

    def absolute_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on ``z = [xa_0, w_0, ..., xa_N]`` in absolute coordinates (see ``absolute_bounds``)."""
        return self._lbz, self._ubz

    def guess(self) -> np.ndarray:
        """The current linearization point ``z`` (after the last step's shift, if any)."""
        return pack_plan(np.array(self.Xb), np.array(self.Wb))

    def reset(self, xa0: np.ndarray):
        """Initialize the guess with ``xa0`` held over the horizon and zero inputs."""
        self.Xb = ca.DM(np.tile(np.asarray(xa0, float)[:, None], (1, self.spec.horizon + 1)))
        self.Wb = ca.DM.zeros(self.spec.nw, self.spec.horizon)
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)

    def step(self, x: np.ndarray, u_prev: np.ndarray, P: np.ndarray, shift: bool = True) -> StepInfo:
        """One RTI: linearize at the (shifted) guess, solve the QP, return its first input."""
        v, nr = self.spec.vehicle, self.spec.vehicle.n_rotors
        if self.spec.exact_input_rate:
            xa0 = np.concatenate([x, u_prev])
        else:
            xa0 = np.asarray(x, float)
            P = P.copy()
            P[ParamIndex.u_prev, 0] = u_prev
        if self.Xb is None:
            self.reset(xa0)
        if not self.spec.exact_input_rate:
            P[ParamIndex.u_prev, 1:] = np.array(self.Wb[:nr, :])
        t0 = time.perf_counter()
        H, g, A, lba, uba, lbx, ubx = self.prep(self.Xb, self.Wb, P, xa0)
        t1 = time.perf_counter()
        sol = self.qp(h=H, g=g, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx, x0=self._dz0, lam_x0=self.lam_x, lam_a0=self.lam_a)
        stats = self.qp.stats()
        X, W, Xs, Ws, u0, slack, check = self.update(self.Xb, self.Wb, sol["x"])
        t2 = time.perf_counter()
        status = str(stats.get("return_status", "unknown"))
        ok = bool(stats.get("success", False)) and np.isfinite(float(check))
        if ok:
            self.Xb, self.Wb = (Xs, Ws) if shift else (X, W)
            self.lam_x, self.lam_a = sol["lam_x"], sol["lam_a"]
            u = np.clip(np.array(u0).ravel(), v.omega_dot_min, v.omega_dot_max)
            slack_max = max(float(slack), 0.0) if self.spec.constrained else 0.0
        else:
            self.failures += 1
            log.warning("NMPC QP failed (%s); applying the shifted previous input", status)
            # the guess is the previous plan shifted to now: apply its first input, shift once more
            u = np.clip(np.nan_to_num(np.array(self.Wb[:nr, 0]).ravel()), v.omega_dot_min, v.omega_dot_max)
            _, _, self.Xb, self.Wb, _, _, _ = self.update(self.Xb, self.Wb, self._dz0)
            slack_max = float("nan")
            self.lam_x = ca.DM.zeros(self.nz)
            self.lam_a = ca.DM.zeros(self.na)
        return StepInfo(u, ok, status, (t1 - t0) * 1e3, (t2 - t1) * 1e3, slack_max, int(stats.get("iter_count", 0) or 0))
