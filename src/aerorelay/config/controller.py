"""``[controller]`` as data: the NMPC's sampling, horizon and weights, its workspace, the
fail-safe and supervisor limits, and the capacity-seeking planner's settings."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, create_model, field_validator, model_validator

from .base import Strict, Vec3, papers_generator_named
from .cost_terms import COST_TERMS

MIN_PREDICTION_S = 0.3  # horizon x Ts: shorter predictions cannot plan a stop inside the workspace
MAX_TS_S = 0.05  # one RK4 step per Ts: longer periods do not resolve the attitude dynamics


def _weights_model() -> type[Strict]:
    """``[controller.weights]``: one field per cost term of ``config/cost_terms.py`` (and
    ``<name>_terminal`` for a term with its own terminal weight). Each is the diagonal entry
    ``q`` of a term ``q * r^2`` (docs/concepts/weights-that-fly.md). Generated once, at import,
    from ``COST_TERMS``, so a new cost term is one entry there (docs/decisions.md)."""
    fields: dict[str, Any] = {}
    for t in COST_TERMS:
        weight = Field(t.default, gt=0.0, description=t.doc) if t.strictly_positive else \
            Field(t.default, ge=0.0, description=t.doc)
        fields[t.name] = (float, weight)
        if t.own_terminal:
            fields[f"{t.name}_terminal"] = (float, Field(float(t.terminal or 0.0), ge=0.0, description=f"terminal: {t.doc}"))
    return create_model("Weights", __base__=Strict, __doc__=_weights_model.__doc__, **fields)


if TYPE_CHECKING:
    class Weights(Strict):
        """The type checker's view of the generated model: every weight a float."""

        def __getattr__(self, name: str) -> float: ...
else:
    Weights = _weights_model()


class FailsafeConfig(Strict):
    """When the brake law takes over from the NMPC, and when the NMPC takes over again."""

    failures_to_fallback: int = Field(3, ge=1, le=1000, description="consecutive QP failures before the hand-over")
    successes_to_resume: int = Field(5, ge=1, le=1000, description="consecutive QP successes before the NMPC resumes")
    workspace_margin_m: float = Field(0.5, ge=0.0, le=5.0, description="the brake law's hold point keeps this far inside the workspace")
    supervisor: bool = Field(True, description="the flight-safety supervisor: outside its envelope the brake law flies at once")
    box_tolerance_m: float = Field(0.05, ge=0.0, le=2.0, description="envelope: how far past the workspace box, m")
    max_tilt_deg: float = Field(45.0, gt=0.0, le=89.0, description="envelope: body tilt, deg")
    max_speed_m_s: float = Field(10.0, gt=0.0, le=50.0, description="envelope: speed, m/s")
    max_body_rate_rad_s: float = Field(6.0, gt=0.0, le=50.0, description="envelope: body rates, rad/s")
    max_safety_handovers: int = Field(1, ge=1, le=1000, description="after this many envelope hand-overs the brake law "
                                      "keeps the relay for the rest of the mission")


class Workspace(Strict):
    """Axis-aligned box (m, world) the relay must stay in (NMPC position bounds)."""

    min: Vec3 = Field(default_factory=lambda: [-7.0, -6.0, 0.5], description="the box's lower corner, m (world; z at or "
                      "above world.ground_z_m)")
    max: Vec3 = Field(default_factory=lambda: [7.0, 6.0, 19.0], description="the box's upper corner, m (world)")

    @model_validator(mode="after")
    def _ordered(self):
        for i, ax in enumerate("xyz"):
            if self.min[i] >= self.max[i]:
                raise ValueError(f"workspace {ax}: min ({self.min[i]}) must be < max ({self.max[i]})")
        return self

    def contains(self, p) -> bool:
        return all(self.min[i] <= p[i] <= self.max[i] for i in range(3))


