"""The built-in planners behind ``controller.planner`` (one relay, registered with ``planning.base``) and
``network.planner`` (a network's, registered with ``planning.fleet``)."""

from __future__ import annotations

import numpy as np

from .base import PlannerContext, PlannerInput, register_planner
from .baselines import PlannedReference, SingleShotPlanner
from .capacity_planner import CapacityPlanner, holdable_axes
from .fleet import (
    EquidistantPlanner,
    EquidistantSettings,
    FleetCapacityPlanner,
    FleetCapacitySettings,
    NetworkPlannerContext,
    register_network_planner,
)
from .network_generator import NetworkGenerator
from .trajectory_generator import Reference, SurrogateParams, TrajectoryGenerator


class GeneratorPlanner:
    """The paper's max-min trajectory generator with its reference governor (eq. 14-19)."""

    def __init__(self, generator: TrajectoryGenerator):
        self.generator = generator

    def update(self, inp: PlannerInput) -> Reference:
        return self.generator.update(inp.dt, inp.p1, inp.p2, inp.v2, inp.a2, inp.jammer_positions, inp.jammer_powers)


class FixedPlanReference:
    """A plan made once before take-off, replayed (baseline B)."""

    def __init__(self, reference: PlannedReference):
        self.reference = reference

    def update(self, inp: PlannerInput) -> Reference:
        return self.reference.update(inp.t)


def _generator(ctx: PlannerContext, mu: float) -> TrajectoryGenerator:
    c = ctx.settings.generator
    return TrajectoryGenerator(
        SurrogateParams.of_scene(ctx.scene, mu, ctx.surrogate_g_bar),
        ctx.scene.fixed_pose(ctx.scene.name_of("base_station")).position, governor_speed=c.governor_speed_m_s,
        eig_floor=c.hessian_eig_floor, workspace_min=ctx.workspace_min, workspace_max=ctx.workspace_max,
    )


@register_planner("trajectory_generator")
def _paper_generator(ctx: PlannerContext):
    return GeneratorPlanner(_generator(ctx, ctx.settings.generator.mu))


@register_planner("isotropic")
def _baseline_a(ctx: PlannerContext):
    # baseline A plans with isotropic antennas: H_bar = G_bar / d, i.e. the surrogate with mu = 1
    return GeneratorPlanner(_generator(ctx, 1.0))


@register_planner("single_shot")
def _baseline_b(ctx: PlannerContext):
    planner = SingleShotPlanner(ctx.scene, max_speed=ctx.settings.generator.governor_speed_m_s, gravity=ctx.vehicle.gravity)
    plan = planner.plan(ctx.source, ctx.relay_start, ctx.duration_s, ctx.workspace_min, ctx.workspace_max)
    return FixedPlanReference(PlannedReference(plan))


@register_planner("capacity")
def _capacity_seeking(ctx: PlannerContext):
    return CapacityPlanner(ctx)


def _box(ctx: NetworkPlannerContext) -> dict:
    return {"workspace_min": tuple(float(v) for v in ctx.workspace_min), "workspace_max": tuple(float(v) for v in ctx.workspace_max)}


@register_network_planner("equidistant")
def _equidistant(ctx: NetworkPlannerContext):
    cap = ctx.settings.capacity
    return EquidistantPlanner(ctx.routes, ctx.starts, EquidistantSettings(speed_m_s=cap.speed_m_s, margin_m=cap.margin_m,
                                                                          **_box(ctx)))


@register_network_planner("capacity")
def _fleet_capacity(ctx: NetworkPlannerContext):
    cap = ctx.settings.capacity
    # each relay's antenna axes it can hold at zero yaw toward each azimuth (its own limit there, times tilt_fraction), as
    # the one relay's planner: its best azimuth's limit everywhere was not holdable (3 m tracking errors)
    axes = {name: holdable_axes(ctx.vehicles[name], cap.tilt_fraction, cap.axis_step_deg, cap.boundary_axes)[2]
            for name in ctx.starts}
    return FleetCapacityPlanner(ctx.scene, ctx.starts, axes,
                                FleetCapacitySettings(speed_m_s=cap.speed_m_s, replan_every=cap.replan_every,
                                                      axis_rate_deg_s=cap.axis_rate_deg_s, margin_m=cap.margin_m,
                                                      separation_m=ctx.separation_m, obstacles=ctx.obstacles, **_box(ctx)))


@register_network_planner("trajectory_generator")
def _network_generator(ctx: NetworkPlannerContext):
    g = ctx.settings.generator
    return NetworkGenerator(SurrogateParams.of_scene(ctx.scene, g.mu, ctx.surrogate_g_bar), ctx.routes, list(ctx.starts),
                            tuple(float(v) for v in np.asarray(ctx.bs_position, float)), governor_speed=g.governor_speed_m_s,
                            eig_floor=g.hessian_eig_floor, workspace_min=ctx.workspace_min, workspace_max=ctx.workspace_max)
