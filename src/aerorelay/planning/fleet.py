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

from ..models.obstacles import inside_any
from ..models.radio import NodePose, RadioScene
from ..models.vehicle import Multirotor
from .base import Planner, PlannerInput, PlannerSettings, registrar
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
    ``G_bar``, the separation to keep (m) and the obstacles grown by their margins."""

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


NetworkPlannerFactory = Callable[[NetworkPlannerContext], FleetPlanner]
NETWORK_PLANNERS: dict[str, NetworkPlannerFactory] = {}


# a network planner's factory under a name for ``network.planner`` (the built-ins: ``planning/registry.py``; register
# yours before loading the scenario that names it)
register_network_planner = registrar(NETWORK_PLANNERS, "network planner")


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
    margin_m: float = 0.05
    workspace_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    workspace_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)


def equidistant_targets(routes: Sequence[Sequence[str]], positions: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each relay's place on its route: relay ``k`` (1-based from the base station) of a route with
    ``K`` relays at ``p_bs + k / (K + 1) (p_source - p_bs)``; a relay on several routes at the mean
    of its places. ``routes``: ``[source, relay, ..., bs]``; ``positions``: the sources' and the base
    station's (m, world)."""
    places: dict[str, list[np.ndarray]] = {}
    for route in routes:
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

    def __init__(self, routes: Sequence[Sequence[str]], relay_starts: Mapping[str, np.ndarray], settings: EquidistantSettings):
        self.routes = [list(r) for r in routes]
        self.settings = settings
        self.refs = {n: np.asarray(p, float).copy() for n, p in relay_starts.items()}
        lo, hi = np.asarray(settings.workspace_min, float), np.asarray(settings.workspace_max, float)
        self.lo, self.hi = lo + settings.margin_m, hi - settings.margin_m

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        targets = equidistant_targets(self.routes, inp.positions)
        out = {}
        for name, ref in self.refs.items():
            goal = np.clip(targets[name], self.lo, self.hi)
            step = goal - ref
            dist = float(np.linalg.norm(step))
            most = self.settings.speed_m_s * inp.dt
            if dist > most:
                step = step * (most / dist)
            new = ref + step
            self.refs[name] = new
            out[name] = Reference(p_opt=goal, p_ref=new.copy(), v_ref=step / inp.dt, a_ref=np.zeros(3))
        return out


@dataclass(frozen=True, kw_only=True)
class FleetCapacitySettings:
    """The fleet's capacity-seeking planner: every ``replan_every`` control steps each relay in turn
    scores its 27 neighbouring goals ``step_m`` (m) apart with every antenna axis it can hold (its
    candidate axes) on the network's rate, the others held; references move at ``speed_m_s`` (m/s)
    and turn at ``axis_rate_deg_s`` (deg/s) inside the workspace box less ``margin_m`` (m)."""

    speed_m_s: float = 1.0
    step_m: float = 0.5
    replan_every: int = 4
    axis_rate_deg_s: float = 30.0
    margin_m: float = 0.05
    workspace_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    workspace_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)
    separation_m: float = 0.0  # goals keep this far (m) from every other vehicle's goal or position, plus GOAL_CLEARANCE_M
    obstacles: tuple = ()  # models.obstacles shapes grown by their margins: no goal inside one


GOAL_CLEARANCE_M = 0.5  # a goal's extra clearance over the separation (m): the NMPC's own margin stays unused

_OFFSETS = np.array([[i, j, k] for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], float)


def _turned(axis: np.ndarray, goal: np.ndarray, most_rad: float) -> np.ndarray:
    """``axis`` turned toward ``goal`` by at most ``most_rad`` (unit vectors)."""
    angle = float(np.arccos(np.clip(axis @ goal, -1.0, 1.0)))
    if angle <= most_rad or angle < 1e-12:
        return goal.copy()
    s = np.sin(angle)
    f = most_rad / angle
    out = (np.sin((1 - f) * angle) * axis + np.sin(f * angle) * goal) / s  # slerp
    return out / np.linalg.norm(out)


