"""Records the logs the regression test of issue 46 (one machinery) compares against: each case
flown by the code before the one-relay loop and the fleet loop became one loop (commit 05e1bca), its
timeseries written to ``tests/data/before_one_machinery/<case>.parquet``. Run from the repository
root at that commit (``git worktree add /tmp/old 05e1bca``, then from /tmp/old ``PYTHONPATH=src python
/path/to/this/script``; cases already recorded are kept unless ``--all``). ``chain_capacity`` was recorded
again on 2026-12-04 by the code that rebuilt the fleet's capacity planner (issue 47: a pre-flight route,
joint moves, the one reference shaper), and on 2026-12-05 when a relay whose move loses the joint decision
came to hold its goal within its leash (5e-4 m on r1 in these 1.5 s): deliberate changes of that planner's
flights, recorded so the case keeps guarding the loop (``python tests/data/record_before_one_machinery.py
chain_capacity`` from the root). The four ``nominal_*`` cases were recorded again on 2026-12-06 when the paper's one
relay came to keep the separation from its source in its NMPC, as every fleet relay does (issue 61: a soft row, never
active in these cases, that moves the interior-point QP's answer: the relay's position by at most 2.1e-4 m, 3.5e-3 m
with the capacity planner, the capacity by at most 4.9e-4 relative; written under the old column names, the new log renamed back through
``modern_columns``); ``nominal_estimated`` again the same day when the jammer estimator came to read its residuals'
scale robustly and to flag an estimate at its search box's edge (issue 61, item 5): the same flight, the estimate's
columns changed. Every case was recorded again on 2026-12-07 (issue 76: the separation row bounded, 2 d^2 (r^2 - d^2) /
(r^2 + d^2)), on a CPU without AVX-512 with ``OPENBLAS_CORETYPE=Haswell`` and ``NPY_DISABLE_CPU_FEATURES="X86_V4
AVX512_ICL AVX512_SPR"`` (the test command's pins: numpy's and OpenBLAS's kernels differ by CPU, and the capacity
planner's choices amplify a rounding difference to 5e-4 m); the nominal cases kept under their old column names."""

from __future__ import annotations

import sys
from pathlib import Path

import aerorelay as ar

OUT = Path(__file__).resolve().parent / "before_one_machinery"

CASES = {  # case -> (scenario file, dotted updates)
    "nominal_paper": ("scenarios/nominal_tilted.toml", {"sim.duration_s": 3.0}),
    "nominal_capacity": ("scenarios/nominal_tilted.toml", {"sim.duration_s": 3.0, "controller.planner": "capacity"}),
    "nominal_noisy": ("scenarios/nominal_tilted.toml", {
        "sim.duration_s": 2.0, "perturbations.fading_k_db": 3.0, "perturbations.csi_noise_m": 0.05,
        "perturbations.process_noise_v": 0.05, "perturbations.process_noise_w": 0.05,
        "wind.mean_m_s": [3.0, 0.0, 0.0], "wind.gusts": True}),
    "nominal_estimated": ("scenarios/nominal_tilted.toml", {"sim.duration_s": 2.0, "jammer.localization": "estimated",
                                                            "jammer.inr_db_at_relay_start": 10.0}),
    "chain": ("scenarios/chain_two_relays.toml", {"sim.duration_s": 2.0}),
    "two_sources": ("scenarios/two_sources.toml", {"sim.duration_s": 2.0}),
    "chain_capacity": ("scenarios/chain_two_relays.toml", {"sim.duration_s": 1.5, "controller.planner": "capacity"}),
    "two_sources_paper": ("scenarios/two_sources.toml", {"sim.duration_s": 1.5, "controller.planner": "paper"}),
}


def main() -> None:
    OUT.mkdir(exist_ok=True)
    for case, (path, updates) in CASES.items():
        if (OUT / f"{case}.parquet").exists() and "--all" not in sys.argv and case not in sys.argv:
            continue
        r = ar.simulate(ar.load_scenario(path, set=updates))
        r.timeseries.to_parquet(OUT / f"{case}.parquet")
        print(case, len(r.timeseries), "rows", len(r.timeseries.columns), "columns")


if __name__ == "__main__":
    main()