class CapacityPlannerConfig(Strict):
    """The capacity-seeking planner (``controller.planner = "capacity"``). Its NMPC tracks the
    planner's position and antenna-axis references: the paper's comms-aware terms (misalignment
    cost, mutual-alignment constraint) are dropped whatever ``controller.variant`` says, and the
    position weights below replace ``weights.position`` / ``weights.position_terminal``."""

    speed_m_s: float = Field(1.0, gt=0.0, le=5.0, description="reference speed limit, m/s")
    max_accel_m_s2: float = Field(4.0, gt=0.0, le=8.0, description="reference acceleration limit, m/s^2")
    brake_accel_m_s2: float = Field(1.5, gt=0.0, le=8.0, description="the reference slows down early enough to stop on "
                                    "its target at this deceleration, m/s^2 (at most max_accel_m_s2; 4: the tilted relay at "
                                    "3 m/s overshot its braking reference by 0.9 m, motors at their bounds: docs/results/controller-speed.md)")
    margin_m: float = Field(0.05, ge=0.0, le=2.0, description="the reference keeps this far inside the workspace box, m")
    leash_m: float = Field(1.0, gt=0.0, le=20.0, description="the target stays this close to the pre-flight route, m")
    route_grid_m: float = Field(1.0, ge=0.1, le=20.0, description="grid of the pre-flight route, m (0.5 m: 9-11 s before "
                                "take-off, 1 m: 0.3-0.6 s on this VM, capacity within 0.01 of the bound either way)")
    route_dt_s: float | None = Field(None, ge=0.1, le=30.0, description="time step of the pre-flight route, s; default 1 s "
                                     "for one relay (at least route_grid_m / speed_m_s: a step moves at least one cell; with "
                                     "scoring = 'traced' each step traces every cell), 2 s for a network's route (each step's "
                                     "configuration refined on the network's rate). network.route_dt_s is its old spelling")
    lookahead_s: float | None = Field(None, ge=0.0, le=10.0, description="MRAV-2 is predicted this far ahead for the "
                                      "target, s (default: 1 s up to 1 m/s, 1 m / speed_m_s above: a faster relay lags less)")
    axis_rate_deg_s: float = Field(30.0, gt=0.0, le=720.0, description="the antenna-axis reference turns at most this fast, deg/s")
    axis_step_deg: float = Field(5.0, ge=1.0, le=30.0, description="spacing of the antenna axes the planner scores "
                                 "(tilt rings and azimuths), deg")
    tilt_fraction: float = Field(0.85, gt=0.0, le=1.0, description="the antenna axes the planner may ask for tilt at most "
                                 "this fraction of the platform's hover tilt limit toward their azimuth (1: up to the limit, "
                                 "where a motor saturates; the bound allows the full limit)")
    tracking_freq_rad_s: float = Field(1.0, gt=0.0, le=5.0, description="a level-only platform's thrust-direction reference "
                                       "adds the acceleration a critically damped PD law of this frequency asks to close its "
                                       "tracking error (1.5: the same link, a motor at a bound 5x as often)")
    boundary_axes: bool = Field(True, description="besides the tilt rings every axis_step_deg, the axes at the tilt limit "
                                "(times tilt_fraction) toward each azimuth: the strongest holdable tilts, which the rings miss "
                                "by up to axis_step_deg")
    yaw_rate_deg_s: float = Field(0.0, ge=0.0, le=90.0, description="the platform may yaw (its reference at most this "
                                  "fast, deg/s, in 10 deg steps within +-60 deg) to bring its strongest tilt azimuth under "
                                  "the antenna axis it wants (0: zero yaw)")
    excursion_m: float = Field(0.0, ge=0.0, le=10.0, description="while an estimated jammer's position std is above "
                               "excursion_std_m, the target circles at this radius (m) to make the jammer observable (0: off)")
    excursion_std_m: float = Field(1.0, gt=0.0, le=100.0, description="the excursion stops once every estimated jammer's "
                                   "largest position std is below this, m")
    excursion_max_loss: float = Field(0.05, ge=0.0, le=1.0, description="the excursion pauses while the best capacity at "
                                      "its circling point is more than this fraction below the target's (1: never pauses)")
    position_weight: float = Field(5.0, ge=0.0, description="replaces weights.position, m^-2")
    position_weight_terminal: float = Field(50.0, ge=0.0, description="replaces weights.position_terminal, m^-2")
    scoring: Literal["joint", "decoupled", "traced"] = Field(
        "joint", description="joint: every candidate position with every holdable axis (27 x K poses); decoupled: the "
        "positions at the current axis goal, then every axis at the best one (27 + K: docs/results/controller-speed.md); "
        "traced: as joint, on the ray-traced channel (channel.propagation.model = 'ray_traced'; one trace per replan, "
        "the replans at most every trace_period_s; a fleet's with network.planner = 'capacity': a trace per relay and "
        "one for the joint moves)")
    replan_every: int = Field(4, ge=1, le=50, description="control steps between two replans (all candidates scored in "
                              "one compiled call): 1 spreads the planner over every step, so no step carries it alone "
                              "(docs/results/controller-speed.md)")
    qp_iter_max: int = Field(50, ge=1, le=100, description="the tracking NMPC's QP interior-point iteration cap (5 "
                             "trims the step-time tail on the presets; an iterate that fails qp_accept_tol continues from "
                             "itself for up to 50 more: docs/results/controller-speed.md)")
    qp_accept_tol: float = Field(0.0, ge=0.0, le=1e-2, description="a QP the cap stopped is flown when its primal "
                                 "residuals (dynamics, every inequality) are <= this, else it is a QP failure (0: never)")

    @property
    def lookahead(self) -> float:
        """MRAV-2's prediction horizon for the target, s (``lookahead_s``, or 1 s up to 1 m/s and
        1 m / ``speed_m_s`` above: measured on the nominal tilted mission at 3 m/s, mean C 0.796 /
        0.818 / 0.835 of the path bound at 1 / 0.5 / 0 s; at 1 m/s 0.842 / 0.832 at 1 / 0.5 s)."""
        return self.lookahead_s if self.lookahead_s is not None else min(1.0, 1.0 / self.speed_m_s)


