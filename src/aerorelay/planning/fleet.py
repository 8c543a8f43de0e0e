"""Planners for a fleet of relays (``[[relays]]``): one call per control step plans every relay.

A fleet planner is an object with ``update(FleetInput) -> dict[relay name, Reference]``, called with
what the fleet knows: every relay's measured state and every source's position over its optical
link. ``EquidistantPlanner`` is what operators do today (Pinto & Almeida, Sensors 2022, compare
optimized chains against it): each relay on its route's straight line from the base station to the
source, evenly spaced.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..models.mission import SourceTrajectory
from ..models.radio import RadioScene
from ..models.raytrace import RayTracer
from ..models.vehicle import Multirotor
from .base import Planner, PlannerInput, PlannerSettings
from .trajectory_generator import Reference


@dataclass(frozen=True, kw_only=True)
class FleetInput:
    """What the fleet knows at one control step (world frame, SI units): every vehicle's position
    (m), velocity (m/s) and antenna axis (unit) by node name (relays: measured; sources: over their
    optical links), the sources' accelerations (m/s^2); the jammers' positions ``(nJ, 3)`` (m) and the powers to plan with ``(nJ,)`` (W:
    0 before a jammer is localized)."""

    t: float
    dt: float
    positions: Mapping[str, np.ndarray]
    velocities: Mapping[str, np.ndarray]
    axes: Mapping[str, np.ndarray] = field(default_factory=dict)
    accelerations: Mapping[str, np.ndarray] = field(default_factory=dict)
    jammer_positions: np.ndarray | None = None
    jammer_powers: np.ndarray | None = None
    jammer_std_m: np.ndarray | None = None  # an estimate's largest position std per jammer (m; None: the oracle's)
    yaws: Mapping[str, float] = field(default_factory=dict)  # every relay's measured yaw (rad)


class FleetPlanner(Protocol):
    def update(self, inp: FleetInput) -> dict[str, Reference]: ...


@dataclass(frozen=True, kw_only=True)
class NetworkPlannerContext:
    """What a network's planner is built from: the network's world view of the radio scene (no true
    jammer), its routes (``[source, relay, ..., bs]``), every relay's start (m, world) and vehicle, the
    base station's position (m), the workspace box (m), the planners' typed settings, the surrogate's
    ``G_bar``, the separation to keep (m), the obstacles grown by their margins, the sources' mission plans,
    the mission's length, the time it starts flying (s) and the pre-flight route's settings."""

    scene: RadioScene
    routes: Sequence[Sequence[str]]
    starts: Mapping[str, np.ndarray]
    vehicles: Mapping[str, Multirotor]
    bs_position: np.ndarray
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    settings: PlannerSettings = PlannerSettings()
    surrogate_g_bar: float = 1.0
    separation_m: float = 0.0
    obstacles: tuple = ()
    sources: Mapping[str, SourceTrajectory] = field(default_factory=dict)  # each source's mission plan (pre-flight routes)
    duration_s: float = 0.0  # the mission's length (s)
    t0_s: float = 0.0  # when this planner starts flying (s; a smaller fleet's after a loss)
    route_dt_s: float = 2.0  # a pre-flight route's time step (s)
    route: bool = True  # whether a planner that can plan a pre-flight route does
    tracer: RayTracer | None = None  # the scene's ray tracer when candidates are scored on the traced channel
    traced_coherent: bool = False  # ... and whether its paths are summed with their phases
    relay_settings: Mapping[str, PlannerSettings] = field(default_factory=dict)  # a relay's own ([[relays.controller]])
    # a relay's own workspace ([relays.controller.workspace]) as (min, max), m; workspace_min/max then bound them all
    boxes: Mapping[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    def settings_of(self, name: str) -> PlannerSettings:
        """Relay ``name``'s own planner settings (its ``[relays.controller]`` over ``[controller]``): its speed and
        acceleration limits, tilt fraction, axes and governor; the network-wide ones are ``settings``'."""
        return self.relay_settings.get(name, self.settings)

    def box_of(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Relay ``name``'s workspace (min, max), m: its own, else the network's."""
        lo, hi = self.boxes.get(name, (self.workspace_min, self.workspace_max))
        return np.asarray(lo, float), np.asarray(hi, float)


NetworkPlannerFactory = Callable[[NetworkPlannerContext], FleetPlanner]


def held_reference(position: np.ndarray) -> Reference:
    """A reference that holds ``position`` (m, world): at rest, no antenna axis asked."""
    p = np.asarray(position, float)
    return Reference(p_opt=p.copy(), p_ref=p.copy(), v_ref=np.zeros(3), a_ref=np.zeros(3))


class OneRelayPlanner:
    """A one-relay planner (``planning.base.Planner``: the registry's or a user's) as a network's planner:
    it plans ``relay`` with ``source`` as its MRAV-2 (for the paper's one relay, the only ones); every
    relay in ``held`` (name -> position, m) holds there. Its input is the network's, read for the one
    relay: its measured position, velocity and yaw, the source's position over its optical link, the
    jammers as known (``FleetInput``)."""

    def __init__(self, planner: Planner, relay: str, source: str, held: Mapping[str, np.ndarray] | None = None):
        self.planner, self.relay, self.source = planner, relay, source
        self.held = {n: held_reference(p) for n, p in (held or {}).items()}

    def __getattr__(self, name: str):  # the wrapped planner's own attributes (preflight_s for the bench, counters)
        if name == "planner":
            raise AttributeError(name)
        return getattr(self.planner, name)

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        r, s = self.relay, self.source
        assert inp.jammer_positions is not None and inp.jammer_powers is not None  # the loop always tells them
        ref = self.planner.update(PlannerInput(
            t=inp.t, dt=inp.dt, p1=inp.positions[r], p2=inp.positions[s], v2=inp.velocities[s], a2=inp.accelerations[s],
            jammer_positions=inp.jammer_positions, jammer_powers=inp.jammer_powers, jammer_std_m=inp.jammer_std_m,
            psi1=float(inp.yaws.get(r, 0.0)), v1=inp.velocities.get(r)))
        return {r: ref, **self.held}


@dataclass(frozen=True, kw_only=True)
class EquidistantSettings:
    """The reference moves toward its target at most ``speed_m_s`` (m/s) and stays ``margin_m`` (m)
    inside the workspace box ``[workspace_min, workspace_max]`` (m, world)."""

    speed_m_s: float = 1.0
    speeds_m_s: Mapping[str, float] = field(default_factory=dict)  # a relay's own limit, where it has one
    margin_m: float = 0.05
    workspace_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    workspace_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)
    boxes: Mapping[str, tuple] = field(default_factory=dict)  # a relay's own workspace (min, max), where it has one


def inner_box(box, margin_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``box`` = (min, max) (m) shrunk by ``margin_m`` on every side."""
    return np.asarray(box[0], float) + margin_m, np.asarray(box[1], float) - margin_m


def placed_routes(routes: Sequence[Sequence[str]], positions: Mapping[str, np.ndarray],
                  ends: Sequence[Sequence[str]] = ()) -> list[tuple[str, ...]]:
    """Each route as the planners lay their relays along it: ``[source, relay, ..., bs]`` with ``bs`` the base
    station nearest its source among those it may end at (``ends[i]``, ``RadioScene.handover``; empty or
    missing: its own end). The one place that decides which line a route's relays are placed on."""
    out = []
    for i, route in enumerate(routes):
        route = tuple(route)
        if i < len(ends) and ends[i]:
            p_src = np.asarray(positions[route[0]], float)
            bs = min(ends[i], key=lambda b: float(np.linalg.norm(np.asarray(positions[b], float) - p_src)))
            route = (*route[:-1], bs)
        out.append(route)
    return out


def equidistant_targets(routes: Sequence[Sequence[str]], positions: Mapping[str, np.ndarray],
                        ends: Sequence[Sequence[str]] = ()) -> dict[str, np.ndarray]:
    """Each relay's place on its route: relay ``k`` (1-based from the base station) of a route with
    ``K`` relays at ``p_bs + k / (K + 1) (p_source - p_bs)``; a relay on several routes at the mean
    of its places. ``routes``: ``[source, relay, ..., bs]``; ``positions``: the sources' and the base
    stations' (m, world); ``ends``: per route, the base stations it may end at (``RadioScene.handover``;
    empty: its own end): the one nearest its source is its ``bs``."""
    places: dict[str, list[np.ndarray]] = {}
    for route in placed_routes(routes, positions, ends):
        src, relays, bs = route[0], list(route[1:-1]), route[-1]
        p_src, p_bs = np.asarray(positions[src], float), np.asarray(positions[bs], float)
        n = len(relays)
        for k, name in enumerate(reversed(relays), start=1):  # counted from the base station
            places.setdefault(name, []).append(p_bs + k / (n + 1) * (p_src - p_bs))
    return {name: np.mean(p, axis=0) for name, p in places.items()}


class EquidistantPlanner:
    """Relays evenly spaced on the line from the base station to their source
    (``equidistant_targets``), each reference moving toward its place at a speed limit and kept
    inside the workspace; no antenna-axis reference (the thrust direction follows the flight, as an
    operator's relay flies)."""

    def __init__(self, routes: Sequence[Sequence[str]], relay_starts: Mapping[str, np.ndarray], settings: EquidistantSettings,
                 ends: Sequence[Sequence[str]] = ()):
        """``ends``: per route, the base stations it may end at (``equidistant_targets``)."""
        self.routes = [list(r) for r in routes]
        self.ends = [list(e) for e in ends]
        self.settings = settings
        self.refs = {n: np.asarray(p, float).copy() for n, p in relay_starts.items()}
        self.box = {n: inner_box(settings.boxes.get(n, (settings.workspace_min, settings.workspace_max)), settings.margin_m)
                    for n in self.refs}

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        targets = equidistant_targets(self.routes, inp.positions, self.ends)
        out = {}
        for name, ref in self.refs.items():
            goal = np.clip(targets[name], *self.box[name])
            step = goal - ref
            dist = float(np.linalg.norm(step))
            most = self.settings.speeds_m_s.get(name, self.settings.speed_m_s) * inp.dt
            if dist > most:
                step = step * (most / dist)
            new = ref + step
            self.refs[name] = new
            out[name] = Reference(p_opt=goal, p_ref=new.copy(), v_ref=step / inp.dt, a_ref=np.zeros(3))
        return out
