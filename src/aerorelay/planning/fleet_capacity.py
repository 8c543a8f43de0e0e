"""The fleet's capacity-seeking planner: what the one relay's has, for every relay of a network.

**Before take-off** (``fleet_routes``, from the sources' mission plans and the jammers as the fleet
knows them at its first step, silent where not localized yet; planned again when a jammer becomes
known in flight, the goals unleashed until the first new route is ready): every
``route_dt_s`` the relays' evenly spaced places on their routes, chased from the relays' starts
within the speed and acceleration limits, with each relay's best holdable axis
(``fleet_configuration.FleetConfigurations.best_axes``), then every relay's path optimized jointly on
the network's rate at those limits (``feasible_path.best_feasible_fleet_path``, with the separation): the route the fleet flies near.
That optimization is local, and a jammer splits the places into branches (above it, nulling it with the
antenna's tilt, or on the line's far side): IPOPT from the even places picks one by a hair (two runs of the
network study's two relays at 120 m, their starts 0.1 m apart when the jammer became known, went to opposite
sides). So the route is optimized from ``ROUTE_STARTS``: the even places, and the same shifted to either side of
the line, across it by a quarter of the workspace's width there; the best mean rate is flown. In flight the
solves run one after another beside the control loop, each ready ``ROUTE_LATENCY_S`` after the previous, and a
route replaces the one flown when its mean rate is higher (the first is flown as soon as it is ready).

**In flight**, once every ``max(replan_every, K)`` control steps, the sources predicted
``lookahead_s`` ahead at constant acceleration (their antennas along their thrust): every relay's
27 goals around its current goal ``step_m`` apart (one relay scored per control step, round robin,
so no step scores them all), each with every antenna axis it can hold, kept within ``leash_m`` of
its route at the look-ahead time, are scored on the network's true rate (the jammers as the fleet
knows them) with the other relays at their goals, each relay's candidates in one compiled call
(``planning.relay_grid``). Then the moves are **joint**: every subset of the relays' best moves is
scored in one compiled call (``2^K - 1`` configurations, K <= ``JOINT_SUBSETS_MAX_RELAYS``; beyond
it all moves together or each alone), and the best subset keeping the separation is taken; a relay whose move
is not taken holds its goal brought within the leash (else it stayed put while its route ran on: 4.4 m
behind it for the rest of the network study's 120 m mission after 4.5 s of lost decisions).
Each relay's reference follows its goal through its own
``shaper.ReferenceShaper`` (speed, acceleration, braking on the goal, acceleration feed-forward, axis
rate, the level-only tracking law), the one relay's planner's.

**Yaw** (``yaw_rate_deg_s`` > 0, tilted platforms; ``planning.platform_yaw``, as the one relay's planner): a
relay's candidates are scored with the axes it holds at its yaw goal, and at its best goal every yaw's holdable
axes too; a better yaw travels with the move (taken in the joint decision with it), the yaw reference turns at
<= ``yaw_rate_deg_s`` and the axis reference is clipped to what the relay holds at its measured yaw. The bounds
let a relay yaw freely: at zero yaw the network study's two relays at 120 m had 7.7% less at their own places
(docs/results/networks.md).
"""

from __future__ import annotations

import itertools
import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..models.geometry import E3, thrust_direction_from_acceleration
from ..models.mission import SourceTrajectory
from ..models.obstacles import inside_any
from ..models.radio import NodePose, RadioScene
from ..models.raytrace import RayTracer
from .fleet import FleetInput, equidistant_targets, inner_box, placed_routes
from .fleet_configuration import FleetConfigurations, flyable_fleet_path, mission_poses
from .platform_yaw import PlatformYaw
from .relay_grid import CompiledConfigurations, CompiledRelayGrid
from .shaper import ReferenceShaper, ShaperSettings
from .traced_grid import TracedConfigurations, TracedRelayGrid
from .trajectory_generator import Reference

log = logging.getLogger(__name__)

GOAL_CLEARANCE_M = 0.5  # a goal's extra clearance over the separation (m): the NMPC's own margin stays unused
# a route solved in flight is flown this long after the jammer became known, or after the previous solve (s): it runs
# beside the control loop (one solve: 0.73 s for two relays, 1.27 s for three over the 47 s mission on the 2-core VM,
# 2026-12-04; 0.6-0.9 s for two relays 2026-12-07)
ROUTE_LATENCY_S = 1.5
# the route's first guesses: the even places shifted across the source-base station line by these fractions of the
# workspace's width across it (0: the even places themselves), solved in this order
ROUTE_STARTS = (0.0, -0.25, 0.25)
JOINT_SUBSETS_MAX_RELAYS = 4  # every subset of the relays' moves scored up to this many relays (2^K configurations)
_OFFSETS = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=3)))
_HOLD = 13  # the stencil's centre (offset 0): the goal held, brought within the leash


