"""A time budget for ``reproduce --quick``: which runs fit in a few minutes, and what is left out.

Each run's cost is estimated from what it flies, calibrated on a --quick campaign on the
project's 2-core VM, two dask workers (2026-12-03, per-run wall times in its manifest): the closed
loop at ``SIM_S_PER_MISSION_S`` of wall time per simulated second (nominal 47 s mission: 5.9-8.4 s
per run), a fixed ``RUN_OVERHEAD_S`` per run (scenario, parts, compiled library), and a capacity
bound at ``BOUND_S_PER_MISSION_S`` the first time a geometry is seen (moving jammer, speed and
energy studies: 60-90 s for 47 s; cached afterwards), ``RANDOM_BOUND_FACTOR`` times that over a
run's own shadowing realization (one per seed: ~190 s). Runs are taken round-robin over the studies, each study's
runs in order, so every study keeps its first runs; the others are left out and named. A ray-traced channel adds
``TRACE_S`` per trace at Sionna's default 1e6 rays per transmitter (Sionna RT on the CPU, street canyon, depth 3,
every link of one relay: 207 s against 21 s for the 47 s mission traced every 0.25 s, 2026-12-05), in proportion to
``rays_per_source`` down to ``TRACE_FLOOR`` of it (1e5 rays: 44 s against 253 s for the same mission), and
``TRACE_STARTUP_S`` (the scene and the first trace's compilation); a bound on a traced channel at
``planning.bound_cost``'s estimate of its traced map."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..assembly.parts import bound_cost, scenario_bound_key
from ..config import Scenario, ScenarioError
from .study import RunSpec, scenario_of

SIM_S_PER_MISSION_S = 0.12
RUN_OVERHEAD_S = 3.0
BOUND_S_PER_MISSION_S = 1.6
RANDOM_BOUND_FACTOR = 2.5  # a bound over the run's own shadowing / LoS realization (one per seed) costs this much more
TRACE_S = 1.0
TRACE_FLOOR = 0.15
TRACE_STARTUP_S = 6.0


@dataclass(frozen=True)
class BudgetChoice:
    """The runs kept within the budget, those left out, and the estimated wall time of the kept (s)."""

    kept: list[RunSpec]
    left_out: list[RunSpec]
    estimated_s: float


def flight_seconds(sc: Scenario) -> tuple[float, int]:
    """A flight's estimated wall time here (s), its bound left out, and the traces it takes (0 on an analytic
    channel): the closed loop per simulated second, each trace in proportion to ``rays_per_source``."""
    cost = RUN_OVERHEAD_S + SIM_S_PER_MISSION_S * sc.duration_s * len(sc.relay_list)
    prop = sc.channel.propagation
    if prop.model != "ray_traced":
        return cost, 0
    traces = math.ceil(sc.duration_s / max(prop.trace_period_s, sc.control_period_s))
    per_trace = TRACE_S * max(prop.rays_per_source / 1e6, TRACE_FLOOR) * len(sc.relay_list)
    return cost + TRACE_STARTUP_S + per_trace * traces, traces


def check_flight_time(sc: Scenario) -> None:
    """A named error (ScenarioError) before any work when the flight is estimated to take longer than
    ``sim.max_minutes`` here, naming what to change (a traced channel's rays and trace period first)."""
    seconds, traces = flight_seconds(sc)
    most = sc.sim.max_minutes
    if seconds <= 60.0 * most:
        return
    prop = sc.channel.propagation
    what = (f"{traces} traces at channel.propagation.rays_per_source = {prop.rays_per_source:.3g} every "
            f"trace_period_s = {prop.trace_period_s:g} s" if traces else f"{sc.duration_s:g} s of closed loop")
    fix = ("fewer rays_per_source, a longer trace_period_s, a shorter sim.duration_s" if traces else "a shorter sim.duration_s")
    raise ScenarioError(f"sim.max_minutes: this flight would take about {seconds / 60.0:.3g} min here ({what}), more "
                        f"than sim.max_minutes = {most:g}; {fix}, or a larger sim.max_minutes")


def run_cost_s(spec: RunSpec, bounds_seen: set[str]) -> float:
    """Estimated worker-seconds of one run (its bound counted once per geometry: ``bounds_seen``)."""
    sc = scenario_of(spec)
    cost, _ = flight_seconds(sc)
    prop = sc.channel.propagation
    if spec.bound:
        key = scenario_bound_key(sc)
        if key not in bounds_seen:
            bounds_seen.add(key)
            factor = RANDOM_BOUND_FACTOR if sc.channel.propagation.random else 1.0
            # a traced map's bound is its tracing: planning.bound_cost's estimate (the analytic rate does not hold); an
            # analytic one at least the calibrated rate, and the grid's estimate where that is more (aerorelay design's
            # far source at the one relay's 0.5 m grid: 940,000 cells a step, 16 min and 6 GB, estimated at 1.6 min)
            calibrated = BOUND_S_PER_MISSION_S * factor * sc.duration_s
            cost += bound_cost(sc).seconds if prop.model == "ray_traced" else max(calibrated, bound_cost(sc).seconds)
    return cost


def within_budget(specs: list[RunSpec], budget_s: float, workers: int) -> BudgetChoice:
    """The runs that fit in ``budget_s`` of wall time on ``workers`` workers, taken round-robin
    over the studies in their order (each study's runs in order)."""
    by_study: dict[str, list[RunSpec]] = {}
    for s in specs:
        by_study.setdefault(s.study, []).append(s)
    queues = [list(v) for v in by_study.values()]
    kept: list[RunSpec] = []
    seen: set[str] = set()
    total = 0.0
    full = False
    while any(queues) and not full:
        for q in queues:
            if not q:
                continue
            trial = set(seen)
            cost = run_cost_s(q[0], trial)
            if (total + cost) / max(workers, 1) > budget_s:
                full = True
                break
            kept.append(q.pop(0))
            seen, total = trial, total + cost
    chosen = {s.key for s in kept}
    return BudgetChoice([s for s in specs if s.key in chosen], [s for s in specs if s.key not in chosen], total / max(workers, 1))


def left_out_notices(choice: BudgetChoice, budget_s: float) -> list[str]:
    """What a budget left out, one line per study (its runs named), and what the kept runs cost."""
    if not choice.left_out:
        return [f"budget {budget_s / 60:.1f} min: every run fits (estimated {choice.estimated_s / 60:.1f} min)"]
    by_study: dict[str, list[str]] = {}
    for s in choice.left_out:
        by_study.setdefault(s.study, []).append(s.group if s.seed == 0 else f"{s.group} seed {s.seed}")
    lines = [f"budget {budget_s / 60:.1f} min: {len(choice.kept)} runs kept (estimated {choice.estimated_s / 60:.1f} min), "
             f"{len(choice.left_out)} left out (run without --quick, or with a larger --budget-min, for them):"]
    lines += [f"  left out of {study}: {', '.join(groups)}" for study, groups in by_study.items()]
    return lines