class FleetCapacityPlanner:
    """Capacity-seeking references for every relay of a fleet, one relay at a time (coordinate-wise:
    each relay's goal and antenna axis the best of its neighbourhood on the true network rate with
    the others' goals held), from what the fleet knows: the scene's world view with the jammers at the
    positions and powers the fleet was told (``FleetInput.jammer_positions`` / ``jammer_powers``)."""

    def __init__(self, scene: RadioScene, relay_starts: Mapping[str, np.ndarray], candidate_axes: Mapping[str, np.ndarray],
                 settings: FleetCapacitySettings):
        """``candidate_axes``: each relay's holdable antenna axes ``(n, 3)`` (unit, world)."""
        self.scene, self.settings = scene, settings
        self.refs = {n: np.asarray(p, float).copy() for n, p in relay_starts.items()}
        self.goals = {n: p.copy() for n, p in self.refs.items()}
        up = np.array([0.0, 0.0, 1.0])
        self.axis_goals = {n: up.copy() for n in self.refs}
        self.axes = {n: up.copy() for n in self.refs}
        self.candidate_axes = {n: np.asarray(candidate_axes[n], float) for n in self.refs}
        lo, hi = np.asarray(settings.workspace_min, float), np.asarray(settings.workspace_max, float)
        self.lo, self.hi = lo + settings.margin_m, hi - settings.margin_m
        self.k = 0

    def _poses(self, inp: FleetInput) -> dict:
        poses = {n: NodePose(self.goals[n], self.axis_goals[n]) for n in self.refs}
        for n, p in inp.positions.items():
            if n not in self.refs and self.scene.node(n).position is None:
                poses[n] = NodePose(np.asarray(p, float), np.asarray(inp.axes[n], float))
        return poses

    def _replan(self, inp: FleetInput) -> None:
        for name in self.refs:
            poses = self._poses(inp)
            P = np.clip(self.goals[name] + self.settings.step_m * _OFFSETS, self.lo, self.hi)
            B = self.candidate_axes[name]
            others = np.array([np.asarray(p.position, float) for n, p in poses.items() if n != name])
            poses[name] = NodePose(P[:, None, :], B[None, :, :])
            rate = np.array(np.broadcast_to(self.scene.evaluate(inp.t, poses, jammer_positions=inp.jammer_positions,
                                                                jammer_powers=inp.jammer_powers).capacity, (len(P), len(B))))
            rate = np.nan_to_num(rate, nan=-np.inf)  # an undefined rate is never the best
            if self.settings.separation_m > 0 and len(others):
                gap = np.linalg.norm(P[:, None, :] - others[None, :, :], axis=-1).min(axis=1)
                rate[gap < self.settings.separation_m + GOAL_CLEARANCE_M] = -np.inf  # too close to another vehicle
                if not np.isfinite(rate).any():
                    continue  # every neighbour too close: the goal stays
            if self.settings.obstacles:
                rate[inside_any(self.settings.obstacles, P)] = -np.inf  # a goal inside an obstacle's margin
                if not np.isfinite(rate).any():
                    continue
            i, j = np.unravel_index(int(np.argmax(rate)), rate.shape)
            self.goals[name], self.axis_goals[name] = P[i].copy(), B[j].copy()

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        if self.k % self.settings.replan_every == 0:
            self._replan(inp)
        self.k += 1
        out = {}
        most = self.settings.speed_m_s * inp.dt
        for name, ref in self.refs.items():
            step = self.goals[name] - ref
            dist = float(np.linalg.norm(step))
            if dist > most:
                step = step * (most / dist)
            self.refs[name] = ref + step
            self.axes[name] = _turned(self.axes[name], self.axis_goals[name], np.radians(self.settings.axis_rate_deg_s) * inp.dt)
            out[name] = Reference(p_opt=self.goals[name].copy(), p_ref=self.refs[name].copy(), v_ref=step / inp.dt,
                                  a_ref=np.zeros(3), axis=self.axes[name].copy())
        return out
