"""
A directional jammer
====================

A directional jammer (cosine pattern) pointed at the base station, from the scenario file, with
the interference-to-noise ratios at the start and the best link the physics allows.
"""

import os
from pathlib import Path

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))

sc = ar.load_scenario(SCENARIOS / "directional_jammer.toml", set={"sim.duration_s": DURATION})
budget = ar.link_budget(sc)
print(f"interference / noise at t = 0: relay {budget['inr_relay_db']:+.1f} dB, BS {budget['inr_bs_db']:+.1f} dB")
result = ar.simulate(sc.with_updates({"controller.planner": "capacity"}), bound=os.environ.get("AERORELAY_EXAMPLE_BOUND", "1") == "1")
m = result.metrics
print(f"capacity-seeking relay: C_min {m['c_min']:.3e}, mean C {m['c_mean']:.3e}, outage {m['outage_fraction']:.0%}")
if result.bound is not None:
    print(f"efficiency vs the best path: mean {m['capacity_efficiency_mean']:.2f}, min {m['capacity_efficiency_min']:.2f}")
