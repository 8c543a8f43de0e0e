"""What a bound will cost before it is computed (cells, antenna axes, instants, relays, memory and an
estimated time), and a named error, before any work, when it would not fit this machine or would
take longer than ``[bound] max_minutes`` (issue 45: a K = 4 network bound over a 200 m box ran 300 s
at 2.4 GB with nothing printed; a 200 m one-relay bound and the finest network grid ended in
MemoryError).

The time estimate scales throughputs measured on the project's 2-core VM (2026-12-04, timing
``compute_bound`` / ``compute_network_bound`` uncached: the command is in docs/results/reliability.md):
the one-relay bound evaluates ``cells x axes x instants`` capacities
(the nominal mission: 27,550 x 63 x 95 in 23 s, ``SINGLE_EVALS_PER_S``); the network bound's
relay-relay hops dominate with ``cells^2`` pair terms per hop and instant (``chain_two_relays``:
31 x 7,072^2 in 30 s, ``PAIR_EVALS_PER_S``). The memory estimate is the largest arrays the
computation holds at once: the capacity of every cell and axis at one instant (with numpy's
temporaries, ``TEMPORARIES``) and the best capacity of every cell at every instant; a network
bound's pair-term block (``CHUNK`` rows of cells)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..config import ScenarioError
from .traced_grid import ROWS_PER_CALL

SINGLE_EVALS_PER_S = 7.1e6  # capacities per second, one-relay bound (measured, see the module)
PAIR_EVALS_PER_S = 5.1e7  # pair terms per second, network bound (measured, see the module)
DP_PASSES = 4  # the network bound's passes over every pair of cells an instant: up and down, certified and at the centres
BOX_PAIRS_PER_S = 2.3e6  # pair terms per second of its branch and bound's cubes (measured 2026-12-04: 5.5e6 in 2.4 s)
# planning.network_bound.NetworkBoundSolver's defaults: its worst case a search; 1e6 pairs a level measured as tight as
# 3e6 at a third of the time (network study K = 2, 120 m: 18.33 Mbit/s at t = 30 s either way, 2.1 against 7.1 s)
BRANCH_LEVELS, BRANCH_PAIRS = 6, 1e6
BRANCH_SEARCHES = 2  # searches an instant: the static bound's and the upper path bound's (kept to what the relays can reach)
BRANCH_CELLS = 200_000  # ... and the most cubes a relay may have at a level (one relay alone has no pair terms)
# a traced bound (planning.bound with a ray tracer): Sionna RT on this VM's CPU, street canyon, depth 3, 2026-12-05:
# 1 transmitter to 400 receivers in 3.56 s at 1e5 rays, 22.0 s at 1e6 (python tm.py in docs/results/raytraced.md);
# Munich's meshes 1.4x the street's: the estimate takes 1e-7 s per ray and receiver
TRACE_S_PER_RAY_RECEIVER = 1e-7
TRACED_PATHS, TRACED_PATH_BYTES = 40, 80  # paths a link holds (its widest receiver's) and bytes per path and row
TEMPORARIES = 4  # arrays of one instant's (cells x axes) numpy holds at once in the capacity landscape
CHUNK = 256  # rows of a network bound's pair-term block (planning.network_bound.CHUNK)


class BoundTooLarge(ScenarioError):
    """A bound that would not fit the machine's memory or the time allowed: the message names what to change."""


@dataclass(frozen=True)
class BoundCost:
    """A bound's size: position cells, antenna axes per cell (one-relay bound), instants, relays,
    relay-relay hops, the bytes it holds at once and its estimated wall time (s)."""

    cells: int
    axes: int
    instants: int
    relays: int
    pair_hops: int
    bytes: float
    seconds: float
    combinations: int = 1  # a network's combinations of base-station ends, each bounded on its own


def grid_cells(lo, hi, step: float) -> int:
    """Cells of the position grid of the box ``[lo, hi]`` every ``step`` m (as ``planning.bound.position_grid``)."""
    return math.prod(len(np.arange(lo[i], hi[i] + 1e-9, step)) for i in range(3))


def cube_cells(lo, hi, step: float) -> int:
    """Cubes of side ``step`` m covering the box ``[lo, hi]`` (as ``planning.network_bound.cell_grid``)."""
    return math.prod(max(1, math.ceil((hi[i] - lo[i]) / step - 1e-9)) for i in range(3))


def single_bound_cost(lo, hi, grid_m: float, dt_s: float, duration_s: float, axes: int) -> BoundCost:
    """The one-relay bound's cost (``planning.bound.compute_bound``)."""
    cells, instants = grid_cells(lo, hi, grid_m), int(duration_s / dt_s + 1e-9) + 1
    held = cells * axes * 8 * TEMPORARIES + instants * cells * (8 + 4 + 8 + 8)  # best, best_axis, the DP's values and mask
    return BoundCost(cells, axes, instants, 1, 0, float(held), cells * axes * instants / SINGLE_EVALS_PER_S)


