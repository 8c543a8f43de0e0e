"""The QP through ``casadi.conic``: a compiled preparation function, any CasADi QP plugin, an MX update.

Three calls per control step. Kept beside the compiled engine (``hpipm_rti.py``) as a second,
independent route to the same QP: the tests cross-check the two, ``aerorelay bench --backend
casadi`` times it, and the controller falls back to it where no C compiler is available.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from .codegen import compiled
from .linearization import stage_linearization, terminal_linearization
from .ocp import HESSIAN_REG, INF, NP, OcpSpec, ParamIndex, absolute_bounds


def _pack_mx(X, W):
    """``z = [xa_0; w_0; ...; xa_(N-1); w_(N-1); xa_N]`` from state and control matrices."""
    N = W.shape[1]
    return ca.vertcat(ca.vec(ca.vertcat(X[:, :N], W)), X[:, N])


def build_preparation(spec: OcpSpec) -> ca.Function:
    """MX function ``(Xb, Wb, P, xa0) -> (H, g, A, lba, uba, lbx, ubx)``: the QP in the step ``dz``
    around the guess ``(Xb, Wb)``, in HPIPM's stage structure, with the initial state fixed to ``xa0``."""
    N, nx, nw = spec.horizon, spec.nx, spec.nw
    Xb, Wb, P = ca.MX.sym("Xb", nx, N + 1), ca.MX.sym("Wb", nw, N), ca.MX.sym("P", NP, N + 1)
    xa0 = ca.MX.sym("xa0", nx)
    outs = stage_linearization(spec).map(N, "serial")(Xb[:, :N], Wb, P[:, :N])
    xn, Ak, Bk, Hk, gk = outs[:5]
    HN, gN = terminal_linearization(spec)(Xb[:, N], P[:, N])
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


class ConicEngine:
    """casadi.conic route: compiled preparation, QP solver plugin, MX update (three calls)."""

    def __init__(self, spec: OcpSpec, settings):
        self.spec = spec
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        prep = build_preparation(spec)
        self.prep = compiled(prep, spec.key()) if settings.compile else prep
        self.update = build_update(spec)
        sp = {"h": prep.sparsity_out("H"), "a": prep.sparsity_out("A")}
        ng = [0] + [1 if spec.constrained else 0] * (N - 1) + [0]
        opts = settings.conic_options()
        if settings.qp_solver == "hpipm":
            opts.update({"N": N, "nx": [nx] * (N + 1), "nu": [nw] * N + [0], "ng": ng})
        opts.setdefault("error_on_fail", False)
        self.qp = ca.conic("nmpc_qp", settings.qp_solver, sp, opts)
        self.nz = spec.nz
        self.na = prep.sparsity_out("A").size1()
        self._dz0 = ca.DM.zeros(self.nz)

    def reset(self, X: np.ndarray, W: np.ndarray):
        self.Xb, self.Wb = ca.DM(X), ca.DM(W)
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)

    def plan(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.Xb), np.array(self.Wb)

    def step(self, xa0: np.ndarray, P: np.ndarray, shift: bool):
        """-> (ok, first input or fallback input, status, preparation ms, slack max, iterations)."""
        t0 = time.perf_counter()
        H, g, A, lba, uba, lbx, ubx = self.prep(self.Xb, self.Wb, P, xa0)
        t1 = time.perf_counter()
        sol = self.qp(h=H, g=g, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx, x0=self._dz0, lam_x0=self.lam_x, lam_a0=self.lam_a)
        stats = self.qp.stats()
        X, W, Xs, Ws, u0, slack, check = self.update(self.Xb, self.Wb, sol["x"])
        status = str(stats.get("return_status", "unknown"))
        iters = int(stats.get("iter_count", 0) or 0)
        if bool(stats.get("success", False)) and np.isfinite(float(check)):
            self.Xb, self.Wb = (Xs, Ws) if shift else (X, W)
            self.lam_x, self.lam_a = sol["lam_x"], sol["lam_a"]
            return True, np.array(u0).ravel(), status, (t1 - t0) * 1e3, float(slack), iters
        u_fallback = np.array(self.Wb[: self.spec.vehicle.n_rotors, 0]).ravel()
        _, _, self.Xb, self.Wb, _, _, _ = self.update(self.Xb, self.Wb, self._dz0)  # shift the guess
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)
        return False, u_fallback, status, (t1 - t0) * 1e3, float("nan"), iters
