"""The communications-aware NMPC's optimal control problem, described as data (paper eq. 20-27).

Multiple shooting with one RK4 step per interval ``Ts``. The input-rate term ``u_k - u_(k-1)``
(eq. 22) couples neighbouring stages; two formulations keep the QP stage-wise for HPIPM:

- ``exact_input_rate=True`` (default): the state is augmented with the previous input,
  ``xa = (p, eta, v, omega, Omega, u_prev)`` (12 + 2 N_p states): the paper's cost, exactly.
- ``exact_input_rate=False``: ``xa = x`` and ``u_(k-1)`` is a parameter, taken from the previous
  plan (the last applied input at k = 0). Same value at the RTI fixed point but without the
  gradient through ``u_(k-1)``; 6 fewer states, so a cheaper QP (compared by ``aerorelay bench``).

The stage control is ``w = (u, pi)`` with ``u = Omega_dot`` (Hz/s) and the alignment slack
``pi`` >= 0. All costs are Gauss-Newton least squares ``|r|^2``.

Per-stage parameters (``NP`` entries, see ``ParamIndex``): the reference ``p_ref, v_ref,
rho_d``, MRAV-2's predicted position ``p2``, the square roots of the weights and ``mu``. The
terminal stage reuses the layout with the terminal weights.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..models.channel import misalignment, mutual_alignment
from ..models.geometry import rotation_zyx
from ..models.vehicle import Multirotor


class ParamIndex:
    """Slices of the per-stage parameter vector."""

    p_ref = slice(0, 3)
    v_ref = slice(3, 6)
    rho_d = slice(6, 9)
    p2 = slice(9, 12)
    sw_pos, sw_vel, sw_rho, sw_mis, sw_omega, sw_yaw, sw_urate, sw_slack = range(12, 20)
    mu = 20
    u_prev = slice(21, 27)  # used only when exact_input_rate is False
    size = 27


NP = ParamIndex.size
INF = 1e8  # 'unbounded' in the QP's bound vectors
HESSIAN_REG = 1e-8  # added to the Gauss-Newton Hessian's diagonal (both QP routes)


@dataclass(frozen=True)
class OcpSpec:
    """Structure of the OCP: vehicle, horizon, sampling, constraint set and bounds."""

    vehicle: Multirotor
    horizon: int
    ts: float
    constrained: bool
    bs_position: tuple[float, float, float]
    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]
    exact_input_rate: bool = True

    @property
    def nx(self) -> int:  # OCP state (augmented with u_prev when exact_input_rate)
        return self.vehicle.nx + (self.vehicle.n_rotors if self.exact_input_rate else 0)

    @property
    def nw(self) -> int:  # inputs + slack
        return self.vehicle.n_rotors + 1

    @property
    def nz(self) -> int:  # QP variables z = [xa_0, w_0, ..., xa_(N-1), w_(N-1), xa_N]
        return self.horizon * (self.nx + self.nw) + self.nx

    def key(self) -> str:
        """Stable text identifying the generated code (for the on-disk cache)."""
        v = self.vehicle
        parts = [
            v.positions.round(12).tolist(), v.axes.round(12).tolist(), v.spins.tolist(), v.mass,
            np.asarray(v.inertia).round(12).tolist(), v.gravity, v.c_xi, v.c_tau, v.omega_min, v.omega_max,
            v.omega_dot_min, v.omega_dot_max, self.horizon, self.ts, self.constrained, self.bs_position,
            self.workspace_min, self.workspace_max, self.exact_input_rate,
        ]
        return repr(parts)


def _split(spec: OcpSpec, xa):
    nr = spec.vehicle.n_rotors
    return xa[0:3], xa[3:6], xa[6:9], xa[9:12], xa[12 : 12 + nr], xa[12 + nr :]


def discrete_dynamics(spec: OcpSpec, xa, w):
    """``xa_next = (RK4(x, u, Ts), u)`` (eq. 24)."""
    nr = spec.vehicle.n_rotors
    x = xa[: spec.vehicle.nx]
    u = w[:nr]
    x_next = spec.vehicle.rk4_step(x, u, spec.ts)
    return ca.vertcat(x_next, u) if spec.exact_input_rate else x_next


def _tracking_residual(spec: OcpSpec, xa, p):
    """Tracking (eq. 20), misalignment (eq. 23) and regularizers, weighted by the sqrt-weights."""
    I = ParamIndex
    pos, eta, vel, om, _, _ = _split(spec, xa)
    R = rotation_zyx(eta)
    rho = R[:, 2]
    p0 = ca.DM(spec.bs_position)
    v12 = misalignment(pos, R, p[I.p2])
    v10 = misalignment(pos, R, p0)
    return ca.vertcat(
        p[I.sw_pos] * (pos - p[I.p_ref]),
        p[I.sw_vel] * (vel - p[I.v_ref]),
        p[I.sw_rho] * (rho - p[I.rho_d]),
        p[I.sw_mis] * ca.vertcat(v12, v10),
        p[I.sw_omega] * om,
        p[I.sw_yaw] * eta[2],
    ), v12, v10


def stage_residual(spec: OcpSpec, xa, w, p):
    """Stage residual ``r_k`` with ``l_k = |r_k|^2`` (eq. 25 plus the slack penalty q_pi pi^2)."""
    I = ParamIndex
    nr = spec.vehicle.n_rotors
    r_track, _, _ = _tracking_residual(spec, xa, p)
    u_prev = xa[12 + nr :] if spec.exact_input_rate else p[I.u_prev]
    return ca.vertcat(r_track, p[I.sw_urate] * (w[:nr] - u_prev), p[I.sw_slack] * w[nr])


def terminal_residual(spec: OcpSpec, xa, p):
    """Terminal residual ``r_N`` with ``l_N = |r_N|^2`` (eq. 26)."""
    return _tracking_residual(spec, xa, p)[0]


def alignment_constraint(spec: OcpSpec, xa, w, p):
    """``(1 - v_12)(1 - v_10) + pi`` which must be ``>= mu`` (eq. 27e)."""
    _, v12, v10 = _tracking_residual(spec, xa, p)
    return mutual_alignment(v12, v10) + w[spec.vehicle.n_rotors]


def misalignment_function(spec: OcpSpec) -> ca.Function:
    """Numeric helper: (xa or x, p2) -> (v_12, v_10) for logging."""
    x = ca.SX.sym("x", spec.vehicle.nx)
    p2 = ca.SX.sym("p2", 3)
    R = rotation_zyx(x[3:6])
    return ca.Function("mis", [x, p2], [misalignment(x[0:3], R, p2), misalignment(x[0:3], R, ca.DM(spec.bs_position))])


def pack_plan(X: np.ndarray, W: np.ndarray) -> np.ndarray:
    """numpy twin of ``conic_route._pack_mx``: ``z = [xa_0; w_0; ...; xa_N]`` from ``(nx, N+1)`` and ``(nw, N)``."""
    N = W.shape[1]
    return np.concatenate([np.vstack([X[:, :N], W]).T.reshape(-1), X[:, N]])


def unpack_plan(spec: OcpSpec, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of ``pack_plan``: ``(X (nx, N+1), W (nw, N))`` from ``z``."""
    N, nx, nw = spec.horizon, spec.nx, spec.nw
    body = np.asarray(z[: N * (nx + nw)]).reshape(N, nx + nw).T
    return np.column_stack([body[:nx], z[N * (nx + nw) :]]), body[nx:].copy()


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
