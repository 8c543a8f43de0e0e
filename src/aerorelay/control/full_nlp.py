"""The same OCP as the RTI NMPC, solved to convergence by IPOPT (reference for tests and the bench)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .ocp import OcpSpec


class FullNlp:
    """Multiple-shooting NLP with the RTI's variables ``z = [xa_0, w_0, ..., xa_N]`` and bounds."""

    def __init__(self, spec: OcpSpec, ipopt_options: dict | None = None):
        self.spec = spec
        N, nx, nw, ng = spec.horizon, spec.nx, spec.nw, spec.ng
        xa0, P = ca.MX.sym("xa0", nx), ca.MX.sym("P", spec.n_params, N + 1)
        X = [ca.MX.sym(f"x{k}", nx) for k in range(N + 1)]
        W = [ca.MX.sym(f"w{k}", nw) for k in range(N)]
        xs, ws, ps = ca.SX.sym("x", nx), ca.SX.sym("w", nw), spec.params.symbol()
        F = ca.Function("F", [xs, ws, ps], [spec.discrete_dynamics(xs, ws, ps)])
        L = ca.Function("L", [xs, ws, ps], [ca.sumsqr(spec.stage_residual(xs, ws, ps))])
        LN = ca.Function("LN", [xs, ps], [ca.sumsqr(spec.terminal_residual(xs, ps))])
        h = ca.Function("h", [xs, ws, ps], [spec.constraint_expr(xs, ws, ps)])
        J: ca.MX = ca.MX(0)
        g, lbg, ubg = [X[0] - xa0], [np.zeros(nx)], [np.zeros(nx)]
        for k in range(N):
            J += L(X[k], W[k], P[:, k])
            g.append(F(X[k], W[k], P[:, k]) - X[k + 1])
            lbg.append(np.zeros(nx))
            ubg.append(np.zeros(nx))
            if ng and k >= 1:
                g.append(h(X[k], W[k], P[:, k]))
                lbg.append(np.zeros(ng))
                ubg.append(np.full(ng, np.inf))
        J += LN(X[N], P[:, N])
        z = ca.vertcat(*[ca.vertcat(X[k], W[k]) for k in range(N)], X[N])
        opts: dict = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.tol": 1e-8, "ipopt.max_iter": 500}
        opts.update(ipopt_options or {})
        self.solver = ca.nlpsol("full_nmpc", "ipopt", {"x": z, "p": ca.vertcat(xa0, ca.vec(P)), "f": J, "g": ca.vertcat(*g)}, opts)
        self.lbg, self.ubg = np.concatenate(lbg), np.concatenate(ubg)

    def solve(self, xa0: np.ndarray, P: np.ndarray, z_guess: np.ndarray, lbz: np.ndarray, ubz: np.ndarray):
        """Solve from ``xa0``; returns (z*, success). Bounds are the RTI's absolute bounds."""
        sol = self.solver(x0=z_guess, p=np.concatenate([xa0, P.T.reshape(-1)]), lbx=lbz, ubx=ubz, lbg=self.lbg, ubg=self.ubg)
        return np.asarray(sol["x"]).ravel(), bool(self.solver.stats()["success"])
