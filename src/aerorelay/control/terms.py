"""The NMPC's cost terms and constraints as data (paper eq. 20-27).

Each ``CostTerm`` is a least-squares residual ``r`` weighted as ``q |r|^2``; its ``name`` is also
its weight's field in ``[controller.weights]`` (and ``<name>_terminal`` when it has its own
terminal weight) and its stage parameter ``sw_<name>`` (the square root of ``q``). Each
``Constraint`` is ``h(stage) >= 0`` on stages 1..N-1; a soft one gets its own slack ``pi >= 0``
in the stage input (``h + pi >= 0``) with the penalty ``controller.q_slack * pi^2``.

**Adding a cost term or a constraint is one entry in ``COST_TERMS`` (``config/cost_terms.py``: the schema's weights
are generated from it, so it is data CasADi-free) or ``CONSTRAINTS`` (here)**: the
scenario schema, the parameter layout, the linearization, both QP routes, the compiled engine
and the full NLP take their dimensions from these lists. A term or constraint that needs a new
reference signal also declares it in ``REFERENCE_SIGNALS`` and the planner's reference fills it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca

from ..models.channel import misalignment, mutual_alignment
from ..models.geometry import rotation_zyx
from ..models.state import ETA, OMEGA, YAW, P, V

# Signals fed to every stage by the controller (name, size): the planner's reference and what
# the relay knows of the others. Units: m, m/s, unit vector, m, dimensionless.
REFERENCE_SIGNALS: tuple[tuple[str, int], ...] = (
    ("p_ref", 3),  # governed position reference, world
    ("v_ref", 3),  # velocity reference, world
    ("rho_d", 3),  # desired thrust direction (a_d + g e3)/|a_d + g e3| (eq. 20)
    ("p2", 3),  # MRAV-2's predicted position, world
    ("mu", 1),  # minimum mutual alignment (eq. 27e)
    ("psi_ref", 1),  # yaw reference, rad (0 unless a planner turns the platform)
)
# A fleet's relay (``OcpSpec.p0_parameter``) adds ("p0", 3): its next node toward the base station on
# its route (the next relay's latest plan or the base station), m, world; v_10 is the cosine toward it.


def separation_margin(r2, d2):
    """The separation row's value for a squared distance ``r2`` and a squared separation ``d2`` (m^2; numpy or
    CasADi): ``2 d^2 (r^2 - d^2) / (r^2 + d^2)``. It is zero exactly where ``r = d`` and has the gradient of
    ``r^2 - d^2`` there (``2 d`` per metre), so a violation costs the slack what it did; but it stays within
    ``(-2 d^2, 2 d^2)``: a vehicle 100 m away reads ``~2 d^2``, nearly constant. The unbounded ``r^2 - d^2`` read
    1.7e3-3.2e4 m^2 for the neighbours of a 250 m chain, next to rows of order 1: the interior-point method's
    complementarity (absolute, ``tol_comp``) then took 47 iterations on average and most QPs ended at the cap
    (docs/results/networks.md, 'Networks at scale')."""
    return 2.0 * d2 * (r2 - d2) / (r2 + d2)


class StageVars:
    """Named quantities of one stage for the term and constraint expressions (CasADi symbols).

    ``xa = (p, eta, v, omega, Omega[, u_prev])``, ``w = (u, pi_1..pi_ns)``, ``p`` the stage's
    parameter vector unpacked by name. Derived quantities are computed once per stage.
    """

    def __init__(self, spec, xa, w, p: dict[str, Any]):
        nr = spec.vehicle.n_rotors
        self.vehicle = spec.vehicle
        self.pos, self.eta, self.vel, self.omega = xa[P], xa[ETA], xa[V], xa[OMEGA]
        self.yaw = xa[YAW]
        self.speeds = xa[12 : 12 + nr]
        self.u = None if w is None else w[:nr]
        self.slack = {} if w is None else {c.name: w[nr + i] for i, c in enumerate(spec.soft_constraints)}
        self.u_prev: Any = xa[12 + nr :] if spec.exact_input_rate else p.get("u_prev")
        self.p = p
        # the link toward the base station: the BS itself, or a fleet's next node on the route (parameter p0)
        self.bs = p["p0"] if spec.p0_parameter else ca.DM(spec.bs_position)

    @staticmethod
    def stack(*parts):
        """The parts as one column (a residual of several pieces)."""
        return ca.vertcat(*parts)

    @cached_property
    def R(self):
        return rotation_zyx(self.eta)

    @cached_property
    def rho(self):
        """Thrust direction R e3 (body z in the world frame)."""
        return self.R[:, 2]

    @cached_property
    def shaft_power_residual(self):
        """``r`` with ``|r|^2`` the aerodynamic shaft power ``sum_i 2 pi c_tau Omega_i^3`` (W,
        ``Multirotor.shaft_power``); ``(Omega^2)^(3/4)`` keeps it smooth for any sign."""
        return ca.sqrt(2.0 * ca.pi * self.vehicle.c_tau) * (self.speeds**2) ** 0.75

    @cached_property
    def v12(self):
        """Directional cosine squared toward MRAV-2 (eq. 23)."""
        return misalignment(self.pos, self.R, self.p["p2"])

    @cached_property
    def separation_margins(self):
        """``separation_margin(|p - q_j|^2, d^2)`` (m^2) for every other vehicle ``j`` in the relay's separation
        rows at its predicted position ``q_j`` (``p_others``, 3 per vehicle) and the separation ``d``
        (``separation_m``)."""
        q = self.p["p_others"]
        d2 = self.p["separation_m"] ** 2
        rows = []
        for j in range(q.shape[0] // 3):
            e = self.pos - q[3 * j : 3 * j + 3]
            rows.append(separation_margin(ca.dot(e, e), d2))
        return ca.vertcat(*rows)

    @cached_property
    def keep_out_margins(self):
        """``n_j . p - c_j`` (m) for every obstacle's separating plane ``(n_j, c_j)`` (``obstacle_planes``,
        4 per obstacle, ``models.obstacles.separating_plane``): >= 0 outside the grown obstacle."""
        q = self.p["obstacle_planes"]
        return ca.vertcat(*[ca.dot(q[4 * j : 4 * j + 3], self.pos) - q[4 * j + 3] for j in range(q.shape[0] // 4)])

    @cached_property
    def v10(self):
        """Directional cosine squared toward the base station (eq. 23), or a fleet's next node toward it."""
        return misalignment(self.pos, self.R, self.bs)


