"""
A chain of two relays
=====================

An inspection drone circles a structure 60 m from the base station; two relays carry its data
(``inspector -> r1 -> r2 -> bs``) under a jammer 10 dB over the noise. The fleet flies the
equidistant planner, every relay its own NMPC. The log names each vehicle's columns
``<node>.<quantity>``, each hop's SINR ``sinr.<tx>.<rx>`` and the network's rate ``capacity``::

    python examples/relay_chain.py            # the whole 60 s mission, writes runs/example_chain/
"""

import os
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import aerorelay as ar  # noqa: E402

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "60"))
OUT = os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_chain")

sc = ar.load_scenario(SCENARIOS / "chain_two_relays.toml", set={"sim.duration_s": DURATION})
result = ar.simulate(sc)
df, m = result.timeseries, result.metrics
print(f"C_min {m['c_min'] / 1e6:.2f} Mbit/s, mean C {m['c_mean'] / 1e6:.2f} Mbit/s, outage {m['outage_fraction']:.0%}, "
      f"closest two vehicles {m['separation_min_m']:.1f} m")
for name, r in m["relays"].items():
    print(f"  {name}: tracking error {r['position_error_mean_m']:.2f} m, step {r['solve_ms']['mean']:.2f} ms mean")

fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
for tx, rx in zip(sc.route_list[0][:-1], sc.route_list[0][1:], strict=True):
    top.plot(df["t"], 10 * np.log10(df[f"sinr.{tx}.{rx}"]), label=f"{tx} -> {rx}")
top.set_ylabel("SINR (dB)")
top.legend(fontsize=7)
bottom.plot(df["t"], df["capacity"] / 1e6)
bottom.set_ylabel("network rate (Mbit/s)")
bottom.set_xlabel("t (s)")
os.makedirs(OUT, exist_ok=True)
fig.savefig(os.path.join(OUT, "chain.png"), dpi=100)
result.save(os.path.join(OUT, "run"), figures=False)
print(f"wrote {OUT}")
