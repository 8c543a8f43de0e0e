"""Controller timing: per-step preparation/feedback statistics, deadline misses, full-IPOPT comparison."""

from __future__ import annotations

import gc
import time
from contextlib import contextmanager

import numpy as np

from ..stats import stats_ms
from .full_nlp import FullNlp
from .nmpc import QpStatus
from .ocp import unpack_plan


@contextmanager
def collections_counted(out: dict):
    """Count Python's garbage collections inside the block, per generation, and time the longest of
    each: ``out["collections"]`` ``[young, middle, full]``, ``out["max_ms"]`` (ms). A full collection
    walks every tracked object (70-100 ms during a mission here): the control loop holds them off
    (``sim/realtime.py``), and this shows whether any ran inside a step's time anyway."""
    counts, longest, start = [0, 0, 0], [0.0, 0.0, 0.0], [0.0]

    def callback(phase: str, info: dict) -> None:
        if phase == "start":
            start[0] = time.perf_counter()
            return
        g = int(info["generation"])
        counts[g] += 1
        longest[g] = max(longest[g], (time.perf_counter() - start[0]) * 1e3)

    gc.callbacks.append(callback)
    try:
        yield
    finally:
        gc.callbacks.remove(callback)
        out.update(collections=counts, max_ms=longest)


def relay_timing(loop, relay, period_ms: float, *, ipopt_points: int) -> dict:
    """One relay's controller timing over the steps it flew: preparation and feedback phases, the whole
    step and with the network planner's step, deadline misses, QP iterations and caps; IPOPT at up to
    ``ipopt_points`` of the states it met (``BenchPoint``)."""
    timings = loop.timings[relay.name]
    if not timings:  # a spare that never launched: nothing timed
        return {"steps": 0, "flew": False}
    prep, feedback, iters, planner = (np.array([getattr(s, f) for s in timings], float)
                                      for f in ("prep_ms", "feedback_ms", "qp_iters", "planner_ms"))
    whole = prep + feedback
    nmpc = relay.controller.nmpc
    out = {
        "steps": int(len(prep)),
        "preparation_ms": stats_ms(prep),
        "feedback_ms": stats_ms(feedback),
        "step_ms": stats_ms(whole),
        "planner_ms": stats_ms(planner),
        "step_with_planner_ms": stats_ms(whole + planner),
        "deadline_misses": int(np.sum(whole > period_ms)),
        "misses_at_500Hz": int(np.sum(whole > 2.0)),
        "qp_failures": nmpc.failures,
        "qp_iterations": {"mean": float(iters.mean()), "p99": float(np.percentile(iters, 99)), "max": int(iters.max())},
        "step_p99_over_p50": float(np.percentile(whole + planner, 99) / np.percentile(whole + planner, 50)),
        "route": nmpc.route(),
    }
    if loop.sensing is not None:  # jammer.localization = "estimated": the estimator's update per step
        estimator = np.array([s.estimator_ms for s in timings], float)
        out["estimator_ms"] = stats_ms(estimator)
        out["step_with_planner_and_estimator_ms"] = stats_ms(whole + planner + estimator)
    points = [(p.x, p.u_prev, p.P, p.guess) for p in loop.bench_points[relay.name] if p.guess is not None][:ipopt_points]
    if points:
        nlp = FullNlp(nmpc.spec)
        lbz, ubz = nmpc.absolute_bounds()
        times, ok = [], 0
        for x, u, P, guess in points:
            xa0, P = nmpc.ocp_data(x, u, P, unpack_plan(nmpc.spec, guess)[1])
            t0 = time.perf_counter()
            _, success = nlp.solve(xa0, P, guess, lbz, ubz)
            times.append((time.perf_counter() - t0) * 1e3)
            ok += success
        out["ipopt_ms"] = stats_ms(times)
        out["ipopt_converged"] = f"{ok}/{len(points)}"
        out["ipopt_over_rti_mean"] = float(np.mean(times) / whole.mean())
    return out


def benchmark_closed_loop(loop, *, ipopt_points: int = 3) -> dict:
    """Fly ``loop`` (a ``sim.closed_loop.ClosedLoop``, any network) and time it: each relay's controller
    (``relay_timing``, under ``relays``), the network planner's step, and the network's step two ways:
    one computer flying every relay in turn (the relays' steps and the planner's summed) and each relay
    on its own computer (the slowest relay's step plus the planner's). Times in ms. The slowest relay's timing is also
    at the top level (``slowest_relay`` names it; one relay: its own), the keys ``aerorelay bench`` prints."""
    collections: dict = {}
    wall0 = time.perf_counter()
    with collections_counted(collections):
        result = loop.run()
    wall = time.perf_counter() - wall0
    log, period_ms = result.log, loop.settings.period_s * 1e3
    planner = np.asarray(loop.planner_ms, float)[: len(log["t"])]
    summed, slowest = planner.copy(), np.zeros_like(planner)
    relays = {}
    for r in loop.relays:
        timings = loop.timings[r.name]
        step = np.full(len(planner), np.nan)
        step[: len(timings)] = [s.prep_ms + s.feedback_ms for s in timings] if timings else []
        flew = np.isfinite(np.asarray(log[f"{r.name}.solve_ms"], float))  # a relay lost in flight times nothing after
        summed[flew] += np.asarray(log[f"{r.name}.solve_ms"], float)[flew]
        slowest = np.maximum(slowest, np.where(flew, np.asarray(log[f"{r.name}.solve_ms"], float), 0.0))
        relays[r.name] = relay_timing(loop, r, period_ms, ipopt_points=ipopt_points)
        if flew.any():  # the shares the verdict reads (verdict.fallback_fraction_max)
            relays[r.name]["fallback_fraction"] = float(np.mean(np.asarray(log[f"{r.name}.fallback"], bool)[flew]))
            relays[r.name]["qp_failure_fraction"] = float(np.mean(~np.asarray(log[f"{r.name}.qp_ok"], bool)[flew]))
    own = slowest + planner
    out = {
        "steps": int(len(planner)),
        "sim_s": result.sim_s,
        "wall_s": wall,
        "real_time_factor": result.sim_s / wall,
        "relays": relays,
        "planner_ms": stats_ms(planner),
        "planner_preflight_s": float(getattr(loop.planner, "preflight_s", 0.0)),
        "planner_reroute_s": [float(v) for v in getattr(loop.planner, "reroute_s", [])],  # beside the loop, not in planner_ms
        "fleet_step_one_computer_ms": stats_ms(summed),
        "fleet_step_own_computers_ms": stats_ms(own),
        "control_period_ms": period_ms,
        "deadline_misses_one_computer": int(np.sum(summed > period_ms)),
        "deadline_misses_own_computers": int(np.sum(own > period_ms)),
        "qp_failures": result.qp_failures,
        "fallback_episodes": result.fallback_episodes,
        "qp_capped": int(sum(np.sum(np.asarray(log[f"{r.name}.qp_status"]) == QpStatus.CAPPED) for r in loop.relays)),
        "c_min": float(np.min(log["capacity"])),
        "garbage_collections": collections,
    }
    # the slowest relay's timing at the top level (its mean step with the planner), named: the same keys for one relay
    # (its own) and for K
    timed = {n: t for n, t in relays.items() if "step_ms" in t}
    if timed:
        slowest_name = max(timed, key=lambda n: timed[n]["step_ms"]["mean"])
        out |= {k: v for k, v in timed[slowest_name].items() if k not in out}  # the fleet's own keys kept
        out["slowest_relay"] = slowest_name
    return out