@dataclass(frozen=True)
class Constraint:
    """``expression(stage) >= 0`` (rows: the expression's length) on stages 1..N-1."""

    name: str
    expression: Callable[[StageVars], Any]
    doc: str
    soft: bool = True
    comms_aware: bool = True



# A fleet's relays keep apart: present in the OCP of a relay that has neighbours (``OcpSpec.neighbours``: its rows, one
# per other vehicle it keeps apart from, the nearest ones), whose predicted positions come as the stage parameter
# ``p_others`` (their latest plans, one step old).
SEPARATION = Constraint("separation", lambda s: s.separation_margins,
                        "2 d^2 (|p - q_j|^2 - d^2) / (|p - q_j|^2 + d^2) >= -pi for the nearest other vehicles j "
                        "(network.min_separation_m, network.separation_neighbours)", comms_aware=False)

# A relay among obstacles (``OcpSpec.obstacles``) keeps out: one plane per obstacle and stage, chosen from its
# previous plan (the plane through the grown obstacle's nearest point, normal toward the plan): a linear row
# whose feasible side never meets the obstacle (convexity).
KEEP_OUT = Constraint("obstacles", lambda s: s.keep_out_margins,
                      "n_j . p - c_j >= -pi for every obstacle's separating plane ([[obstacles]] margin_m)", comms_aware=False)

CONSTRAINTS: tuple[Constraint, ...] = (
    Constraint("mutual_alignment", lambda s: mutual_alignment(s.v12, s.v10) - s.p["mu"],
               "(1 - v_12)(1 - v_10) >= mu - pi (eq. 27e)"),
)
