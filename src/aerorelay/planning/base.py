"""One interface for every relay planner (the paper's generator, baselines A/B, new ones).

A planner is an object with ``update(PlannerInput) -> Reference``, called once per control step
with what the relay knows (``examples/own_planner.py`` is a template). A named planner
(``controller.planner`` in a scenario) is built by the factory registered under its name from a
``PlannerContext``, the parts the composition root (``assembly/parts.py``) made:

    @register_planner("name")
    def _mine(ctx: PlannerContext) -> Planner: ...

or pass a planner object to ``aerorelay.simulate(sc, planner=...)`` without registering it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol, TypeVar

import numpy as np

from ..models import checks
from ..models.mission import SourceTrajectory
from ..models.radio import RadioScene
from ..models.vehicle import Multirotor
from .trajectory_generator import Reference


@dataclass(frozen=True, kw_only=True)
class PlannerInput:
    """What the relay knows at one control step (world frame, SI units).

    ``jammer_positions`` ``(nJ, 3)`` m: the (possibly noisy) localized positions;
    ``jammer_powers`` ``(nJ,)`` W: the powers the planner should assume (0 before a jammer is
    localized, see ``sim.closed_loop``); ``jammer_std_m`` ``(nJ,)``: the largest position std of
    an estimated jammer (m; None when the positions are the oracle's).
    """

    t: float
    dt: float
    p1: np.ndarray
    p2: np.ndarray
    v2: np.ndarray
    a2: np.ndarray
    jammer_positions: np.ndarray
    jammer_powers: np.ndarray
    jammer_std_m: np.ndarray | None = None
    psi1: float = 0.0  # the relay's measured yaw, rad
    v1: np.ndarray | None = None  # the relay's measured velocity, m/s (None: not given)


@dataclass(frozen=True, kw_only=True)
class GeneratorSettings:
    """The paper's trajectory generator (and baselines A/B): the surrogate's alignment ``mu``, the
    reference governor's speed (m/s), the eigenvalue floor of ``H11`` after regularization."""

    mu: float = 0.2
    governor_speed_m_s: float = 0.5
    hessian_eig_floor: float = 1e-3


@dataclass(frozen=True, kw_only=True)
class CapacityPlannerSettings:
    """The capacity-seeking planner (``[controller.capacity]``; meanings and units there):
    reference speed (m/s) and accelerations (m/s^2), margins and leash (m), the pre-flight route's
    grid (m, s), look-ahead (s), antenna axes (deg, deg/s, fraction of the tilt limit), the
    observability excursion (m, m, fraction), yaw (deg/s), the level-only tracking frequency
    (rad/s), the scoring and how often it replans (steps)."""

    speed_m_s: float = 1.0
    replan_every: int = 4
    step_m: float = 0.3
    leash_m: float = 1.0
    lookahead_s: float = 1.0
    axis_step_deg: float = 5.0
    axis_rate_deg_s: float = 30.0
    margin_m: float = 0.05
    route_grid_m: float = 1.0
    route_dt_s: float = 1.0
    accel_tau_s: float = 0.3
    max_accel_m_s2: float = 4.0
    brake_accel_m_s2: float = 1.5
    excursion_m: float = 0.0
    excursion_std_m: float = 1.0
    excursion_max_loss: float = 0.05
    yaw_rate_deg_s: float = 0.0
    tilt_fraction: float = 0.85
    boundary_axes: bool = True
    tracking_freq_rad_s: float = 1.0
    scoring: str = "joint"

    def __post_init__(self):
        checks.one_of("CapacityPlannerSettings", "scoring", self.scoring, ("joint", "decoupled", "traced"))


@dataclass(frozen=True, kw_only=True)
class PlannerSettings:
    """Every built-in planner's settings (a part is built from these, never from a scenario)."""

    generator: GeneratorSettings = GeneratorSettings()
    capacity: CapacityPlannerSettings = CapacityPlannerSettings()


@dataclass(frozen=True, kw_only=True)
class PlannerContext:
    """What a planner is built from: the relay's world view of the radio scene, MRAV-2's planned
    path, the relay vehicle (built once, with its hover-tilt limits), the workspace box (m), the
    relay's start (m), the mission length (s), the planners' typed settings and the surrogate's
    ``G_bar``."""

    scene: RadioScene
    source: SourceTrajectory
    vehicle: Multirotor
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    relay_start: np.ndarray
    duration_s: float
    settings: PlannerSettings = PlannerSettings()
    surrogate_g_bar: float = 1.0  # G_bar of the generator's surrogate (eq. 12-13)
    obstacles: tuple = ()  # models.obstacles shapes grown by their margins: no position inside is a goal
    source_clearance_m: float = 0.0  # no goal closer than this to the source (now or as predicted), m
    tracer: object | None = None  # a models.raytrace.RayTracer of the scene's map (scoring "traced"), None: analytic
    traced_coherent: bool = False  # the traced paths summed with their phases


class Planner(Protocol):
    def update(self, inp: PlannerInput) -> Reference: ...


log = logging.getLogger(__name__)


class CheckedPlanner:
    """A user's planner behind the API's boundary check: every ``Reference`` it returns must carry
    3-vectors of finite numbers (``p_opt``, ``p_ref``, ``v_ref``, ``a_ref``; ``axis`` None or a
    non-zero 3-vector; finite ``yaw``), else InvalidInput naming the field and the step; a position
    reference outside the workspace box is clipped into it, logged once, and counted
    (``clipped_steps``, ``first_clip``: metrics.json's ``reference_clipped_steps``)."""

    def __init__(self, planner: Planner, workspace_min, workspace_max):
        self.planner = planner
        self.lo, self.hi = np.asarray(workspace_min, float), np.asarray(workspace_max, float)
        self.clipped_steps = 0
        self.first_clip: str | None = None

    def __getattr__(self, name: str):  # the wrapped planner's own attributes (e.g. preflight_s for the bench)
        if name == "planner":
            raise AttributeError(name)
        return getattr(self.planner, name)

    def update(self, inp: PlannerInput) -> Reference:
        ref = self.planner.update(inp)
        who = f"planner {type(self.planner).__name__} at t = {inp.t:.3f} s: Reference"
        if not isinstance(ref, Reference):
            raise checks.InvalidInput(f"planner {type(self.planner).__name__}.update must return a Reference, "
                                      f"got {type(ref).__name__}")
        vecs = {f: checks.vector(who, f, getattr(ref, f)) for f in ("p_opt", "p_ref", "v_ref", "a_ref")}
        if ref.axis is not None:
            checks.vector(who, "axis", ref.axis, nonzero=True)
        checks.number(who, "yaw", ref.yaw)
        p = vecs["p_ref"]
        clipped = np.clip(p, self.lo, self.hi)
        if np.array_equal(clipped, p):
            return ref
        self.clipped_steps += 1
        if self.first_clip is None:
            self.first_clip = (f"t = {inp.t:.3f} s: p_ref {np.array2string(p, precision=3)} outside the workspace "
                               f"[{self.lo.tolist()}, {self.hi.tolist()}], clipped to {np.array2string(clipped, precision=3)}")
            log.warning("planner %s: %s (later clips counted in metrics.json)", type(self.planner).__name__, self.first_clip)
        return replace(ref, p_ref=clipped)


PlannerFactory = Callable[[PlannerContext], Planner]
PLANNERS: dict[str, PlannerFactory] = {}
F = TypeVar("F")


def registrar(registry: dict[str, F], what: str) -> Callable[[str], Callable[[F], F]]:
    """A decorator factory registering factories in ``registry`` by name (``what`` names the kind in the error
    raised for a name registered twice)."""
    def register(name: str) -> Callable[[F], F]:
        def deco(factory: F) -> F:
            if name in registry:
                raise ValueError(f"{what} {name!r} is registered twice")
            registry[name] = factory
            return factory
        return deco
    register.__doc__ = (f"Register a {what} factory under ``name`` (a decorator: ``@register_...(\"mine\")`` above a "
                        f"function taking the {what}'s context and returning it); a name registered twice is a ValueError.")
    return register


register_planner = registrar(PLANNERS, "planner")  # a planner factory under a name (the built-ins: planning/registry.py)


def planner_factory(name: str) -> PlannerFactory:
    """The factory registered under ``name``; a named error listing the registered ones otherwise."""
    try:
        return PLANNERS[name]
    except KeyError:
        raise ValueError(f"controller.planner: unknown planner {name!r}; registered: {', '.join(sorted(PLANNERS))}") from None