@dataclass(frozen=True, kw_only=True)
class FleetCapacitySettings:
    """Goals ``step_m`` (m) apart, scored every ``replan_every`` control steps with the sources predicted
    ``lookahead_s`` (s) ahead, kept within ``leash_m`` (m) of the route, ``margin_m`` (m) inside the
    workspace box ``[workspace_min, workspace_max]`` (m, world), ``separation_m`` (m, plus
    ``GOAL_CLEARANCE_M``) from every other vehicle and outside ``obstacles``; ``joint``: the relays' moves
    taken together (else one relay at a time, the others held: the planner before 2026-12-04)."""

    step_m: float = 0.5
    replan_every: int = 4
    lookahead_s: float = 1.0
    leash_m: float = 1.0
    margin_m: float = 0.05
    workspace_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    workspace_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)
    boxes: Mapping[str, tuple] = field(default_factory=dict)  # a relay's own workspace (min, max), where it has one
    separation_m: float = 0.0
    obstacles: tuple = ()
    joint: bool = True


@dataclass(frozen=True)
class FleetRoute:
    """A pre-flight route: times ``(T,)`` (s) and every relay's positions ``(T, K, 3)`` (m, world), relays
    in ``relays`` order, and its planned mean rate."""

    t: np.ndarray
    positions: np.ndarray
    relays: tuple[str, ...]
    mean_rate: float = float("nan")  # the network's mean rate along it as planned (bit/s; nan: not scored)

    def at(self, t: float) -> dict[str, np.ndarray]:
        """Every relay's place on the route at ``t`` (s), linear between its points."""
        return {r: np.array([np.interp(t, self.t, self.positions[:, k, i]) for i in range(3)])
                for k, r in enumerate(self.relays)}


def across_line(scene: RadioScene, positions: Mapping[str, np.ndarray], relays: Sequence[str]) -> dict[str, np.ndarray]:
    """Each relay's horizontal unit vector across its route's line (source to base station, the first route it is
    on, ending where ``equidistant_targets`` places it: ``fleet.placed_routes``; the x axis where the source is
    straight above its base station)."""
    out: dict[str, np.ndarray] = {}
    for route in placed_routes(scene.all_routes, positions, scene.handover):
        d = np.asarray(positions[route[0]], float) - np.asarray(positions[route[-1]], float)
        h = float(np.hypot(d[0], d[1]))
        n = np.array([-d[1] / h, d[0] / h, 0.0]) if h > 1e-9 else np.array([1.0, 0.0, 0.0])
        for r in route[1:-1]:
            out.setdefault(r, n)
    return {r: out.get(r, np.array([1.0, 0.0, 0.0])) for r in relays}


