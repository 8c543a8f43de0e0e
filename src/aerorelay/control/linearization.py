"""Gauss-Newton linearization of the OCP's stages (paper eq. 20-27), one definition for both QP routes.

``stage_linearization(spec)(xa, w, p) -> (xn, A, B, H, g[, h, Jh])``: the RK4 successor and its
Jacobians, the Gauss-Newton Hessian ``H = J'J`` and gradient ``g = J'r`` of the stage's
least-squares cost over ``z = (xa, w)`` and, in the constrained variant, the mutual-alignment
constraint and its Jacobian. ``terminal_linearization(spec)(xa, p) -> (H, g)``. With
``dense=True`` every output is stored dense (the C engine copies fixed-size blocks).
"""

from __future__ import annotations

import casadi as ca

from .ocp import NP, OcpSpec, alignment_constraint, discrete_dynamics, stage_residual, terminal_residual


def _out(expr, dense: bool):
    return ca.densify(expr) if dense else expr


def stage_linearization(spec: OcpSpec, dense: bool = False) -> ca.Function:
    xa, w, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("w", spec.nw), ca.SX.sym("p", NP)
    z = ca.vertcat(xa, w)
    xn = discrete_dynamics(spec, xa, w)
    r = stage_residual(spec, xa, w, p)
    J = ca.jacobian(r, z)
    outs = [xn, ca.jacobian(xn, xa), ca.jacobian(xn, w), ca.mtimes(J.T, J), ca.mtimes(J.T, r)]
    if spec.constrained:
        h = alignment_constraint(spec, xa, w, p)
        outs += [h, ca.jacobian(h, z)]
    return ca.Function("stage_lin", [xa, w, p], [_out(o, dense) for o in outs])


def terminal_linearization(spec: OcpSpec, dense: bool = False) -> ca.Function:
    xa, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("p", NP)
    r = terminal_residual(spec, xa, p)
    J = ca.jacobian(r, xa)
    return ca.Function("term_lin", [xa, p], [_out(ca.mtimes(J.T, J), dense), _out(ca.mtimes(J.T, r), dense)])
