"""The NMPC's cost terms as data: each a weighted least-squares residual ``q |r(stage)|^2`` with its name (its weight's
field in ``[controller.weights]``, ``<name>_terminal`` with an own terminal weight, and its stage parameter
``sw_<name>``), default weight and meaning. The residual is a recipe on a stage's named quantities
(``control.terms.StageVars``: ``s.pos``, ``s.p["p_ref"]``, ``s.stack(...)``...), so this table imports no CasADi and the
schema (``config.controller``) is generated from it below the control floor. **Adding a cost term is one entry here.**"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class CostTerm:
    """A weighted least-squares term ``q |residual(stage)|^2``.

    ``terminal``: ``"stage"`` reuses the stage weight at the terminal stage, a number gives the
    default of an own terminal weight ``<name>_terminal``, ``None`` means no terminal term (the
    residual needs the stage input). ``comms_aware`` terms are dropped in the unconstrained variant.
    """

    name: str
    residual: Callable[[Any], Any]  # a control.terms.StageVars -> its residual (CasADi)
    default: float
    doc: str
    terminal: str | float | None = "stage"
    comms_aware: bool = False
    strictly_positive: bool = False

    @property
    def own_terminal(self) -> bool:
        return self.terminal is not None and self.terminal != "stage"


COST_TERMS: tuple[CostTerm, ...] = (
    CostTerm("position", lambda s: s.pos - s.p["p_ref"], 1.0, "position tracking (eq. 20), m^-2", terminal=10.0),
    CostTerm("velocity", lambda s: s.vel - s.p["v_ref"], 2.0, "velocity tracking (eq. 20), (m/s)^-2"),
    CostTerm("thrust_direction", lambda s: s.rho - s.p["rho_d"], 300.0, "thrust direction R e3 vs rho_d (eq. 20)"),
    CostTerm("misalignment", lambda s: s.stack(s.v12, s.v10), 10.0, "misalignment (v_12, v_10) (eq. 23)",
             terminal=10.0, comms_aware=True),
    CostTerm("body_rate", lambda s: s.omega, 1.0, "regularizer on omega, (rad/s)^-2"),
    CostTerm("yaw", lambda s: s.yaw - s.p["psi_ref"], 1.0, "yaw psi vs its reference (0: a regularizer, nothing else fixes the yaw), rad^-2"),
    CostTerm("shaft_power", lambda s: s.shaft_power_residual, 0.0,
             "shaft power sum 2 pi c_tau Omega^3 (energy-aware term, the paper's 4th future work), W^-1", terminal=None),
    CostTerm("input_rate", lambda s: s.u - s.u_prev, 1e-5, "on u_k - u_(k-1) (eq. 22), (Hz/s)^-2",
             terminal=None, strictly_positive=True),
)
