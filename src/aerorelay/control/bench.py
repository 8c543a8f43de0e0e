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


def benchmark_closed_loop(loop, *, ipopt_points: int = 3) -> dict:
    """Fly ``loop`` (a ClosedLoop) and time its controller; time IPOPT at a few visited states."""
    collections: dict = {}
    wall0 = time.perf_counter()
    with collections_counted(collections):
        result = loop.run()
    wall = time.perf_counter() - wall0
    prep, feedback, iters, planner = (np.array([getattr(s, f) for s in loop.timings], float)
                                      for f in ("prep_ms", "feedback_ms", "qp_iters", "planner_ms"))
    whole = prep + feedback
    period_ms = loop.settings.period_s * 1e3
    out = {
        "steps": int(len(prep)),
        "sim_s": result.sim_s,
        "wall_s": wall,
        "real_time_factor": result.sim_s / wall,
        "preparation_ms": stats_ms(prep),
        "feedback_ms": stats_ms(feedback),
        "step_ms": stats_ms(whole),
        "planner_ms": stats_ms(planner),
        "step_with_planner_ms": stats_ms(whole + planner),
        "planner_preflight_s": float(getattr(loop.planner, "preflight_s", 0.0)),
        "control_period_ms": period_ms,
        "deadline_misses": int(np.sum(whole > period_ms)),
        "misses_at_500Hz": int(np.sum(whole > 2.0)),
        "qp_failures": result.qp_failures,
        "fallback_episodes": result.fallback_episodes,
        "qp_iterations": {"mean": float(iters.mean()), "p99": float(np.percentile(iters, 99)), "max": int(iters.max())},
        "qp_capped": int(np.sum(np.asarray(result.log["qp_status"]) == QpStatus.CAPPED)),
        "step_p99_over_p50": float(np.percentile(whole + planner, 99) / np.percentile(whole + planner, 50)),
        "c_min": float(np.min(result.log["capacity"])),
        "route": loop.nmpc.route(),
        "garbage_collections": collections,
    }
    if getattr(loop, "sensing", None) is not None:  # jammer.localization = "estimated": the estimator's update per step
        estimator = np.array([s.estimator_ms for s in loop.timings], float)
        out["estimator_ms"] = stats_ms(estimator)
        out["step_with_planner_and_estimator_ms"] = stats_ms(whole + planner + estimator)
    points = [(p.x, p.u_prev, p.P, p.guess) for p in loop.bench_points if p.guess is not None][:ipopt_points]
    if points:
        nlp = FullNlp(loop.nmpc.spec)
        lbz, ubz = loop.nmpc.absolute_bounds()
        times, ok = [], 0
        for x, u, P, guess in points:
            xa0, P = loop.nmpc.ocp_data(x, u, P, unpack_plan(loop.nmpc.spec, guess)[1])
            t0 = time.perf_counter()
            _, success = nlp.solve(xa0, P, guess, lbz, ubz)
            times.append((time.perf_counter() - t0) * 1e3)
            ok += success
        out["ipopt_ms"] = stats_ms(times)
        out["ipopt_converged"] = f"{ok}/{len(points)}"
        out["ipopt_over_rti_mean"] = float(np.mean(times) / whole.mean())
    return out


def benchmark_fleet(loop) -> dict:
    """Fly ``loop`` (a FleetLoop) and time it: each relay's controller step (preparation, feedback,
    deadline misses, over the steps it flew), the fleet planner's step, and the fleet's step two ways:
    one computer flying every relay in turn (the relays' steps and the planner's summed) and each
    relay on its own computer (the slowest relay's step plus the planner's). Times in ms."""
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
        step = np.asarray(log[f"{r.name}.solve_ms"], float)
        feedback = np.asarray(log[f"{r.name}.feedback_ms"], float)
        flew = np.isfinite(step)  # a relay lost in flight times nothing after
        summed[flew] += step[flew]
        slowest = np.maximum(slowest, np.where(flew, step, 0.0))
        relays[r.name] = {"preparation_ms": stats_ms(step[flew] - feedback[flew]), "feedback_ms": stats_ms(feedback[flew]),
                          "step_ms": stats_ms(step[flew]), "deadline_misses": int(np.sum(step[flew] > period_ms)),
                          "qp_failures": r.controller.nmpc.failures, "steps": int(flew.sum())}
    own = slowest + planner
    return {
        "steps": int(len(planner)),
        "sim_s": result.sim_s,
        "wall_s": wall,
        "real_time_factor": result.sim_s / wall,
        "relays": relays,
        "planner_ms": stats_ms(planner),
        "fleet_step_one_computer_ms": stats_ms(summed),
        "fleet_step_own_computers_ms": stats_ms(own),
        "control_period_ms": period_ms,
        "deadline_misses_one_computer": int(np.sum(summed > period_ms)),
        "deadline_misses_own_computers": int(np.sum(own > period_ms)),
        "qp_failures": result.qp_failures,
        "fallback_episodes": result.fallback_episodes,
        "c_min": float(np.min(log["capacity"])),
        "garbage_collections": collections,
    }
