"""One interface for every relay planner (the paper's generator, baselines A/B, new ones).

A planner is an object with ``update(PlannerInput) -> Reference``, called once per control step
with what the relay knows (``examples/own_planner.py`` is a template). A named planner
(``controller.planner`` in a scenario, for one relay or a network) is built by the factory registered under
its name from a ``PlannerContext``, the parts the composition root (``assembly/parts.py``) made, and declares
what its references carry, which decides the NMPC that flies them (``REFERENCES``):

    @register_planner("name", references="position")
    def _mine(ctx: PlannerContext) -> Planner: ...

(``register_network_planner`` registers a factory for any network under the same name, in the same registry).

or pass a planner object to ``aerorelay.simulate(sc, planner=...)`` without registering it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Protocol, TypeVar

import numpy as np

from ..models import checks
from ..models.mission import SourceTrajectory
from ..models.radio import RadioScene
from ..models.state import YAW, P
from ..models.vehicle import Multirotor
from .plugins import load_entry_points
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
    reference governor's speed (m/s), the eigenvalue floor of ``H11`` after regularization and its rule
    (``relative_floor``: relative to the largest eigenvalue; else the paper's, at least the floor itself)."""

    mu: float = 0.2
    governor_speed_m_s: float = 0.5
    hessian_eig_floor: float = 1e-3
    relative_floor: bool = False


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


class PlannerFailed(RuntimeError):
    """A planner raised, or returned what is not a reference (``ReferenceCheck``): named by its registered name."""


@dataclass
class ReferenceCheck:
    """Every planner's references checked each step, one relay's or a network's, built-in, registered or passed from
    Python (``control.network.NetworkController.plan``), the planner named by ``name``:

    - not a ``{relay: Reference}`` mapping, a reference not a ``Reference`` or a field not a 3-vector
      (``p_opt``, ``p_ref``, ``v_ref``, ``a_ref``; ``axis`` None or one): ``PlannerFailed`` naming the planner,
      the relay, the field and the time (a program error, not a flight's);
    - a relay left out, or a reference with a non-finite number or a zero axis: the relay **holds** where it is
      (its position, no speed, its yaw), counted (``held``) and said once per relay;
    - a position reference outside the relay's workspace: **clipped** into it, counted (``clipped``) and said once
      per relay.

    ``workspaces``: each relay's ``(min, max)`` (m, world). ``first``: the first hold or clip said, per relay."""

    name: str
    workspaces: dict[str, tuple[np.ndarray, np.ndarray]]

    def __post_init__(self):
        self.clipped = dict.fromkeys(self.workspaces, 0)
        self.held = dict.fromkeys(self.workspaces, 0)
        self.first: dict[str, str] = {}

    def _said(self, relay: str, what: str) -> None:
        if relay not in self.first:
            self.first[relay] = what
            log.warning("planner %r: relay %r: %s (later ones counted in metrics.json)", self.name, relay, what)

    def _vector(self, t: float, relay: str, field: str, value) -> np.ndarray:
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            v = None
        if v is None or v.shape != (3,):
            raise PlannerFailed(f"planner {self.name!r} at t = {t:.3f} s: relay {relay!r}: Reference.{field}: must be 3 "
                                f"numbers (x, y, z; m, m/s, m/s^2 world), got {value!r}")
        return v

    def __call__(self, t: float, refs, states) -> dict[str, Reference]:
        """The references to fly: ``refs`` (the planner's) checked for the relays ``states`` (``{relay: x}``, each
        relay's state, ``models.state``) asked of it; references of relays not asked are kept as they are."""
        if not isinstance(refs, Mapping):
            raise PlannerFailed(f"planner {self.name!r} at t = {t:.3f} s: must return {{relay: Reference}}, got "
                                f"{type(refs).__name__}")
        out = dict(refs)
        for relay, x in states.items():
            ref = refs.get(relay)
            why = None
            if ref is None:
                why = "left out of the planner's references: held where it is"
            elif not isinstance(ref, Reference):
                raise PlannerFailed(f"planner {self.name!r} at t = {t:.3f} s: relay {relay!r}: must be a Reference, got "
                                    f"{type(ref).__name__}")
            else:
                vecs = {f: self._vector(t, relay, f, getattr(ref, f)) for f in ("p_opt", "p_ref", "v_ref", "a_ref")}
                axis = None if ref.axis is None else self._vector(t, relay, "axis", ref.axis)
                finite = all(np.isfinite(v).all() for v in vecs.values()) and math.isfinite(float(ref.yaw)) and \
                    (axis is None or (np.isfinite(axis).all() and float(np.linalg.norm(axis)) > 1e-9))
                if not finite:
                    why = (f"a non-finite reference (or a zero axis) at t = {t:.3f} s: held where it is")
            lo, hi = self.workspaces[relay]
            if why is not None:
                self.held[relay] += 1
                self._said(relay, why)
                p = np.clip(np.asarray(x[P], float), lo, hi)
                out[relay] = Reference(p_opt=p, p_ref=p.copy(), v_ref=np.zeros(3), a_ref=np.zeros(3),
                                       yaw=float(x[YAW]) if math.isfinite(float(x[YAW])) else 0.0)
                continue
            assert isinstance(ref, Reference)
            p = vecs["p_ref"]
            clipped = np.clip(p, lo, hi)
            if not np.array_equal(clipped, p):
                self.clipped[relay] += 1
                self._said(relay, f"t = {t:.3f} s: p_ref {np.array2string(p, precision=3)} outside the workspace "
                                  f"[{lo.tolist()}, {hi.tolist()}], clipped to {np.array2string(clipped, precision=3)}")
                out[relay] = replace(ref, p_ref=clipped)
        return out

    def metrics(self) -> dict:
        """``reference_clipped_steps`` and ``reference_held_steps`` summed over the relays, the first said per relay
        (``reference_first``) and the planner's name (each relay's own counts: ``relay_metrics``)."""
        return {"reference_clipped_steps": sum(self.clipped.values()), "reference_held_steps": sum(self.held.values()),
                "reference_first": dict(self.first), "planner_name": self.name}

    def relay_metrics(self, relay: str) -> dict:
        """Relay ``relay``'s ``reference_clipped_steps`` and ``reference_held_steps``."""
        return {"reference_clipped_steps": self.clipped.get(relay, 0), "reference_held_steps": self.held.get(relay, 0)}


