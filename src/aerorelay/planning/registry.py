"""The built-in planners behind ``controller.planner``, registered with ``planning.base``."""

from __future__ import annotations

from .base import PlannerContext, PlannerInput, register_planner
from .baselines import PlannedReference, SingleShotPlanner
from .capacity_planner import CapacityPlanner
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
