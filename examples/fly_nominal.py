"""
Fly the nominal mission
=======================

Fly the paper's nominal mission and plot the end-to-end capacity over time::

    python examples/fly_nominal.py            # the whole 47 s mission, writes runs/example_nominal/
"""

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import aerorelay as ar  # noqa: E402

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
OUT = os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_nominal")

sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION})
result = ar.simulate(sc)
df = result.timeseries
print(f"C_min {result.metrics['c_min']:.3e}, mean C {result.metrics['c_mean']:.3e}, outage {result.metrics['outage_fraction']:.0%}")

fig, ax = plt.subplots(figsize=(7, 3))
ax.semilogy(df["t"], df["capacity"].clip(lower=1e-12), label="end-to-end C")
ax.axhline(sc.channel.outage, color="r", ls="--", label="outage threshold")
ax.set_xlabel("t (s)")
ax.set_ylabel("C (bit/s/Hz)")
ax.legend()
os.makedirs(OUT, exist_ok=True)
fig.savefig(os.path.join(OUT, "capacity.png"), dpi=100)
result.save(os.path.join(OUT, "run"), figures=False)
print(f"wrote {OUT}")