class ControllerConfig(Strict):
    """Trajectory generator + communications-aware NMPC."""

    variant: Literal["constrained", "unconstrained"] = Field("constrained", description="constrained: the paper's "
                                                             "comms-aware NMPC (misalignment cost, alignment constraint); "
                                                             "unconstrained: the same NMPC without them")
    planner: str | None = Field(
        None, min_length=1, max_length=64, pattern=r"^[a-z][a-z0-9_]*$",
        description="the planner of the relay or of the whole network, a registered planner (its references decide the "
        "NMPC: docs/guide/extending.md): trajectory_generator (the paper's generator, over every hop of every route in a "
        "network, flown by the comms-aware NMPC; 'paper' is read as it), isotropic (baseline A: isotropic surrogate), "
        "single_shot (baseline B: a single-shot plan), capacity (the capacity-seeking planner, one relay's or the "
        "fleet's, flown by the tracking NMPC with its antenna-axis reference), equidistant (each relay evenly spaced on "
        "the line from the base station to its source, tracking NMPC), or one registered with aerorelay.register_planner "
        "(register_network_planner) before the scenario is loaded; default trajectory_generator for one relay and one "
        "source, equidistant for a network. network.planner is its old spelling",
    )

    _one_name_per_planner = field_validator("planner", mode="before")(papers_generator_named)

    ts_s: float = Field(0.015, gt=0.0, le=MAX_TS_S, description="NMPC sampling period Ts (one RK4 step per period)")
    horizon: int = Field(30, ge=1, le=200, description="N shooting intervals")
    mu: float = Field(0.2, ge=0.0, le=1.0, description="minimum mutual alignment")
    q_slack: float = Field(1e4, gt=0.0, description="q_pi")
    governor_speed_m_s: float = Field(0.5, gt=0.0, description="max speed of the reference governor")
    hessian_eig_floor: float = Field(1e-3, gt=0.0, description="min eigenvalue of H11 after regularization")
    hessian_floor: Literal["paper", "relative"] | None = Field(
        None, description="the eigenvalue floor's rule: paper (hessian_eig_floor * max(1, |lambda|max), the paper's, "
        "which freezes the generator in physical units, where the cost is in s/bit) or relative (hessian_eig_floor * "
        "|lambda|max, scale-free); default paper for one relay and one source, relative for a network "
        "(docs/results/networks.md#the-papers-generator-written-once)")
    exact_input_rate: bool = Field(
        True, description="input-rate cost through an augmented state (exact) or the previous plan (faster)"
    )
    senses_jammer_state: bool = Field(
        False, description="after localization, the generator plans with P_J = 0 while the jammer is OFF "
        "(it senses the schedule); otherwise it plans with the nominal power throughout"
    )
    backend: Literal["python", "c"] = Field(
        "python", description="what flies each control step: python (the NMPC through aerorelay's compiled engine) or c "
        "(the relay's generated C library, as aerorelay codegen writes it, built once per controller into the cache: the "
        "same commands, bit for bit with the same BLASFEO kernels; a C compiler and make needed)")
    weights: Weights = Field(default_factory=Weights)
    workspace: Workspace = Field(default_factory=Workspace)
    failsafe: FailsafeConfig = Field(default_factory=FailsafeConfig)
    capacity: CapacityPlannerConfig = Field(default_factory=CapacityPlannerConfig)

    @model_validator(mode="after")
    def _prediction_long_enough(self):
        if self.horizon * self.ts_s < MIN_PREDICTION_S - 1e-12:
            raise ValueError(f"horizon x ts_s = {self.horizon} x {self.ts_s:g} s = {self.horizon * self.ts_s:.3g} s: the NMPC "
                             f"must predict >= {MIN_PREDICTION_S} s to plan a stop inside the workspace (horizon >= "
                             f"{math.ceil(MIN_PREDICTION_S / self.ts_s - 1e-9)} at this ts_s)")
        return self
