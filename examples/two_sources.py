"""
Two sources sharing two relays
==============================

Two inspection drones send their data through the same two relays to the base station. Every hop
of every route has its own time slot and every source gets the same rate, so the network's rate is
``R = B / sum_s sum_k 1/log2(1 + Gamma_{s,k})``: the shared hops ``r1 -> r2 -> bs`` carry both::

    python examples/two_sources.py            # the whole 40 s mission, writes runs/example_two_sources/
"""

import os
from pathlib import Path

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "40"))
OUT = os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_two_sources")

sc = ar.load_scenario(SCENARIOS / "two_sources.toml", set={"sim.duration_s": DURATION})
result = ar.simulate(sc)
m = result.metrics
print(f"network: C_min {m['c_min'] / 1e6:.2f} Mbit/s, mean C {m['c_mean'] / 1e6:.2f} Mbit/s, "
      f"closest two vehicles {m['separation_min_m']:.1f} m, unsafe: {m['unsafe']}")
for source, r in m["routes"].items():
    print(f"  route from {source} alone: mean {r['c_mean'] / 1e6:.2f} Mbit/s")
result.save(os.path.join(OUT, "run"), figures=False)
print(f"wrote {OUT}")
