"""
The jammer estimator on a batch of flights
==========================================

The jammer estimator on a batch of flights: the capacity-seeking relay at 10 and 20 dB (jammer
always on) and 10 dB switching 5 s ON / 5 s OFF, 3 seeds each, two flights at a time. Prints per
flight: the fraction of the mission after 10 s with the estimate within 1 m, the fraction
"confidently wrong" (error above 1 m while the largest std is below 1.5 m, the planner's
threshold), the estimator's mean cost, C_min; then the means and worst runs. The table of
estimator changes in the docs (Finding the jammer) was measured with it (26 s on 2 cores, 2026-12-02).
"""

import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
FLIGHTS = [(inr, schedule, seed) for inr, schedule in ((10.0, "always_on"), (20.0, "always_on"), (10.0, "on_off"))
           for seed in (0, 1, 2)]


def fly(flight: tuple[float, str, int]) -> dict:
    inr, schedule, seed = flight
    sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={
        "controller.planner": "capacity", "jammer.inr_db_at_relay_start": inr, "jammer.schedule": schedule,
        "jammer.localization": "estimated", "seed": seed, "sim.duration_s": DURATION})
    res = ar.simulate(sc)
    df, m = res.timeseries, res.metrics
    late = (df["t"] >= min(10.0, 0.5 * DURATION)).to_numpy()
    err, std = df["est_jammer_err_m"].to_numpy()[late], df["est_jammer_std_m"].to_numpy()[late]
    return {"flight": f"{inr:g} dB {schedule} seed {seed}", "within_1m": float(np.mean(err <= 1.0)),
            "confidently_wrong": float(np.mean((err > 1.0) & (std < 1.5))),
            "estimator_ms": m["estimator_ms"]["mean"], "c_min": m["c_min"]}


if __name__ == "__main__":
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(fly, FLIGHTS))
    for r in rows:
        print(f"{r['flight']:28s} within 1 m {r['within_1m']:.3f}  confidently wrong {r['confidently_wrong']:.3f}  "
              f"estimator {r['estimator_ms']:.3f} ms  C_min {r['c_min']:.3g}")
    w, cw = np.array([r["within_1m"] for r in rows]), np.array([r["confidently_wrong"] for r in rows])
    print(f"within 1 m after 10 s: mean {w.mean():.3f}, worst {w.min():.3f}; confidently wrong: mean {cw.mean():.3f}, "
          f"worst {cw.max():.3f}")
