"""The built-in planners behind ``controller.planner``, one registry (``planning.base.PLANNERS``): each name with
what its references carry (the NMPC that flies them) and its factories for one relay and for a network."""

from __future__ import annotations

import numpy as np

from .base import PlannerContext, PlannerInput, register_network_planner, register_planner
from .baselines import PlannedReference, SingleShotPlanner
from .capacity_planner import CapacityPlanner, holdable_axes, shaper_settings
from .fleet import EquidistantPlanner, EquidistantSettings, NetworkPlannerContext
from .fleet_capacity import FleetCapacityPlanner, FleetCapacitySettings, fleet_routes
from .platform_yaw import PlatformYaw
from .trajectory_generator import Reference, SurrogateParams, TrajectoryGenerator


class FixedPlanReference:
    """A plan made once before take-off, replayed (baseline B)."""

    def __init__(self, reference: PlannedReference):
        self.reference = reference

    def update(self, inp: PlannerInput) -> Reference:
        return self.reference.update(inp.t)


@register_planner("single_shot", references="alignment")
def _baseline_b(ctx: PlannerContext):
    planner = SingleShotPlanner(ctx.scene, max_speed=ctx.settings.generator.governor_speed_m_s, gravity=ctx.vehicle.gravity)
    plan = planner.plan(ctx.source, ctx.relay_start, ctx.duration_s, ctx.workspace_min, ctx.workspace_max)
    return FixedPlanReference(PlannedReference(plan))


@register_planner("capacity", references="axis")
def _capacity_seeking(ctx: PlannerContext):
    return CapacityPlanner(ctx)


FLEET_ROUTE_CLEARANCE_M = 0.5  # the pre-flight route keeps this much more than the separation (m), as the goals do


def _box(ctx: NetworkPlannerContext) -> dict:
    """The network's workspace and each relay's own (``NetworkPlannerContext.boxes``) as a planner's settings."""
    return {"workspace_min": tuple(float(v) for v in ctx.workspace_min), "workspace_max": tuple(float(v) for v in ctx.workspace_max),
            "boxes": {n: ctx.box_of(n) for n in ctx.starts}}


@register_network_planner("equidistant", references="position")
def _equidistant(ctx: NetworkPlannerContext):
    cap = ctx.settings.capacity
    speeds = {name: ctx.settings_of(name).capacity.speed_m_s for name in ctx.starts}  # each relay's own limit
    return EquidistantPlanner(ctx.scene.all_routes, ctx.starts, EquidistantSettings(speed_m_s=cap.speed_m_s, speeds_m_s=speeds,
                                                                                    margin_m=cap.margin_m, **_box(ctx)),
                              ctx.scene.handover)


@register_network_planner("capacity", references="axis")
def _fleet_capacity(ctx: NetworkPlannerContext):
    cap = ctx.settings.capacity
    # each relay's antenna axes it can hold at zero yaw toward each azimuth (its own limit there, times tilt_fraction), as
    # the one relay's planner: its best azimuth's limit everywhere was not holdable (3 m tracking errors)
    # (each relay's own tilt fraction, axes, speed and acceleration limits: its [relays.controller.capacity])
    own = {name: ctx.settings_of(name).capacity for name in ctx.starts}
    held = {name: holdable_axes(ctx.vehicles[name], own[name].tilt_fraction, own[name].axis_step_deg, own[name].boundary_axes)
            for name in ctx.starts}
    axes = {name: h[2] for name, h in held.items()}
    shapers = {name: shaper_settings(own[name], float(h[1].max()), ctx.vehicles[name].gravity) for name, h in held.items()}
    # the joint pre-flight route moves every relay at the slowest one's limits (each then chases it within its own)
    route_speed = min(c.speed_m_s for c in own.values())
    route_accel = min(c.max_accel_m_s2 for c in own.values())
    route = None
    if ctx.route and ctx.sources and ctx.duration_s > ctx.t0_s:
        def route(t0, starts, jammer_positions, jammer_powers):
            return fleet_routes(ctx.scene, ctx.sources, starts, {n: float(h[1].max()) for n, h in held.items()},
                                ctx.workspace_min + cap.margin_m, ctx.workspace_max - cap.margin_m, t0=t0,
                                duration_s=ctx.duration_s, dt_s=ctx.route_dt_s, speed_m_s=route_speed,
                                accel_m_s2=route_accel, gravity=next(iter(ctx.vehicles.values())).gravity,
                                separation_m=ctx.separation_m + FLEET_ROUTE_CLEARANCE_M if ctx.separation_m > 0 else 0.0,
                                obstacles=ctx.obstacles, jammer_positions=jammer_positions, jammer_powers=jammer_powers)
    return FleetCapacityPlanner(ctx.scene, ctx.starts, axes, shapers,
                                FleetCapacitySettings(step_m=cap.step_m, replan_every=cap.replan_every,
                                                      lookahead_s=cap.lookahead_s, leash_m=cap.leash_m, margin_m=cap.margin_m,
                                                      separation_m=ctx.separation_m, obstacles=ctx.obstacles, **_box(ctx)),
                                route, tracer=ctx.tracer, traced_coherent=ctx.traced_coherent,
                                yaws={name: PlatformYaw(h[2], h[0], h[1], rate=np.radians(own[name].yaw_rate_deg_s))
                                      for name, h in held.items() if own[name].yaw_rate_deg_s > 0 and float(h[1].max()) > 0})


def _generator(ctx: NetworkPlannerContext, mu: float) -> TrajectoryGenerator:
    """The paper's generator over the network's relays, planning with alignment ``mu`` (each relay's own governor
    speed and workspace)."""
    g = ctx.settings.generator
    governors = {n: ctx.settings_of(n).generator.governor_speed_m_s for n in ctx.starts}
    return TrajectoryGenerator(SurrogateParams.of_scene(ctx.scene, mu, ctx.surrogate_g_bar), ctx.routes, list(ctx.starts),
                               tuple(float(v) for v in np.asarray(ctx.bs_position, float)), governor_speed=governors,
                               eig_floor=g.hessian_eig_floor, relative_floor=g.relative_floor, workspace_min=ctx.workspace_min,
                               workspace_max=ctx.workspace_max, boxes={n: ctx.box_of(n) for n in ctx.starts})


@register_network_planner("trajectory_generator", references="alignment")
def _paper_generator(ctx: NetworkPlannerContext):
    return _generator(ctx, ctx.settings.generator.mu)


@register_network_planner("isotropic", references="alignment")
def _baseline_a(ctx: NetworkPlannerContext):
    # baseline A plans with isotropic antennas: H_bar = G_bar / d, i.e. the surrogate with mu = 1
    return _generator(ctx, 1.0)