def fleet_routes(scene: RadioScene, sources: Mapping[str, SourceTrajectory], starts: Mapping[str, np.ndarray],
                 tilt_limits: Mapping[str, float], lo, hi, *, t0: float, duration_s: float, dt_s: float, speed_m_s: float,
                 accel_m_s2: float, gravity: float, separation_m: float = 0.0, obstacles: tuple = (),
                 axis_step_deg: float = 10.0, jammer_positions=None, jammer_powers=None,
                 route_starts: Sequence[float] = ROUTE_STARTS) -> list[FleetRoute]:
    """The fleet's routes (module docstring), one per first guess in ``route_starts``, in that order, from ``t0`` to
    ``duration_s`` (s) every ``dt_s``, the relays starting at rest at ``starts`` (m), the jammers where the fleet
    knows them (``jammer_positions`` ``(nJ, 3)`` m, ``jammer_powers`` ``(nJ,)`` W; None: silent, not localized yet)."""
    relays = list(starts)
    p0 = np.stack([starts[r] for r in relays])
    times = np.arange(t0, max(duration_s, t0) + 1e-9, dt_s)
    if len(times) < 2:
        return [FleetRoute(times, np.clip(p0[None], lo, hi), tuple(relays))]
    silent = np.zeros(len(scene.jammers)) if jammer_powers is None else np.asarray(jammer_powers, float)
    configs = FleetConfigurations(scene, relays, lo, hi, tilt_limits, np.radians(axis_step_deg), separation_m, obstacles,
                                  jammer_positions=jammer_positions, jammer_powers=silent)
    poses = [mission_poses(scene, sources, float(t), gravity) for t in times]
    # evenly spaced places at every instant, chased from the starts: IPOPT's first guess (a per-instant refinement
    # of the places on the network's rate first gave the same route, 6x slower: docs/decisions.md)
    places, across = np.empty((len(times), len(relays), 3)), np.empty((len(times), len(relays), 3))
    width = np.asarray(hi, float) - np.asarray(lo, float)
    for i in range(len(times)):
        at = {n: p.position for n, p in poses[i].items()}
        even = equidistant_targets(scene.all_routes, at, scene.handover)
        places[i] = np.stack([even[r] for r in relays])
        n = across_line(scene, at, relays)
        for k, r in enumerate(relays):  # the workspace's width along n (its unbounded axes n does not cross aside)
            w = float(np.sum(np.abs(n[r]) * np.where(n[r] != 0.0, width, 0.0)))
            across[i, k] = n[r] * w if np.isfinite(w) else np.nan
    if not np.isfinite(across).all():  # unbounded across the line: no width to shift by, the even places alone
        across, route_starts = np.zeros_like(across), route_starts[:1]
    out = []
    for shift in route_starts:
        fleet = flyable_fleet_path(configs, times, places + shift * across, p0, poses,
                                   speed_m_s=speed_m_s, accel_m_s2=accel_m_s2, gravity=gravity, max_iter=200)
        mean = float(np.mean(fleet.capacity))
        log.info("fleet route from %+.2f of the width across: %d instants from %.1f s, mean rate %.6g, %s", shift,
                 len(times), t0, mean, fleet.status)
        out.append(FleetRoute(times, fleet.position, tuple(relays), mean))
    return out


def best_route(routes: Sequence[FleetRoute]) -> FleetRoute:
    """The route of highest planned mean rate (the first of equals; an unscored route loses to a scored one)."""
    return max(routes, key=lambda r: -np.inf if np.isnan(r.mean_rate) else r.mean_rate)


def fleet_route(*args, **kwargs) -> FleetRoute:
    """The best of ``fleet_routes`` (same arguments): the route flown before take-off."""
    return best_route(fleet_routes(*args, **kwargs))