def traced_bound_cost(lo, hi, grid_m: float, dt_s: float, duration_s: float, axes: int, rays: int) -> BoundCost:
    """The one-relay bound's cost on a ray-traced channel: every cell traced from the source at every instant (the fixed
    ends' traces to the cells once, from the tracer's cache afterwards), ``TRACE_S_PER_RAY_RECEIVER`` each, then
    weighed per axis in blocks of ``traced_grid.ROWS_PER_CALL`` (``TRACED_PATHS`` paths of ``TRACED_PATH_BYTES``)."""
    cost = single_bound_cost(lo, hi, grid_m, dt_s, duration_s, axes)
    trace_s = (cost.instants + 2) * cost.cells * rays * TRACE_S_PER_RAY_RECEIVER
    held = cost.bytes + ROWS_PER_CALL * TRACED_PATHS * TRACED_PATH_BYTES * 3 + cost.cells * TRACED_PATHS * TRACED_PATH_BYTES * 3
    return BoundCost(cost.cells, axes, cost.instants, 1, 0, float(held), cost.seconds + trace_s)


def traced_network_bound_cost(lo, hi, grid_m: float, dt_s: float, duration_s: float, relays: int, pair_hops: int,
                              fixed_ends: int, rays: int) -> BoundCost:
    """A fleet's network bound on the traced map (``planning.traced_network_bound``): every cube centre traced to every
    other once per relay-relay hop, each fixed end (sources, jammers) to every centre at each instant, then the
    min-sum's pair terms."""
    cells, instants = cube_cells(lo, hi, grid_m), int(duration_s / dt_s + 1e-9) + 1
    trace_s = (pair_hops * cells + instants * fixed_ends) * cells * rays * TRACE_S_PER_RAY_RECEIVER
    held = (pair_hops + 1) * cells * cells * 8 * 3 + cells * TRACED_PATHS * TRACED_PATH_BYTES * 3
    return BoundCost(cells, 0, instants, relays, pair_hops, float(held),
                     trace_s + instants * DP_PASSES * pair_hops * cells**2 / PAIR_EVALS_PER_S)


def network_bound_cost(lo, hi, grid_m: float, dt_s: float, duration_s: float, relays: int, pair_hops: int,
                       combinations: int = 1, *, global_seconds: float = 0.0, branch_levels: int = BRANCH_LEVELS,
                       branch_pairs: float = BRANCH_PAIRS) -> BoundCost:
    """A fleet's network bound's cost (``planning.network_bound.compute_network_bound``): its passes over every pair
    of cubes and its branch and bound's worst case, each instant, for each of the ``combinations`` of base-station
    ends its routes may take (each bounded on its own; the branch and bound's worst case: ``branch_levels`` levels of
    ``branch_pairs`` pair terms, twice a search); with ``global_seconds``, SCIP's time limit twice at every
    instant too (its worst case: the static problem and the one kept to the relays' reach, ``_reach_limited``)."""
    cells, instants = cube_cells(lo, hi, grid_m), int(duration_s / dt_s + 1e-9) + 1
    held = CHUNK * cells * 8 * 3 + relays * cells * 8 * 8
    branch = (BRANCH_SEARCHES * 2 * branch_levels * branch_pairs / BOX_PAIRS_PER_S) if pair_hops else 0.0
    seconds = instants * (DP_PASSES * pair_hops * float(cells) ** 2 / PAIR_EVALS_PER_S + relays * cells * 64 / SINGLE_EVALS_PER_S
                          + branch + 2 * global_seconds) * combinations
    return BoundCost(cells, 0, instants, relays, pair_hops, float(held), seconds, combinations)


def machine_memory_bytes() -> int:
    """This machine's physical memory (bytes)."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_bound_cost(cost: BoundCost, *, max_minutes: float, grid_field: str, dt_field: str,
                     memory_bytes: int | None = None) -> None:
    """BoundTooLarge, naming the fields to change and by how much, when ``cost`` needs more than half of
    this machine's memory or more than ``max_minutes`` of estimated time."""
    memory = machine_memory_bytes() if memory_bytes is None else memory_bytes
    size = (f"{cost.cells:,} cells" + (f" x {cost.axes} axes" if cost.axes else "") + f" x {cost.instants} instants"
            + (f", {cost.relays} relays ({cost.pair_hops} relay-relay hops, cost ~ cells^2 each)" if cost.pair_hops else "")
            + (f", x {cost.combinations} combinations of base-station ends" if cost.combinations > 1 else ""))
    # the grid scales cells as step^-3 (memory, one-relay time) or step^-6 (pair terms): the coarsening that fits both
    over_memory, over_time = cost.bytes / (memory / 2), cost.seconds / (max_minutes * 60.0)
    if over_memory <= 1 and over_time <= 1:
        return
    factor = max(over_memory ** (1 / 3), over_time ** (1 / (6.0 if cost.pair_hops else 3.0)))
    needs = []
    if over_memory > 1:
        needs.append(f"holds ~{cost.bytes / 1e9:.3g} GB at once, more than half of this machine's {memory / 1e9:.0f} GB")
    if over_time > 1:
        needs.append(f"would take ~{cost.seconds / 60:.3g} min here, more than bound.max_minutes = {max_minutes:g}")
    raise BoundTooLarge(f"{grid_field}: the bound {' and '.join(needs)} ({size}); a grid about {factor:.3g}x coarser fits "
                        f"(or a coarser {dt_field}, a smaller controller.workspace, fewer relays"
                        + (", a larger bound.max_minutes" if over_memory <= 1 else "") + "; or --no-bound)")
