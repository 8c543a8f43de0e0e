"""Gauss-Newton linearization of the OCP's stages (paper eq. 20-27), one definition for both QP routes.

``stage_linearization(spec)(xa, w, p) -> (xn, A, B, H, g, h, Jh)``: the RK4 successor and its
Jacobians, the Gauss-Newton Hessian ``H = J'J`` and gradient ``g = J'r`` of the stage's
least-squares cost over ``z = (xa, w)``, and the ``ng`` constraint rows ``h >= 0`` with their
Jacobian (``ng = 0``: empty). ``terminal_linearization(spec)(xa, p) -> (H, g)``. With
``dense=True`` every output is stored dense (the C engine copies fixed-size blocks).
``check_dimensions`` verifies the functions against the spec before anything is built on them.
"""

from __future__ import annotations

import casadi as ca

from .ocp import OcpSpec


def _out(expr, dense: bool):
    return ca.densify(expr) if dense else expr


def stage_linearization(spec: OcpSpec, dense: bool = False) -> ca.Function:
    xa, w, p = ca.SX.sym("xa", spec.nx), ca.SX.sym("w", spec.nw), spec.params.symbol()
    z = ca.vertcat(xa, w)
    xn = spec.discrete_dynamics(xa, w, p)
    r = spec.stage_residual(xa, w, p)
    J = ca.jacobian(r, z)
    h = spec.constraint_expr(xa, w, p)
    outs = [xn, ca.jacobian(xn, xa), ca.jacobian(xn, w), ca.mtimes(J.T, J), ca.mtimes(J.T, r), h, ca.jacobian(h, z)]
    return ca.Function("stage_lin", [xa, w, p], [_out(o, dense) for o in outs],
                       ["xa", "w", "p"], ["xn", "A", "B", "H", "g", "h", "Jh"])


def terminal_linearization(spec: OcpSpec, dense: bool = False) -> ca.Function:
    xa, p = ca.SX.sym("xa", spec.nx), spec.params.symbol()
    r = spec.terminal_residual(xa, p)
    J = ca.jacobian(r, xa)
    return ca.Function("term_lin", [xa, p], [_out(ca.mtimes(J.T, J), dense), _out(ca.mtimes(J.T, r), dense)],
                       ["xa", "p"], ["H", "g"])


def check_dimensions(spec: OcpSpec, stage: ca.Function, terminal: ca.Function) -> None:
    """Raise ``ValueError`` naming the first block whose shape disagrees with the spec (like
    acados' ``make_consistent``): the engine copies fixed-size blocks and must never shift data."""
    nx, nw, ng, nz = spec.nx, spec.nw, spec.ng, spec.nx + spec.nw
    expected_in = {"xa": (nx, 1), "w": (nw, 1), "p": (spec.n_params, 1)}
    expected_out = {"xn": (nx, 1), "A": (nx, nx), "B": (nx, nw), "H": (nz, nz), "g": (nz, 1),
                    "h": (ng, 1), "Jh": (ng, nz)}
    for fun, ins, outs in ((stage, expected_in, expected_out),
                           (terminal, {"xa": (nx, 1), "p": (spec.n_params, 1)}, {"H": (nx, nx), "g": (nx, 1)})):
        for name, shape in ins.items():
            got = fun.size_in(fun.index_in(name))
            if tuple(got) != shape:
                raise ValueError(f"{fun.name()} input {name}: shape {tuple(got)}, the OCP needs {shape}")
        for name, shape in outs.items():
            got = fun.size_out(fun.index_out(name))
            if tuple(got) != shape:
                raise ValueError(f"{fun.name()} output {name}: shape {tuple(got)}, the OCP needs {shape}")
