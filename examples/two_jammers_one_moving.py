"""
Two jammers, one moving
=======================

Two jammers passed as objects, one fixed and one driving along a road, instead of named in TOML.

The jammers are set where they matter: 100 W each against 1 W of noise (the paper's 1 W jammer
adds ~1% to the noise); `ar.link_budget` prints the interference-to-noise ratios.
"""

import os
from pathlib import Path

import numpy as np

import aerorelay as ar
from aerorelay.models.mission import LinearPath

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))

sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION})
fixed = ar.Jammer(np.array([-6.95, -5.79, 1.72]), power=100.0, name="fixed")
road = LinearPath([[0.0, -7.0, -3.0, 1.5], [47.0, 7.0, -3.0, 1.5]])  # [t, x, y, z]: 0.3 m/s eastward
truck = ar.Jammer(np.array([-7.0, -3.0, 1.5]), power=100.0, path=road, name="truck")

for planner in ("trajectory_generator", "capacity"):
    result = ar.simulate(sc.with_updates({"controller.planner": planner}), jammers=[fixed, truck])
    m = result.metrics
    print(f"{planner:>22}: C_min {m['c_min']:.3e}  mean C {m['c_mean']:.3e}  outage {m['outage_fraction']:.0%}")
