"""The same OCP as the RTI NMPC, solved to convergence by IPOPT (reference for tests and the bench)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .ocp import NP, OcpSpec, ParamIndex, alignment_constraint, discrete_dynamics, stage_residual, terminal_residual


class FullNlp:
    """Multiple-shooting NLP with the RTI's variables ``z = [xa_0, w_0, ..., xa_N]`` and bounds."""

    def __init__(self, spec: OcpSpec, ipopt_options: dict | None = None):
        self.spec = spec
        N, nx, nw = spec.horizon, spec.nx, spec.nw
        xa0, P = ca.MX.sym("xa0", nx), ca.MX.sym("P", NP, N + 1)
        X = [ca.MX.sym(f"x{k}", nx) for k in range(N + 1)]
        W = [ca.MX.sym(f"w{k}", nw) for k in range(N)]
        xs, ws, ps = ca.SX.sym("x", nx), ca.SX.sym("w", nw), ca.SX.sym("p", NP)
        F = ca.Function("F", [xs, ws], [discrete_dynamics(spec, xs, ws)])
        L = ca.Function("L", [xs, ws, ps], [ca.sumsqr(stage_residual(spec, xs, ws, ps))])
        LN = ca.Function("LN", [xs, ps], [ca.sumsqr(terminal_residual(spec, xs, ps))])
        h = ca.Function("h", [xs, ws, ps], [alignment_constraint(spec, xs, ws, ps)])
        J = 0
        g, lbg, ubg = [X[0] - xa0], [np.zeros(nx)], [np.zeros(nx)]
        for k in range(N):
            J += L(X[k], W[k], P[:, k])
            g.append(F(X[k], W[k]) - X[k + 1])
            lbg.append(np.zeros(nx))
            ubg.append(np.zeros(nx))
            if spec.constrained and k >= 1:
                g.append(h(X[k], W[k], P[:, k]) - P[ParamIndex.mu, k])
                lbg.append(np.zeros(1))
                ubg.append(np.full(1, np.inf))
        J += LN(X[N], P[:, N])
        z = ca.vertcat(*[ca.vertcat(X[k], W[k]) for k in range(N)], X[N])
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.tol": 1e-8, "ipopt.max_iter": 500}
        opts.update(ipopt_options or {})
        self.solver = ca.nlpsol("full_nmpc", "ipopt", {"x": z, "p": ca.vertcat(xa0, ca.vec(P)), "f": J, "g": ca.vertcat(*g)}, opts)
        self.lbg, self.ubg = np.concatenate(lbg), np.concatenate(ubg)

    def solve(self, xa0: np.ndarray, P: np.ndarray, z_guess: np.ndarray, lbz: np.ndarray, ubz: np.ndarray):
        """Solve from ``xa0``; returns (z*, success). Bounds are the RTI's absolute bounds."""
        sol = self.solver(x0=z_guess, p=np.concatenate([xa0, P.T.reshape(-1)]), lbx=lbz, ubx=ubz, lbg=self.lbg, ubg=self.ubg)
        return np.asarray(sol["x"]).ravel(), bool(self.solver.stats()["success"])
