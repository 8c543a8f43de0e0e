"""
A sweep on dask
===============

A small sweep on dask: the jammer's power against the paper's controller, one run per worker task.

Uses a local cluster (two single-threaded worker processes); pass a scheduler address to
dask.distributed.Client to scale out.
"""

import os
from pathlib import Path

from dask.distributed import Client, LocalCluster

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
POWERS_W = [1.0, 10.0, 100.0]


def fly(power_w: float) -> dict:
    sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION, "jammer.power_w": power_w})
    m = ar.simulate(sc).metrics
    return {"power_w": power_w, "c_min": m["c_min"], "c_mean": m["c_mean"], "outage": m["outage_fraction"]}


if __name__ == "__main__":
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, Client(cluster) as client:
        rows = client.gather(client.map(fly, POWERS_W))
    for r in sorted(rows, key=lambda r: r["power_w"]):
        print(f"P_J {r['power_w']:6.1f} W: C_min {r['c_min']:.3e}  mean C {r['c_mean']:.3e}  outage {r['outage']:.0%}")
