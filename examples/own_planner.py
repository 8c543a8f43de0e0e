"""
Your own relay planner
======================

Your own relay planner in a few lines: any object with update(PlannerInput) -> Reference.

This one parks the relay on the segment between MRAV-2 and the base station, at a fixed fraction
of the way, moving there at a bounded speed; the NMPC tracks it.
"""

import os
from pathlib import Path

import numpy as np

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))


class MidpointPlanner:
    """Reference on the source-BS segment at ``fraction`` from the BS, at <= ``speed`` m/s."""

    def __init__(self, bs, fraction=0.5, speed=0.5):
        self.bs, self.fraction, self.speed = np.asarray(bs, float), fraction, speed
        self.p_ref = None

    def update(self, inp: ar.PlannerInput) -> ar.Reference:
        goal = self.bs + self.fraction * (inp.p2 - self.bs)
        goal[2] = max(goal[2], 1.0)  # stay above the floor of the workspace
        if self.p_ref is None:
            self.p_ref = inp.p1.copy()
        step = goal - self.p_ref
        n = np.linalg.norm(step)
        step *= min(1.0, self.speed * inp.dt / max(n, 1e-12))
        self.p_ref = self.p_ref + step
        return ar.Reference(p_opt=goal, p_ref=self.p_ref.copy(), v_ref=step / inp.dt, a_ref=np.zeros(3))


sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION, "controller.variant": "unconstrained"})
result = ar.simulate(sc, planner=MidpointPlanner(sc.nodes.bs))
print(f"midpoint planner: C_min {result.metrics['c_min']:.3e}, mean C {result.metrics['c_mean']:.3e}")