class FleetCapacityPlanner:
    """Capacity-seeking references for every relay of a fleet (module docstring), from what the fleet
    knows: the scene's world view with the jammers at the positions and powers the fleet was told
    (``FleetInput.jammer_positions`` / ``jammer_powers``)."""

    def __init__(self, scene: RadioScene, relay_starts: Mapping[str, np.ndarray], candidate_axes: Mapping[str, np.ndarray],
                 shapers: Mapping[str, ShaperSettings], settings: FleetCapacitySettings,
                 route_builder: Callable[..., Sequence[FleetRoute]] | None = None, tracer: RayTracer | None = None,
                 traced_coherent: bool = False, yaws: Mapping[str, PlatformYaw] | None = None):
        """``candidate_axes``: each relay's holdable antenna axes ``(n, 3)`` (unit, world); ``shapers`` each relay's
        reference limits; ``route_builder(t0, starts, jammer_positions, jammer_powers)`` plans the routes
        (``fleet_routes``, in the order they are solved; None: no route, no leash): before the first step with what
        the fleet knows then, and again when a jammer becomes known in flight (its power from 0 to above;
        ``preflight_s`` the first, ``reroute_s`` the others, s). ``tracer``: the candidates and the joint moves scored
        on the ray-traced channel of the scene's map (``planning.traced_grid``; ``traced_coherent``: its paths summed
        with their phases), the route planned on the scene's analytic channel (IPOPT through thousands of traces is
        not flyable on a CPU). ``yaws``: the relays that may yaw, each one's ``PlatformYaw`` (its ``body_axes`` its
        ``candidate_axes``)."""
        self.scene, self.settings, self.route_builder = scene, settings, route_builder
        self.route: FleetRoute | None = None
        self.preflight_s, self.reroute_s = 0.0, list[float]()
        self.known: tuple[bool, ...] | None = None
        self.pending: list[tuple[float, FleetRoute]] = []  # routes planned in flight: when each is ready (s), the route
        self.off_loop_s = 0.0  # this step's work beside the control loop (s)
        self.relays = list(relay_starts)
        self.shapers = {n: ReferenceShaper(shapers[n]) for n in self.relays}
        self.box = {n: inner_box(settings.boxes.get(n, (settings.workspace_min, settings.workspace_max)), settings.margin_m)
                    for n in self.relays}
        for n, p in relay_starts.items():
            self.shapers[n].p_ref = np.clip(np.asarray(p, float), *self.box[n])
        self.goals = {n: self.shapers[n].p_ref.copy() for n in self.relays}  # type: ignore[union-attr]
        self.axis_goals = {n: E3.copy() for n in self.relays}
        self.axes = {n: np.asarray(candidate_axes[n], float) for n in self.relays}
        # each relay's goals x axes scored in one compiled call (planning.relay_grid), the other sources and relays given
        self.sources = [n.name for n in scene.nodes if n.role == "source"]
        self.grids: dict[str, CompiledRelayGrid | TracedRelayGrid]
        if tracer is None:
            self.grids = {n: CompiledRelayGrid(scene, len(_OFFSETS), len(self.axes[n]), source=self.sources[0], relay=n,
                                               moving=self._moving(n)) for n in self.relays}
        else:
            self.grids = {n: TracedRelayGrid(scene, tracer, source=self.sources[0], relay=n, moving=self._moving(n),
                                             coherent=traced_coherent) for n in self.relays}
        self.yaws = dict(yaws or {})
        # every yaw's holdable axes at a relay's best goal, one compiled call
        self.yaw_grids = {n: (CompiledRelayGrid(scene, 1, len(y.all_axes()), source=self.sources[0], relay=n, moving=self._moving(n))
                              if tracer is None else self.grids[n]) for n, y in self.yaws.items()}
        K = len(self.relays)
        # the joint moves' configurations: every non-empty subset of the relays up to JOINT_SUBSETS_MAX_RELAYS, beyond
        # it all relays together and each alone
        self.subsets = ([tuple(c) for r in range(1, K + 1) for c in itertools.combinations(range(K), r)]
                        if K <= JOINT_SUBSETS_MAX_RELAYS else [tuple(range(K))] + [(j,) for j in range(K)])
        self.configurations = (CompiledConfigurations(scene, tuple(self.relays), tuple(self.sources), len(self.subsets))
                               if tracer is None else
                               TracedConfigurations(scene, tracer, tuple(self.relays), tuple(self.sources), coherent=traced_coherent))
        self.cycle = max(settings.replan_every, K)  # steps between two decisions
        self.scored: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}
        self.scored_yaw: dict[int, float] = {}  # a relay's better yaw goal (rad), taken with its move
        self.held: dict[int, np.ndarray] = {}
        self.gravity = next(iter(shapers.values())).gravity if shapers else 9.81
        self.k = 0

    def _moving(self, relay: str) -> tuple[str, ...]:
        """The moving nodes whose poses ``relay``'s grid is given: the sources after the first, the other relays."""
        return tuple(self.sources[1:] + [n for n in self.relays if n != relay])

    def _others(self, inp: FleetInput) -> dict[str, NodePose]:
        """Every non-relay vehicle (the sources) predicted ``lookahead_s`` ahead at constant acceleration, its
        antenna along its thrust (as the one relay's planner predicts MRAV-2)."""
        tau, out = self.settings.lookahead_s, {}
        for n, p in inp.positions.items():
            if n in self.shapers or self.scene.node(n).position is not None:
                continue
            v = np.asarray(inp.velocities.get(n, np.zeros(3)), float)
            a = np.asarray(inp.accelerations.get(n, np.zeros(3)), float)
            out[n] = NodePose(np.asarray(p, float) + v * tau + 0.5 * a * tau**2, thrust_direction_from_acceleration(a, self.gravity))
        return out

    def _candidates(self, t: float, j: int) -> np.ndarray:
        """``(27, 3)``: relay ``j``'s stencil around its goal, within the leash of its route at ``t`` and in the box."""
        n = self.relays[j]
        cand = self.goals[n] + self.settings.step_m * _OFFSETS
        if self.route is not None:
            anchor = self.route.at(t)[n]
            off = cand - anchor
            d = np.linalg.norm(off, axis=1, keepdims=True)
            lim = self.settings.leash_m
            cand = np.where(d > lim, anchor + off * (lim / np.maximum(d, 1e-12)), cand)
        return np.clip(cand, *self.box[n])

    def _blocked(self, P: np.ndarray, others: np.ndarray) -> np.ndarray:
        """True where a goal (``P (..., 3)``) is too close to a vehicle in ``others (M, 3)`` or inside an obstacle."""
        bad = np.zeros(P.shape[:-1], bool)
        if self.settings.separation_m > 0 and len(others):
            gap = np.linalg.norm(P[..., None, :] - others, axis=-1).min(axis=-1)
            bad |= gap < self.settings.separation_m + GOAL_CLEARANCE_M
        if self.settings.obstacles:
            bad |= inside_any(self.settings.obstacles, P.reshape(-1, 3)).reshape(P.shape[:-1])
        return bad

    def _jammers(self, inp: FleetInput) -> tuple[np.ndarray, np.ndarray]:
        nj = len(self.scene.jammers)
        jp = np.zeros((nj, 3)) if inp.jammer_positions is None else np.asarray(inp.jammer_positions, float)
        return jp, np.zeros(nj) if inp.jammer_powers is None else np.asarray(inp.jammer_powers, float)

    def _score(self, inp: FleetInput, j: int) -> None:
        """Relay ``j``'s goals x axes around its goal (the leash, the box, the sources predicted ahead) on the
        network's rate with the others at their goals, in one compiled call; its best kept for the decision."""
        n, others = self.relays[j], self._others(inp)
        cand = self._candidates(inp.t + self.settings.lookahead_s, j)
        here = {**others, **{m: NodePose(self.goals[m], self.axis_goals[m]) for m in self.relays}}
        yaw = self.yaws.get(n)
        axes = self.axes[n] if yaw is None else yaw.axes()
        moving = tuple(here[m] for m in self._moving(n))
        rate = self.grids[n](cand, axes, here[self.sources[0]], *self._jammers(inp), moving)
        rate = np.nan_to_num(rate, nan=-np.inf)
        vehicles = np.array([np.asarray(p.position, float) for p in others.values()]).reshape(-1, 3)
        rate[self._blocked(cand, np.concatenate([vehicles, *[self.goals[m][None] for m in self.relays if m != n]]))] = -np.inf
        i, b = np.unravel_index(int(np.argmax(rate)), rate.shape)
        self.scored[j] = (cand[i].copy(), axes[b].copy(), float(rate[i, b]))
        self.scored_yaw.pop(j, None)
        if yaw is not None and np.isfinite(rate[i, b]):  # every yaw's axes at the best goal: a better yaw goes with the move
            every = yaw.all_axes()
            c = np.nan_to_num(self.yaw_grids[n](cand[i:i + 1], every, here[self.sources[0]], *self._jammers(inp), moving)[0],
                              nan=-np.inf)
            k = yaw.better(c, float(rate[i, b]))
            if k is not None:
                self.scored[j], self.scored_yaw[j] = (cand[i].copy(), every[k].copy(), float(c[k])), yaw.yaw_of(k)
        # holding: the goal brought within the leash (the route moves on: a relay whose move is not taken still follows it)
        self.held[j] = cand[_HOLD].copy() if np.isfinite(rate[_HOLD]).any() else self.goals[n].copy()

    def _decide(self, inp: FleetInput) -> None:
        """Every relay scored since the last decision: the relays' best moves taken jointly (``_joint``) or the
        best one alone."""
        movers = [j for j, sc in self.scored.items() if np.isfinite(sc[2])]
        for j, p in self.held.items():  # every relay within its leash, moved or not
            self.goals[self.relays[j]] = p
        if movers:
            gain = {j: self.scored[j][2] for j in movers}
            chosen = self._joint(inp, movers) if self.settings.joint else [max(gain, key=gain.__getitem__)]
            for j in chosen:
                n = self.relays[j]
                self.goals[n], self.axis_goals[n] = self.scored[j][0].copy(), self.scored[j][1].copy()
                if j in self.scored_yaw:
                    self.yaws[n].goal = self.scored_yaw[j]
        self.scored.clear()
        self.scored_yaw.clear()
        self.held.clear()

    def _joint(self, inp: FleetInput, movers: list[int]) -> list[int]:
        """The subset of the relays' best moves whose configuration rates best and keeps the separation
        between the relays' goals, every subset scored in one compiled call (``subsets``)."""
        goals = np.stack([self.goals[n] for n in self.relays])
        axis_goals = np.stack([self.axis_goals[n] for n in self.relays])
        P = np.broadcast_to(goals, (len(self.subsets), *goals.shape)).copy()
        A = np.broadcast_to(axis_goals, (len(self.subsets), *axis_goals.shape)).copy()
        ok = np.array([all(j in movers for j in sub) for sub in self.subsets])
        for s, sub in enumerate(self.subsets):  # every relay was scored before the decision
            for j in sub:
                P[s, j], A[s, j] = self.scored[j][0], self.scored[j][1]
        others = self._others(inp)
        rate = self.configurations(P, A, tuple(others[n] for n in self.sources), *self._jammers(inp))
        rate = np.where(ok, np.nan_to_num(rate, nan=-np.inf), -np.inf)
        if self.settings.separation_m > 0:
            K = goals.shape[0]
            for c in np.flatnonzero(np.isfinite(rate)):
                gaps = [np.linalg.norm(P[c, a] - P[c, b]) for a in range(K) for b in range(a + 1, K)]
                if gaps and min(gaps) < self.settings.separation_m + GOAL_CLEARANCE_M:
                    rate[c] = -np.inf
        if not np.isfinite(rate).any():
            gain = {j: self.scored[j][2] for j in movers}
            return [max(gain, key=gain.__getitem__)]
        return list(self.subsets[int(np.argmax(rate))])

    def _route_with_what_is_known(self, inp: FleetInput) -> None:
        """The routes planned at the first step (before take-off, ``preflight_s``: the best is flown), and planned
        again from the references' places when a jammer becomes known (``reroute_s``): work a flight computer runs
        beside the control loop, so its time is kept apart (``off_loop_s``, not in the step's). The old route did not
        know the jammer, so the goals climb unleashed until the first new route is ready, ``ROUTE_LATENCY_S`` after
        the jammer became known; each further route is ready ``ROUTE_LATENCY_S`` after the previous (one solve each)
        and replaces the one flown when it plans a higher mean rate."""
        self.off_loop_s = 0.0
        while self.pending and inp.t >= self.pending[0][0] - 1e-9:
            route = self.pending.pop(0)[1]
            self.route = route if self.route is None else best_route([self.route, route])  # the one flown wins ties
        known = None if inp.jammer_powers is None else tuple(bool(p > 0) for p in np.asarray(inp.jammer_powers, float))
        if self.route_builder is None or (self.k > 0 and known == self.known):
            return
        first, self.known = self.k == 0, known
        t0 = time.perf_counter()
        starts = {n: self.shapers[n].p_ref.copy() for n in self.relays}  # type: ignore[union-attr]
        routes = list(self.route_builder(inp.t, starts, inp.jammer_positions, inp.jammer_powers))
        self.off_loop_s = time.perf_counter() - t0
        if first and inp.t <= 1e-9:  # before take-off
            self.route, self.preflight_s, self.pending = best_route(routes), self.off_loop_s, []
        else:  # in flight (a jammer newly known, or a smaller fleet's planner after a loss): the old route, planned
            # without what is known now, no longer leashes the goals while the new ones are planned
            self.route = None
            self.pending = [(inp.t + (i + 1) * ROUTE_LATENCY_S, r) for i, r in enumerate(routes)]
            self.reroute_s.append(self.off_loop_s)

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        self._route_with_what_is_known(inp)
        slot = self.k % self.cycle  # round robin: one relay scored per step, the moves decided once all are
        if slot < len(self.relays):
            self._score(inp, slot)
            if slot == len(self.relays) - 1:
                self._decide(inp)
        self.k += 1
        out = {}
        for n in self.relays:
            sh = self.shapers[n]
            v_ref = sh.advance(self.goals[n], inp.dt)
            sh.turn_axis(self.axis_goals[n], inp.dt)
            # the axis the relay holds at its measured yaw while it turns
            yaw, axis_now = ((0.0, sh.axis) if n not in self.yaws else
                             self.yaws[n].turn(sh.axis, float(inp.yaws.get(n, 0.0)), inp.dt))
            axis = sh.held_axis(axis_now)
            assert sh.p_ref is not None
            out[n] = Reference(p_opt=self.goals[n].copy(), p_ref=sh.p_ref.copy(), v_ref=v_ref,
                               a_ref=sh.acceleration(inp.positions.get(n, sh.p_ref), inp.velocities.get(n), axis), axis=axis,
                               yaw=yaw)
        return out
