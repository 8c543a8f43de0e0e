"""The built-in planners behind ``controller.planner``, registered with ``planning.base``."""

from __future__ import annotations

import numpy as np

from .base import PlannerInput, register_planner
from .baselines import PlannedReference, SingleShotPlanner
from .trajectory_generator import Reference, SurrogateParams, TrajectoryGenerator


class GeneratorPlanner:
    """The paper's max-min trajectory generator with its reference governor (eq. 14-19)."""

    def __init__(self, generator: TrajectoryGenerator):
        self.generator = generator

    def update(self, inp: PlannerInput) -> Reference:
        return self.generator.update(inp.dt, inp.p1, inp.p2, inp.v2, inp.a2, inp.jammer_position, inp.jammer_power)


class FixedPlanReference:
    """A plan made once before take-off, replayed (baseline B)."""

    def __init__(self, reference: PlannedReference):
        self.reference = reference

    def update(self, inp: PlannerInput) -> Reference:
        return self.reference.update(inp.t)


def _generator(sc, mu: float) -> TrajectoryGenerator:
    ch, c = sc.channel, sc.controller
    return TrajectoryGenerator(
        SurrogateParams(mu, sc.antenna.g_bar, ch.tx_power_w, ch.noise_power_w, ch.bandwidth),
        sc.nodes.bs, governor_speed=c.governor_speed_m_s, eig_floor=c.hessian_eig_floor,
        workspace_min=c.workspace.min, workspace_max=c.workspace.max,
    )


@register_planner("trajectory_generator")
def _paper_generator(sc, source):
    return GeneratorPlanner(_generator(sc, sc.controller.mu))


@register_planner("isotropic")
def _baseline_a(sc, source):
    # baseline A plans with isotropic antennas: H_bar = G_bar / d, i.e. the surrogate with mu = 1
    return GeneratorPlanner(_generator(sc, 1.0))


@register_planner("single_shot")
def _baseline_b(sc, source):
    ch, c = sc.channel, sc.controller
    planner = SingleShotPlanner(max_speed=c.governor_speed_m_s, gravity=sc.platform.gravity_m_s2,
                                tx_power=ch.tx_power_w, noise_power=ch.noise_power_w, g_bar=sc.antenna.g_bar)
    plan = planner.plan(source, np.array(sc.nodes.relay, float), sc.nodes.bs, sc.duration_s, c.workspace.min, c.workspace.max)
    return FixedPlanReference(PlannedReference(plan))


@register_planner("capacity")
def _capacity_seeking(sc, source):
    from .capacity_planner import CapacityPlanner

    return CapacityPlanner(sc)
