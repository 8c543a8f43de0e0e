"""
Where the step-time tail comes from
===================================

Where the NMPC's step-time tail comes from: is it the warm start or the QP itself?

Flies the nominal coplanar mission with the paper's controller, keeps the QP of every step whose
warm-started interior-point method needed at least HEAVY iterations (the engine's guess, stage
parameters and measured state at that step), solves each of them again from a cold start in a
second engine, and prints both iteration counts, the cost of one iteration (a linear fit of the
preparation time against the iterations), and what happens on those steps (alignment slack
active, a motor at a bound). The docs' "Where the tail comes from" (Controller speed) was measured with it
(2026-12-02; 7 s).
"""

import os
from pathlib import Path

import numpy as np

import aerorelay as ar
from aerorelay.api import build
from aerorelay.control.hpipm_rti import HpipmRti
from aerorelay.control.ocp import HESSIAN_REG

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
HEAVY = 7  # IPM iterations that make a step "heavy"


def fly_and_keep_heavy_qps(sc):
    """Fly ``sc``; return (mission result, per-step timings, {step: QP data} of the heavy steps)."""
    loop = build(sc).closed_loop()
    nmpc = loop.relays[0].controller.nmpc  # the one relay's NMPC
    rti = nmpc.engine.rti
    prepare, feedback = rti.prepare, rti.feedback
    seen, kept = {"k": -1}, {}

    def prepare_and_remember(P):
        seen["k"] += 1
        seen["guess"], seen["P"] = rti.plan()[:2], P.copy()
        prepare(P)

    def feedback_and_keep(xa0, shift=True):
        u, info = feedback(xa0, shift)
        if info.iter >= HEAVY:
            kept[seen["k"]] = {"guess": seen["guess"], "P": seen["P"], "xa0": xa0.copy(), "iters": info.iter}
        return u, info

    rti.prepare, rti.feedback = prepare_and_remember, feedback_and_keep  # this instance only
    res = loop.run()
    return res, loop.timings["relay"], kept, nmpc.spec


def main():
    sc = ar.load_scenario(SCENARIOS / "nominal_coplanar.toml", set={"sim.duration_s": DURATION})
    res, timings, kept, spec = fly_and_keep_heavy_qps(sc)
    iters = np.array([s.qp_iters for s in timings])
    prep = np.array([s.prep_ms for s in timings])
    slope, base = np.polyfit(iters, prep, 1) if np.ptp(iters) > 0 else (float("nan"), float(prep.mean()))
    print(f"{len(iters)} steps, IPM iterations mean {iters.mean():.2f}, p99 {np.percentile(iters, 99):.0f}, "
          f"max {iters.max()}; preparation = {base:.3f} ms + {slope:.3f} ms per iteration")
    if not kept:
        print(f"no step needed >= {HEAVY} iterations; C_min {np.min(res.log['capacity']):.4e}")
        return
    cold = HpipmRti(spec, iter_max=50, tol_comp=1e-3, warm_start=0, hessian_reg=HESSIAN_REG, feedback_mode=1)
    warm_n, cold_n = [], []
    for qp in kept.values():
        cold.set_plan(*qp["guess"])
        cold.prepare(qp["P"])
        _, info = cold.feedback(qp["xa0"], shift=False)
        warm_n.append(qp["iters"])
        cold_n.append(info.iter)
    w, c = np.array(warm_n), np.array(cold_n)
    heavy = np.zeros(len(iters), bool)
    heavy[list(kept)] = True
    omega = np.stack([res.log[f"relay.Omega_{i + 1}"] for i in range(spec.n_rotors)], 1)
    u = np.stack([res.log[f"relay.u_{i + 1}"] for i in range(spec.n_rotors)], 1)
    v = spec.vehicle
    events = {"alignment slack > 1e-4": res.log["relay.slack_max"] > 1e-4,
              "a motor within 2 Hz of its top speed": omega.max(1) > v.omega_max - 2.0,
              "a motor acceleration within 10 Hz/s of its bound": (u.max(1) > v.omega_dot_max - 10.0)
              | (u.min(1) < v.omega_dot_min + 10.0)}
    print(f"{len(w)} heavy steps (>= {HEAVY} warm iterations), at t = "
          f"{', '.join(f'{k * sc.controller.ts_s:.1f}' for k in list(kept)[:: max(1, len(kept) // 8)])} s ...")
    print(f"  warm-started in the flight: mean {w.mean():.2f}, max {w.max()}; the same QPs cold: mean {c.mean():.2f}, "
          f"max {c.max()}; cold needs fewer in {np.sum(c < w)} of {len(w)}")
    for name, flag in events.items():
        print(f"  {name}: {np.mean(flag[heavy]):.0%} of heavy steps, {np.mean(flag[~heavy]):.0%} of the others")
    print(f"C_min {np.min(res.log['capacity']):.4e}")


if __name__ == "__main__":
    main()
