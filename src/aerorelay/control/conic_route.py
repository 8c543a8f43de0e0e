"""The QP through ``casadi.conic``: a compiled preparation function, any CasADi QP plugin, an MX update.

Kept beside the compiled engine (``hpipm_rti.py``) as a second, independent route to the same QP:
the tests cross-check the two, ``aerorelay bench --backend casadi`` times it, and the controller
falls back to it where no C compiler is available. Same phases as the engine: ``prepare(P)``
linearizes at the guess; ``feedback(xa0)`` fixes the initial state, solves and updates the plan.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..store.codegen import compiled
from .linearization import check_dimensions, stage_linearization, terminal_linearization
from .ocp import HESSIAN_REG, INF, OcpSpec, QpResult, absolute_bounds


def _pack_mx(X, W):
    """``z = [xa_0; w_0; ...; xa_(N-1); w_(N-1); xa_N]`` from state and control matrices."""
    N = W.shape[1]
    return ca.vertcat(ca.vec(ca.vertcat(X[:, :N], W)), X[:, N])


def build_preparation(spec: OcpSpec) -> ca.Function:
    """MX function ``(Xb, Wb, P) -> (H, g, A, lba, uba, lbx, ubx)``: the QP in the step ``dz``
    around the guess ``(Xb, Wb)``, in HPIPM's stage structure (dynamics rows, then the stage's
    constraint rows ``Jh dz >= -h`` on stages 1..N-1). The initial state's bounds are left
    open; ``ConicEngine.feedback`` fixes them to the measurement."""
    N, nx, nw, ng = spec.horizon, spec.nx, spec.nw, spec.ng
    Xb, Wb, P = ca.MX.sym("Xb", nx, N + 1), ca.MX.sym("Wb", nw, N), ca.MX.sym("P", spec.n_params, N + 1)
    stage, term = stage_linearization(spec), terminal_linearization(spec)
    check_dimensions(spec, stage, term)
    xn, Ak, Bk, Hk, gk, hk, Jhk = stage.map(N, "serial")(Xb[:, :N], Wb, P[:, :N])
    HN, gN = term(Xb[:, N], P[:, N])
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
        if ng and k >= 1:
            Jh = Jhk[:, k * (nx + nw) : (k + 1) * (nx + nw)]
            rows.append(ca.horzcat(ca.MX(ng, off), Jh, ca.MX(ng, nz - off - (nx + nw))))
            lb.append(-hk[:, k])
            ub.append(ca.MX(ca.DM.ones(ng) * INF))
    H = ca.diagcat(*blocks_H, HN) + HESSIAN_REG * ca.DM.eye(nz)
    g = ca.vertcat(*blocks_g, gN)
    A = ca.vertcat(*rows)
    lbz, ubz = absolute_bounds(spec)
    zb = _pack_mx(Xb, Wb)
    lbx = ca.DM(lbz) - zb
    ubx = ca.DM(ubz) - zb
    return ca.Function("nmpc_prep", [Xb, Wb, P], [H, g, A, ca.vertcat(*lb), ca.vertcat(*ub), lbx, ubx],
                       ["Xb", "Wb", "P"], ["H", "g", "A", "lba", "uba", "lbx", "ubx"])


def build_update(spec: OcpSpec) -> ca.Function:
    """MX function ``(Xb, Wb, dz) -> (X, W, X_shift, W_shift, u0, slack_max, check)``: apply the QP
    step, shift the plan one stage for the next guess, read the first input; ``check`` is NaN when ``dz`` is."""
    N, nx, nw, nr = spec.horizon, spec.nx, spec.nw, spec.n_rotors
    Xb, Wb, dz = ca.MX.sym("Xb", nx, N + 1), ca.MX.sym("Wb", nw, N), ca.MX.sym("dz", spec.nz)
    body = ca.reshape(dz[: N * (nx + nw)], nx + nw, N)
    X = Xb + ca.horzcat(body[:nx, :], dz[N * (nx + nw) :])
    W = Wb + body[nx:, :]
    Xs = ca.horzcat(X[:, 1:], X[:, N])
    Ws = ca.horzcat(W[:, 1:], W[:, N - 1])
    slack = ca.mmax(W[nr:, 1:]) if (N > 1 and nw > nr) else ca.MX(0)
    return ca.Function("nmpc_update", [Xb, Wb, dz], [X, W, Xs, Ws, W[:nr, 0], slack, ca.sum1(dz)],
                       ["Xb", "Wb", "dz"], ["X", "W", "Xs", "Ws", "u0", "slack", "check"])


class ConicEngine:
    """casadi.conic route: compiled preparation, QP solver plugin, MX update."""

    def __init__(self, spec: OcpSpec, settings):
        self.spec = spec
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        prep = build_preparation(spec)
        # keyed by its source, which holds every constant; straight-line code at -O1, sooner compiled (the route's
        # preparation measured 0-4% slower than at -O2: docs/results/controller-speed.md, "Building an engine")
        self.prep = compiled(prep, "", flags=("-O1",)) if settings.compile else prep
        self.update = build_update(spec)
        sp = {"h": prep.sparsity_out("H"), "a": prep.sparsity_out("A")}
        ng = [0] + [spec.ng] * (N - 1) + [0]
        opts = settings.conic_options()
        if settings.qp_solver == "hpipm":
            opts.update({"N": N, "nx": [nx] * (N + 1), "nu": [nw] * N + [0], "ng": ng})
        opts.setdefault("error_on_fail", False)
        self.qp = ca.conic("nmpc_qp", settings.qp_solver, sp, opts)
        self.nz = spec.nz
        self.na = prep.sparsity_out("A").size1()
        self._dz0 = ca.DM.zeros(self.nz)
        self._qp_data: tuple | None = None

    def reset(self, X: np.ndarray, W: np.ndarray):
        self.Xb, self.Wb = ca.DM(X), ca.DM(W)
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)
        self._qp_data = None

    def plan(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.Xb), np.array(self.Wb)

    def prepare(self, P: np.ndarray) -> None:
        """Linearize at the guess."""
        self._qp_data = self.prep(self.Xb, self.Wb, P)

    def feedback(self, xa0: np.ndarray, shift: bool) -> QpResult:
        """Solve the prepared QP for ``xa0``: the first input, or the fallback input on failure."""
        if self._qp_data is None:
            return QpResult(False, self._fallback(), "not prepared", float("nan"), 0)
        H, g, A, lba, uba, lbx, ubx = self._qp_data
        self._qp_data = None
        x0_step = ca.DM(xa0) - self.Xb[:, 0]
        nx = self.spec.nx
        lbx, ubx = ca.vertcat(x0_step, lbx[nx:]), ca.vertcat(x0_step, ubx[nx:])
        sol = self.qp(h=H, g=g, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx, x0=self._dz0, lam_x0=self.lam_x, lam_a0=self.lam_a)
        stats = self.qp.stats()
        X, W, Xs, Ws, u0, slack, check = self.update(self.Xb, self.Wb, sol["x"])
        status = str(stats.get("return_status", "unknown"))
        iters = int(stats.get("iter_count", 0) or 0)
        if bool(stats.get("success", False)) and np.isfinite(float(check)):
            self.Xb, self.Wb = (Xs, Ws) if shift else (X, W)
            self.lam_x, self.lam_a = sol["lam_x"], sol["lam_a"]
            return QpResult(True, np.array(u0).ravel(), status, float(slack), iters)
        return QpResult(False, self._fallback(), status, float("nan"), iters)

    def _fallback(self) -> np.ndarray:
        """The guess's first input (the previous plan shifted to now); the guess is shifted on."""
        u = np.array(self.Wb[: self.spec.n_rotors, 0]).ravel()
        _, _, self.Xb, self.Wb, _, _, _ = self.update(self.Xb, self.Wb, self._dz0)
        self.lam_x = ca.DM.zeros(self.nz)
        self.lam_a = ca.DM.zeros(self.na)
        return u
