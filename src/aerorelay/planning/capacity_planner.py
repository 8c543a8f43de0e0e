"""Capacity-seeking relay planner: references from the true, antenna-aware capacity (beyond the paper).

Two layers. **Before take-off** (like baseline B, from MRAV-2's mission plan, without the jammer,
which is not localized yet): a coarse route, the max-mean path through the capacity landscape
(best holdable antenna axis per cell) on a ``route_grid_m`` grid every ``route_dt_s`` at the
planner's speed limit, by the dynamic programming of ``planning/bound.py`` (with ``scoring = "traced"`` on
the ray-traced channel at the grid's cells: the scene's map traced from the source's plan at each instant). It picks the basin of
the landscape to be in at each time, so the reference never has to jump between far-apart
near-equal optima. **In flight**, once per ``replan_every`` control steps (all candidates in one
compiled call, ``planning.relay_grid``) the planner evaluates the true end-to-end capacity
(``models.radio``: the scene's antenna gains at every node, every jammer's position and power as
the relay knows them, MRAV-2 predicted ``lookahead_s`` ahead at constant acceleration with its antenna
along its thrust) at candidate relay poses around its current target: positions on a 27-point
stencil ``step_m`` apart, each with every antenna axis the platform can hold in hover
(``Multirotor.hover_tilt_limit``; vertical only for a coplanar platform). The best candidate
becomes the new target (hill climbing over poses); the target stays within ``leash_m`` of the
route (at the look-ahead time), and the position reference moves toward it at <= ``controller.
capacity.speed_m_s``, speeding up at <= ``max_accel_m_s2`` and braking at <= ``brake_accel_m_s2`` so it
stops on the target.
The antenna axis reference turns toward the best axis at <= ``axis_rate``; turned with the
thrust direction the reference's acceleration needs, it is the NMPC's body z reference.

**Yaw** (``yaw_rate_deg_s`` > 0, tilted platforms; ``planning.platform_yaw``): at each replan
every yaw's holdable axes are also scored at the chosen position and the platform turns toward a
better yaw; the axis reference is clipped to what it holds at its measured yaw. Off by default.

**Observability excursion** (``excursion_m`` > 0, for estimated jammers): a relay that holds
still cannot triangulate a jammer from received power. While an estimated jammer's largest
position std is above ``excursion_std_m``, the reference chases a point circling the target at
``excursion_m`` (at the speed limit, with a vertical component), so the relay's bearing and range
to the jammer change; once every estimate is that good the excursion stops. It pauses while the
circling point's best capacity (scored at each replan) is more than ``excursion_max_loss`` below the
target's: information is not bought where the link is weakest.
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from ..models.axes import axis_set
from ..models.geometry import E3, thrust_direction_from_acceleration
from ..models.obstacles import pushed_out
from ..models.radio import NodePose
from ..models.raytrace import RayTracer
from .base import PlannerContext, PlannerInput
from .bound import CapacityLandscape, best_path, position_grid
from .platform_yaw import PlatformYaw
from .relay_grid import CompiledRelayGrid
from .shaper import ReferenceShaper, ShaperSettings
from .traced_grid import TracedRelayGrid
from .trajectory_generator import Reference


def holdable_axes(vehicle, tilt_fraction: float, step_deg: float, boundary: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The antenna axes ``vehicle`` can hold in hover at zero yaw: toward each world azimuth (every
    10 deg, rad) a tilt up to ``tilt_fraction`` (a margin of control authority) of its hover tilt
    limit toward that azimuth (rad); and the axis set on tilt rings every ``step_deg``
    (``models.axes.axis_set``, ``boundary``: also the axes at the limit). ``(azimuths, limits, axes)``."""
    az = np.radians(np.arange(0.0, 360.0, 10.0))
    limits = tilt_fraction * vehicle.hover_tilt_limits(az)
    return az, limits, axis_set(az, limits, np.radians(step_deg), boundary=boundary)