PlannerFactory = Callable[[PlannerContext], Planner]
F = TypeVar("F")

# what a planner's references carry, which decides the NMPC that flies them:
#   "alignment": positions; the paper's comms-aware NMPC aligns each relay's antenna toward its neighbours itself
#                (its misalignment terms, eq. 21-22, with controller.variant = "constrained")
#   "axis":      positions and an antenna-axis reference; the tracking NMPC follows both
#   "position":  positions only; the tracking NMPC follows them, the antenna where the flight tilts it
REFERENCES = ("alignment", "axis", "position")


@dataclass(frozen=True)
class PlannerEntry:
    """A planner registered under a name (``controller.planner``): what its references carry (``REFERENCES``) and
    its factories: ``relay`` builds it for one relay (``PlannerContext``), ``network`` for any network (a
    ``planning.fleet.NetworkPlannerContext``). A network flies ``network`` (else ``relay`` on its first relay, the
    others holding their starts); one relay and one source fly ``relay`` (else ``network``)."""

    references: str
    relay: PlannerFactory | None = None
    network: Callable | None = None

    @property
    def tracking(self) -> bool:
        """Whether the tracking NMPC flies its references (else the paper's comms-aware NMPC)."""
        return self.references != "alignment"


PLANNERS: dict[str, PlannerEntry] = {}


def _registrar(kind: str) -> Callable[..., Callable[[F], F]]:
    def register(name: str, *, references: str = "position") -> Callable[[F], F]:
        if references not in REFERENCES:
            raise ValueError(f"register {name!r}: references must be one of {', '.join(REFERENCES)}, got {references!r}")

        def deco(factory: F) -> F:
            entry = PLANNERS.get(name, PlannerEntry(references))
            if getattr(entry, kind) is not None:
                raise ValueError(f"planner {name!r} is registered twice (for {'one relay' if kind == 'relay' else 'a network'})")
            if entry.references != references:
                raise ValueError(f"planner {name!r}: its {kind} factory says its references carry {references!r}, its other "
                                 f"factory {entry.references!r} (one planner, one NMPC)")
            PLANNERS[name] = replace(entry, relay=factory) if kind == "relay" else replace(entry, network=factory)  # type: ignore[arg-type]
            return factory
        return deco
    case = "for one relay (a function of a PlannerContext)" if kind == "relay" else \
        "for any network (a function of a planning.fleet.NetworkPlannerContext)"
    register.__doc__ = (f"Register a planner's factory {case} "
                        "under ``name`` (a decorator: ``@register_...(\"mine\", references=\"position\")``); ``references`` "
                        "says what its references carry and so which NMPC flies them (``REFERENCES``: \"alignment\", the paper's "
                        "comms-aware NMPC; \"axis\" or \"position\", the tracking NMPC). A name registered twice for the same "
                        "case, or with two declarations, is a ValueError.")
    return register


# a planner's one-relay factory under a name (the built-ins: planning/registry.py; register yours before loading the
# scenario that names it)
register_planner = _registrar("relay")
# a planner's network factory under a name (the same registry: one name, one planner, one NMPC)
register_network_planner = _registrar("network")


def planner_entry(name: str) -> PlannerEntry:
    """The planner registered under ``name`` (the installed ``aerorelay.planners`` entry points loaded first when it is
    not); a named error listing the registered ones otherwise."""
    if name not in PLANNERS:  # a user's planners, installed: imported once, when first needed
        load_entry_points()
    try:
        return PLANNERS[name]
    except KeyError:
        raise ValueError(f"controller.planner: no planner registered as {name!r}; registered: {', '.join(sorted(PLANNERS))} "
                         "(register yours with aerorelay.register_planner, or register_network_planner, in a module given as "
                         "aerorelay --plugin MODULE or an aerorelay.planners entry point, before loading the scenario)") from None
