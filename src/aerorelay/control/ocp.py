"""The communications-aware NMPC's optimal control problem, described as data (paper eq. 20-27).

Multiple shooting with one RK4 step per interval ``Ts``. The cost terms and constraints come
from ``terms.py`` (one entry each); every dimension below is derived from them and from the
vehicle, never restated. The input-rate term ``u_k - u_(k-1)`` (eq. 22) couples neighbouring
stages; two formulations keep the QP stage-wise for HPIPM:

- ``exact_input_rate=True`` (default): the state is augmented with the previous input,
  ``xa = (p, eta, v, omega, Omega, u_prev)`` (12 + 2 N_p states): the paper's cost, exactly.
- ``exact_input_rate=False``: ``xa = x`` and ``u_(k-1)`` is the internal stage parameter
  ``u_prev``, taken from the previous plan (the last applied input at k = 0).

The stage control is ``w = (u, pi_1..pi_ns)``: ``u = Omega_dot`` (Hz/s) and one slack per soft
constraint. All costs are Gauss-Newton least squares ``|r|^2``; constraints are ``h >= 0``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from ..config.cost_terms import COST_TERMS, CostTerm
from ..models.state import P
from ..models.vehicle import Multirotor
from .params import StageParams
from .terms import CONSTRAINTS, KEEP_OUT, REFERENCE_SIGNALS, SEPARATION, Constraint, StageVars

INF = 1e8  # 'unbounded' in the QP's bound vectors
HESSIAN_REG = 1e-8  # added to the Gauss-Newton Hessian's diagonal (both QP routes)


@dataclass(frozen=True)
class QpResult:
    """What an engine's feedback phase returns: whether the QP solved, the first input to apply
    (the shifted previous plan's on failure, Hz/s), the solver's status text, the largest slack
    (NaN on failure), the interior-point iterations and whether the iteration cap stopped the
    solver on a solution that passed the quality check (status ``CAPPED``)."""

    ok: bool
    u: np.ndarray
    status: str
    slack_max: float
    iterations: int
    capped: bool = False


@dataclass(frozen=True)
class OcpSpec:
    """Structure of the OCP: vehicle, horizon, sampling, bounds, and the terms and constraints.

    ``constrained`` is the paper's communications-aware variant: ``False`` drops every term and
    constraint marked ``comms_aware`` (the "unconstrained" NMPC).
    """

    vehicle: Multirotor
    horizon: int
    ts: float
    constrained: bool
    bs_position: tuple[float, float, float]
    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]
    exact_input_rate: bool = True
    cost_terms: tuple[CostTerm, ...] = field(default=COST_TERMS)
    constraints_all: tuple[Constraint, ...] = field(default=CONSTRAINTS)
    neighbours: int = 0  # other vehicles this relay keeps its separation from (a fleet's; 0: none)
    p0_parameter: bool = False  # the node toward the base station is the stage parameter p0 (a fleet's relay), not bs_position
    disturbance: bool = False  # the model adds the stage parameter a_ext (m/s^2, world): an observer's external acceleration
    obstacles: int = 0  # obstacles this relay keeps out of: one separating plane each per stage (parameter obstacle_planes)

    def __post_init__(self):
        if self.horizon < 1 or self.ts <= 0:
            raise ValueError(f"OcpSpec: horizon must be >= 1 and ts > 0, got {self.horizon}, {self.ts}")
        for name in ("bs_position", "workspace_min", "workspace_max"):
            if len(getattr(self, name)) != 3:
                raise ValueError(f"OcpSpec.{name} must have 3 entries, got {getattr(self, name)}")

    @property
    def terms(self) -> tuple[CostTerm, ...]:
        return tuple(t for t in self.cost_terms if self.constrained or not t.comms_aware)

    @property
    def constraints(self) -> tuple[Constraint, ...]:
        own = tuple(c for c in self.constraints_all if self.constrained or not c.comms_aware)
        return own + ((SEPARATION,) if self.neighbours else ()) + ((KEEP_OUT,) if self.obstacles else ())

    @property
    def soft_constraints(self) -> tuple[Constraint, ...]:
        return tuple(c for c in self.constraints if c.soft)

    @property
    def n_rotors(self) -> int:
        return self.vehicle.n_rotors

    @property
    def nx(self) -> int:  # OCP state (augmented with u_prev when exact_input_rate)
        return self.vehicle.nx + (self.vehicle.n_rotors if self.exact_input_rate else 0)

    @property
    def ns(self) -> int:  # slacks (one per soft constraint)
        return len(self.soft_constraints)

    @property
    def nw(self) -> int:  # inputs + slacks
        return self.vehicle.n_rotors + self.ns

    @cached_property
    def ng(self) -> int:
        """Constraint rows per stage (1..N-1), from the expressions themselves."""
        return int(self.constraint_expr(*self._symbols()).shape[0]) if self.constraints else 0

    @property
    def nz(self) -> int:  # QP variables z = [xa_0, w_0, ..., xa_(N-1), w_(N-1), xa_N]
        return self.horizon * (self.nx + self.nw) + self.nx

    @cached_property
    def params(self) -> StageParams:
        """The per-stage parameter layout: reference signals, sqrt-weights, slack penalties."""
        fields = list(REFERENCE_SIGNALS)
        if self.p0_parameter:  # the next node toward the base station over the horizon (m, world)
            fields.append(("p0", 3))
        if self.neighbours:  # the other vehicles' predicted positions (m, world) and the separation (m)
            fields += [("p_others", 3 * self.neighbours), ("separation_m", 1)]
        if self.disturbance:  # the external acceleration the model adds (m/s^2, world)
            fields.append(("a_ext", 3))
        if self.obstacles:  # per obstacle (n, c): keep n . p >= c (unit normal, m)
            fields.append(("obstacle_planes", 4 * self.obstacles))
        fields += [(f"sw_{t.name}", 1) for t in self.terms]
        fields += [(f"sw_slack_{c.name}", 1) for c in self.soft_constraints]
        internal: tuple[str, ...] = ()
        if not self.exact_input_rate:
            fields.append(("u_prev", self.vehicle.n_rotors))
            internal = ("u_prev",)
        return StageParams(fields, internal)

    @property
    def n_params(self) -> int:
        return self.params.size

    def key(self) -> str:
        """Stable text identifying the generated code (for the on-disk cache)."""
        v = self.vehicle
        parts = [
            v.positions.round(12).tolist(), v.axes.round(12).tolist(), v.spins.tolist(), v.mass,
            np.asarray(v.inertia).round(12).tolist(), v.gravity, v.c_xi, v.c_tau, v.omega_min, v.omega_max,
            v.omega_dot_min, v.omega_dot_max, self.horizon, self.ts, self.constrained, self.bs_position,
            self.workspace_min, self.workspace_max, self.exact_input_rate, self.params.names,
            [c.name for c in self.constraints], [c.soft for c in self.constraints],
        ] + ([self.neighbours] if self.neighbours else []) + (["p0"] if self.p0_parameter else [])  # a one-relay OCP keeps its cached engine
        # the disturbance and the obstacles show in params.names and the constraints' names
        return repr(parts)

    _DESCRIBED = ("horizon", "ts", "constrained", "bs_position", "workspace_min", "workspace_max", "exact_input_rate",
                  "neighbours", "p0_parameter", "disturbance", "obstacles")

    def description(self) -> dict:
        """Plain data (JSON) that rebuilds this OCP in another process (``from_description``): the vehicle's numbers
        and the structure's. The cost terms and constraints are the package's own tables; an OCP built with others
        cannot be described (ValueError). A peer solver (benchmarks/acados) rebuilds the OCP from a tree's
        ``manifest.json`` with it and checks ``key()``."""
        if self.cost_terms != COST_TERMS or self.constraints_all != CONSTRAINTS:
            raise ValueError("OcpSpec.description: this OCP has cost terms or constraints of its own (not the package's "
                             "tables): it cannot be rebuilt from data")
        v = self.vehicle
        vehicle = {f.name: np.asarray(getattr(v, f.name)).tolist() for f in fields(v)}
        return {"vehicle": vehicle, **{name: getattr(self, name) for name in self._DESCRIBED}}

    @classmethod
    def from_description(cls, data: dict) -> OcpSpec:
        """The OCP ``description()`` wrote (lists back to arrays and tuples)."""
        v = data["vehicle"]
        arrays = {"positions", "axes", "spins", "inertia"}
        numbers: dict[str, Any] = {k: np.asarray(x) if k in arrays else x for k, x in v.items()}
        vehicle = Multirotor(**numbers)
        rest: dict[str, Any] = {k: tuple(data[k]) if isinstance(data[k], list) else data[k] for k in cls._DESCRIBED}
        return cls(vehicle=vehicle, **rest)

    # -- expressions -------------------------------------------------------------------------
    def _symbols(self):
        return ca.SX.sym("xa", self.nx), ca.SX.sym("w", self.nw), self.params.symbol()

    def stage_vars(self, xa, w, p) -> StageVars:
        return StageVars(self, xa, w, self.params.unpack(p))

    def discrete_dynamics(self, xa, w, p=None):
        """``xa_next = (RK4(x, u, Ts)[, u])`` (eq. 24); with ``disturbance`` the stage parameter
        ``a_ext`` is added to the translational acceleration (held over the step)."""
        nr, veh = self.vehicle.n_rotors, self.vehicle
        x, u = xa[: veh.nx], w[:nr]
        a_ext = None
        if self.disturbance:
            if p is None:
                raise ValueError("discrete_dynamics: this OCP's model adds a_ext: give the stage parameters p")
            a_ext = self.params.unpack(p)["a_ext"]
        x_next = veh.rk4_step(x, u, self.ts, a_ext)
        return ca.vertcat(x_next, u) if self.exact_input_rate else x_next

    def stage_residual(self, xa, w, p):
        """Stage residual ``r_k`` with ``l_k = |r_k|^2`` (eq. 25 plus the slack penalties q_pi pi^2)."""
        s = self.stage_vars(xa, w, p)
        parts = [s.p[f"sw_{t.name}"] * t.residual(s) for t in self.terms]
        parts += [s.p[f"sw_slack_{c.name}"] * s.slack[c.name] for c in self.soft_constraints]
        return ca.vertcat(*parts)

    def terminal_residual(self, xa, p):
        """Terminal residual ``r_N`` with ``l_N = |r_N|^2`` (eq. 26); the terminal stage's
        parameter column carries the terminal weights."""
        s = self.stage_vars(xa, None, p)
        return ca.vertcat(*[s.p[f"sw_{t.name}"] * t.residual(s) for t in self.terms if t.terminal is not None])

    def constraint_expr(self, xa, w, p):
        """Every constraint row ``h(xa, w, p)`` (slacks added to the soft ones); feasible: ``h >= 0``."""
        s = self.stage_vars(xa, w, p)
        rows = []
        for c in self.constraints:
            h = c.expression(s)
            rows.append(h + s.slack[c.name] if c.soft else h)
        return ca.vertcat(*rows) if rows else ca.SX(0, 1)


def pack_plan(X: np.ndarray, W: np.ndarray) -> np.ndarray:
    """numpy twin of ``conic_route._pack_mx``: ``z = [xa_0; w_0; ...; xa_N]`` from ``(nx, N+1)`` and ``(nw, N)``."""
    N = W.shape[1]
    if X.shape[1] != N + 1:
        raise ValueError(f"pack_plan: X has {X.shape[1]} columns, W has {N}; expected N + 1 and N")
    return np.concatenate([np.vstack([X[:, :N], W]).T.reshape(-1), X[:, N]])


def unpack_plan(spec: OcpSpec, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of ``pack_plan``: ``(X (nx, N+1), W (nw, N))`` from ``z``."""
    N, nx, nw = spec.horizon, spec.nx, spec.nw
    if np.size(z) != spec.nz:
        raise ValueError(f"unpack_plan: z has {np.size(z)} entries, the OCP has nz = {spec.nz}")
    body = np.asarray(z[: N * (nx + nw)]).reshape(N, nx + nw).T
    return np.column_stack([body[:nx], z[N * (nx + nw) :]]), body[nx:].copy()


def absolute_bounds(spec: OcpSpec) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on ``z`` in absolute coordinates: motor speeds and workspace on states k >= 1,
    motor accelerations on inputs, slacks ``pi_k >= 0`` for k >= 1 (fixed to 0 at k = 0).
    Unbounded entries are +-INF."""
    v, N, nx, nw, nr = spec.vehicle, spec.horizon, spec.nx, spec.nw, spec.vehicle.n_rotors
    lbx, ubx = -INF * np.ones((nx, N + 1)), INF * np.ones((nx, N + 1))
    lbx[P, 1:] = np.array(spec.workspace_min)[:, None]
    ubx[P, 1:] = np.array(spec.workspace_max)[:, None]
    lbx[12 : 12 + nr, 1:], ubx[12 : 12 + nr, 1:] = v.omega_min, v.omega_max
    lbw, ubw = np.zeros((nw, N)), np.zeros((nw, N))
    lbw[:nr], ubw[:nr] = v.omega_dot_min, v.omega_dot_max
    ubw[nr:, 1:] = INF
    return pack_plan(lbx, lbw), pack_plan(ubx, ubw)