class CapacityPlanner:
    """Hill climbing on the true capacity over (position, antenna axis), speed-limited reference."""

    def __init__(self, ctx: PlannerContext):
        s = ctx.settings.capacity  # CapacityPlannerSettings
        veh = ctx.vehicle
        # at zero yaw only the tilts the platform can hold toward each azimuth (times tilt_fraction,
        # a margin of control authority) are axes it can actually fly
        az, limits, self.axes = holdable_axes(veh, s.tilt_fraction, s.axis_step_deg, s.boundary_axes)
        self.tilt_limit = float(limits.max())
        self.lo, self.hi = np.asarray(ctx.workspace_min, float) + s.margin_m, np.asarray(ctx.workspace_max, float) - s.margin_m
        self.offsets = s.step_m * np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=3)))
        self.speed = s.speed_m_s
        self.replan_every, self.leash, self.lookahead = s.replan_every, s.leash_m, s.lookahead_s
        self.source_clearance = float(ctx.source_clearance_m)
        self.gravity = veh.gravity
        self.source_name = ctx.scene.name_of("source")
        self.obstacles = ctx.obstacles
        t0 = time.perf_counter()
        traced = None
        if s.scoring == "traced":  # the route and every candidate pose on the ray-traced channel of the scene's map
            if not isinstance(ctx.tracer, RayTracer):
                raise ValueError("capacity planner: scoring 'traced' needs the scene's ray tracer (a ray-traced channel)")
            traced = TracedRelayGrid(ctx.scene, ctx.tracer, source=self.source_name, coherent=ctx.traced_coherent)
        self.route_t, self.route_p = self._preflight_route(ctx, s.route_grid_m, s.route_dt_s, traced)
        self.grid: CompiledRelayGrid | TracedRelayGrid = traced or CompiledRelayGrid(ctx.scene, len(self.offsets),
                                                                                     len(self.axes), source=self.source_name)
        # yawing the platform (yaw_rate_deg_s > 0, a tilted platform): rotated axis sets scored at the best position
        self.yaw = (PlatformYaw(self.axes, az, limits, rate=np.radians(s.yaw_rate_deg_s))
                    if s.yaw_rate_deg_s > 0 and self.tilt_limit > 0 else None)
        self.yaw_grid = (CompiledRelayGrid(ctx.scene, 1, len(self.yaw.all_axes()), source=self.source_name)
                         if self.yaw is not None else None)
        self.preflight_s = time.perf_counter() - t0
        self.shaper = ReferenceShaper(shaper_settings(s, self.tilt_limit, self.gravity))
        self.target: np.ndarray | None = None
        self.axis_goal = E3.copy()
        self.best_capacity = 0.0
        self.excursion, self.excursion_std, self.excursion_max_loss = s.excursion_m, s.excursion_std_m, s.excursion_max_loss
        self.excursion_allowed = True
        scoring = s.scoring
        # one position x every axis: the excursion's point, and the decoupled scoring's second pass
        self.axis_grid = (CompiledRelayGrid(ctx.scene, 1, len(self.axes), source=self.source_name)
                          if s.excursion_m > 0 or scoring == "decoupled" else None)
        self.position_grid = (CompiledRelayGrid(ctx.scene, len(self.offsets), 1, source=self.source_name)
                              if scoring == "decoupled" and self.yaw is None else None)
        self._k = 0

    def _preflight_route(self, ctx: PlannerContext, grid_m: float, dt_s: float,
                         traced: TracedRelayGrid | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The route on the analytic channel, or on the traced one at the grid's cells (``traced``: the scene's map,
        every cell traced from the source's plan at each instant)."""
        grid, cells = position_grid(self.lo, self.hi, grid_m)
        shape = tuple(len(g) for g in grid)
        # at least one cell per step: on a 1 m grid at 0.5 m/s a 1 s step could not move at all
        dt_s = max(dt_s, grid_m / self.speed)
        times = np.arange(0.0, ctx.duration_s + dt_s, dt_s)
        start = tuple(int(np.argmin(np.abs(grid[i] - np.clip(ctx.relay_start[i], self.lo[i], self.hi[i])))) for i in range(3))
        landscape = CapacityLandscape(ctx.scene, ctx.source, self.gravity, jammer_known=False, keep_out=ctx.obstacles,
                                      traced=traced)
        route = best_path(landscape, cells, shape, self.axes, times, start, self.speed * dt_s / grid_m)
        return times, route

    def route_at(self, t: float) -> np.ndarray:
        """The pre-flight route at time ``t`` (linear between its points)."""
        return np.array([np.interp(t, self.route_t, self.route_p[:, i]) for i in range(3)])

    def _predicted_source(self, inp: PlannerInput) -> tuple[np.ndarray, np.ndarray]:
        tau = self.lookahead
        p2 = inp.p2 + inp.v2 * tau + 0.5 * inp.a2 * tau**2
        return p2, thrust_direction_from_acceleration(inp.a2, self.gravity)

    def _candidates(self, inp: PlannerInput, target: np.ndarray) -> np.ndarray:
        """The stencil around ``target``, kept within the leash of the route and inside the box."""
        anchor = self.route_at(inp.t + self.lookahead)
        cand = target + self.offsets
        off = cand - anchor  # stay within the leash of the route
        n = np.linalg.norm(off, axis=1, keepdims=True)
        cand = np.clip(np.where(n > self.leash, anchor + off * (self.leash / np.maximum(n, 1e-12)), cand), self.lo, self.hi)
        if self.obstacles:  # a candidate inside an obstacle's margin moves to its surface
            cand = np.array([pushed_out(self.obstacles, c) for c in cand])
        if self.source_clearance > 0:  # never a goal on the source: out of its clearance, now and as predicted
            for p2 in (np.asarray(inp.p2, float), self._predicted_source(inp)[0]):
                cand = away_from(cand, p2, self.source_clearance)
        return cand

    def _replan(self, inp: PlannerInput):
        """One replan: the candidates around the target scored (MRAV-2 predicted ahead) in one
        compiled call (``planning.relay_grid``), the best becomes the target."""
        assert self.target is not None  # update() sets it before the first replan
        p2, b2 = self._predicted_source(inp)
        cand = self._candidates(inp, self.target)
        pose = NodePose(p2, b2)
        axes = self.axes if self.yaw is None else self.yaw.axes()
        if self.position_grid is not None and self.axis_grid is not None:
            # decoupled: the positions at the current axis goal, then every axis at the best of them
            i = int(np.argmax(self.position_grid(cand, self.axis_goal[None, :], pose, inp.jammer_positions, inp.jammer_powers)))
            c_axes = self.axis_grid(cand[i:i + 1], axes, pose, inp.jammer_positions, inp.jammer_powers)[0]
            j = int(np.argmax(c_axes))
            best = float(c_axes[j])
        else:  # joint: every candidate position with every axis
            C = self.grid(cand, axes, pose, inp.jammer_positions, inp.jammer_powers)
            i, j = (int(v) for v in np.unravel_index(int(np.argmax(C)), C.shape))
            best = float(C[i, j])
        self.target = cand[i]
        self.axis_goal = axes[j]
        self.best_capacity = best
        if self.yaw is not None and self.yaw_grid is not None:  # every yaw's axes at the chosen position
            every = self.yaw.all_axes()
            c = self.yaw_grid(cand[i:i + 1], every, pose, inp.jammer_positions, inp.jammer_powers)[0]
            k = self.yaw.choose(c, self.best_capacity)
            if k is not None:
                self.axis_goal, self.best_capacity = every[k], float(c[k])
        if self.excursion > 0 and self.axis_grid is not None and self._estimate_poor(inp):  # the circling point's link
            point = excursion_point(self.target, self.excursion, self.speed, inp.t, self.lo, self.hi)
            c_point = self.axis_grid(point[None, :], axes, pose, inp.jammer_positions, inp.jammer_powers)
            self.excursion_allowed = float(np.max(c_point)) >= (1.0 - self.excursion_max_loss) * self.best_capacity

    def _estimate_poor(self, inp: PlannerInput) -> bool:
        """An estimated jammer's largest position std is above ``excursion_std``."""
        return inp.jammer_std_m is not None and bool(np.any(np.asarray(inp.jammer_std_m) > self.excursion_std))

    def _goal(self, inp: PlannerInput) -> np.ndarray:
        """Where the reference heads: the target, or a point circling it while a jammer estimate is
        poor and the link there is within ``excursion_max_loss`` of the target's."""
        assert self.target is not None
        if self.excursion <= 0 or not self.excursion_allowed or not self._estimate_poor(inp):
            return self.target
        return excursion_point(self.target, self.excursion, self.speed, inp.t, self.lo, self.hi)

    def update(self, inp: PlannerInput) -> Reference:
        sh = self.shaper
        if sh.p_ref is None or self.target is None:
            sh.p_ref = np.clip(np.asarray(inp.p1, float), self.lo, self.hi)
            self.target = sh.p_ref.copy()
        if self._k % self.replan_every == 0:
            self._replan(inp)
        self._k += 1
        v_ref = sh.advance(self._goal(inp), inp.dt)
        sh.turn_axis(self.axis_goal, inp.dt)
        # the axis the platform holds at its measured yaw while it turns
        yaw, axis_now = (0.0, sh.axis) if self.yaw is None else self.yaw.turn(sh.axis, inp.psi1, inp.dt)
        # a coplanar relay tilts only by accelerating (rho_d from a_ref); a tilted one holds the
        # antenna axis relative to the thrust its acceleration needs
        axis = sh.held_axis(axis_now)
        assert sh.p_ref is not None
        return Reference(p_opt=self.target.copy(), p_ref=sh.p_ref.copy(), v_ref=v_ref, a_ref=sh.acceleration(inp.p1, inp.v1, axis),
                         axis=axis, yaw=yaw)


def shaper_settings(s, tilt_limit: float, gravity: float) -> ShaperSettings:
    """The reference shaper's settings from ``[controller.capacity]`` (``CapacityPlannerSettings``) and the
    platform's hover tilt limit (rad; 0: level-only) and gravity (m/s^2)."""
    return ShaperSettings(speed_m_s=s.speed_m_s, max_accel_m_s2=s.max_accel_m_s2, brake_accel_m_s2=s.brake_accel_m_s2,
                          accel_tau_s=s.accel_tau_s, axis_rate_deg_s=s.axis_rate_deg_s,
                          tracking_freq_rad_s=s.tracking_freq_rad_s, tilt_limit=tilt_limit, gravity=gravity)


def away_from(points: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """``points`` ``(n, 3)`` closer than ``radius`` to ``centre`` moved out to that distance, along the line from
    it (straight up for a point on it), m."""
    d = points - centre
    n = np.linalg.norm(d, axis=1, keepdims=True)
    direction = np.where(n > 1e-9, d / np.maximum(n, 1e-12), np.array([0.0, 0.0, 1.0]))
    return np.where(n < radius, centre + direction * radius, points)


def excursion_point(target: np.ndarray, radius: float, speed: float, t: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The observability excursion's point at time ``t`` (s): circling ``target`` (m, world) at
    ``radius`` m and ``speed`` m/s, rising and sinking by half the radius, inside ``[lo, hi]``."""
    phase = speed / radius * t
    offset = radius * np.array([np.cos(phase), np.sin(phase), 0.5 * np.sin(0.5 * phase)])
    return np.clip(target + offset, lo, hi)
