"""The best network the physics allows: a certified upper bound on a fleet's rate, per instant.

The network rate ``R = B / sum_s sum_{k in route s} 1/log2(1 + Gamma_{s,k})`` (``models.radio.
network_rate``) is largest where the sum of the hops' terms is smallest. The workspace box is covered
by cubes of side ``bound.network_grid_m`` (``cell_grid``), and every hop's term is bounded from below
over whole cubes (``models/intervals.py``: the link's least length, floored at the separation, for the
largest path gain; its exact elevation range for each relay end's best gain over every holdable axis,
``[sin(e - tilt), sin(e + tilt)]``; the cone a cube subtends at a fixed node for that node's gain; each
pattern's exact ``gain_bounds``; each relay receiver's jammer interference from below: the relay may
put its null on a jammer). A relay's axis is relaxed per hop (its hops need not agree on it), so the
bound holds over every configuration. That is a min-sum problem whose variables are the relays' cubes:
a hop between a fixed node (a source at its pose on its mission, the base station) and a relay is a
term of that relay's cube, a hop between two relays a term of the pair. When the relays' hops form a
forest (every chain, and routes that merge toward the base station like two sources sharing a chain),
``forest_min_marginals`` solves it exactly with each relay's min-marginals, ``O(cubes^2)`` per
relay-relay hop. Best-first branch and bound then drops the cubes that cannot hold the optimum (their
marginal above a refined configuration's sum) and splits those with the least marginals in eight, as many
as a level's work allows, cubes of several sizes side by side (``NetworkBoundSolver.certify``); the upper
path bound's per-cube terms are tightened by the same search (``_reachable_tightened``).

``achieved``: a configuration the physics allows at that instant, refined on the true network rate
(L-BFGS-B, or SLSQP with the separation, positions and axes jointly) from three starts; the true
optimum lies between ``achieved`` and ``static``, ``resolution.certified_gap_*`` says how far apart.

One relay on one route is the single-relay bound (``planning.bound``): the composition root
dispatches it there.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from itertools import product

import numpy as np
import pandas as pd

from ..models.antenna import gain_bounds
from ..models.intervals import axis_cos_range, cone_cos_range, distance_range, link_ranges
from ..models.mission import SourceTrajectory
from ..models.radio import NodePose, RadioScene, link_gain, route_via, spectral_efficiency
from .bound import BoundResolution, _dp
from .bound_cost import BRANCH_CELLS, BRANCH_LEVELS, BRANCH_PAIRS
from .fleet_configuration import FleetConfigurations, flyable_fleet_path, mission_poses
from .network_bound_global import GlobalResult, expressible, solve_static

NETWORK_BOUND_VERSION = "8"  # bump when the computation changes: cached network bounds are recomputed
CUBE_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)  # in half-sides
CHUNK = 256  # rows of a pair-term block (cells x cells, float64): 256 measured 1.5x faster than 2048 (cache)

ASSUMPTIONS = ("small-scale fading ignored; every relay anywhere in the workspace box (covered by the cubes) at least "
               "the separation from the sources, the base station and its route neighbours (not from relays it shares no "
               "hop with); certified upper bound: every hop's term bounded over whole cubes, each hop taking at each "
               "relay end the best gain any holdable axis gives (tilt up to the hover limit, yaw free) and each relay "
               "receiver the least jammer interference over its axis cone, so a relay's hops need not agree on its axis "
               "(exact for isotropic relays); min-sum dynamic programming over the relays' cubes (exact for a forest "
               "of relay-relay hops), branch and bound within a work cap; achieved: a configuration refined on the "
               "true rate with one axis per relay")


@dataclass(frozen=True)
class NetworkBoundProblem:
    """What a network bound depends on: the radio scene (its routes), each source's path, each
    relay's hover tilt limit (rad), the workspace box (m, world), the mission length (s), the
    resolution (``[bound]``) and the outage threshold."""

    scene: RadioScene
    sources: Mapping[str, SourceTrajectory]
    tilt_limits: Mapping[str, float]
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    duration_s: float
    resolution: BoundResolution
    gravity: float = 9.81
    outage_threshold: float = 1e-3
    separation_m: float = 0.0  # every relay at least this far (m) from the fixed nodes and its route neighbours
    starts: Mapping[str, np.ndarray] = field(default_factory=dict)  # each relay's start (m, world): the flyable path's
    obstacles: tuple = ()  # models.obstacles shapes grown by their margins: no relay inside one
    branch_levels: int = BRANCH_LEVELS  # the branch and bound's levels at most (every level's bound is certified)
    branch_pairs: float = BRANCH_PAIRS  # ... and the pair terms one level may bound at most
    global_seconds: float = 0.0  # SCIP's time per instant for the global static bound (0: not solved)
    global_gap: float = 1e-3  # SCIP's relative gap to stop at
    global_nodes: int | None = None  # SCIP's nodes at most per instant (None: the time limit alone; tests fix the work)


@dataclass
class NetworkBound:
    """Per instant of the bound's time grid (s): the static upper bound on the network rate and the
    relays' cells that reach it on the grid, and the refined configuration's true rate (positions m
    and axes, world, ``(T, K, 3)``, relays in ``relays`` order)."""

    t: np.ndarray
    static: np.ndarray
    static_positions: np.ndarray
    achieved: np.ndarray
    achieved_positions: np.ndarray
    achieved_axes: np.ndarray
    relays: list[str]
    resolution: dict = field(default_factory=dict)
    outage_threshold: float = 1e-3
    assumptions: str = ASSUMPTIONS
    # the flyable fleet path (a lower estimate of the best fleet path; empty: not computed): its true rate
    # ``(T,)`` (NaN after a relay is lost), positions and axes ``(T, K, 3)``
    flyable: np.ndarray = field(default_factory=lambda: np.empty(0))
    flyable_positions: np.ndarray = field(default_factory=lambda: np.empty((0, 0, 3)))
    flyable_axes: np.ndarray = field(default_factory=lambda: np.empty((0, 0, 3)))
    # the upper path bound (``NetworkBoundSolver.upper_path``; empty: not computed): per instant ``(T,)`` along the
    # binding relay's best path (``resolution["path_mean_relay"]``), whose cube centres are ``path_mean_position``
    path_mean: np.ndarray = field(default_factory=lambda: np.empty(0))
    path_mean_position: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))

    def __post_init__(self):
        self.relays = [str(r) for r in self.relays]  # a cached bound's names come back as a numpy array

    def summary(self) -> dict:
        """``bound.json``: mean / min / outage of the static bound and the achieved configuration."""
        def stats(c: np.ndarray) -> dict:
            return {"mean": float(c.mean()), "min": float(c.min()), "outage_fraction": float(np.mean(c < self.outage_threshold))}

        out = {"static": stats(self.static), "achieved": stats(self.achieved), "relays": self.relays,
               "resolution": self.resolution, "assumptions": self.assumptions}
        flown = self.flyable[np.isfinite(self.flyable)]
        if flown.size:
            out["flyable"] = {**stats(flown), "until_s": float(self.t[: flown.size][-1])}
        upper = self.path_mean[np.isfinite(self.path_mean)]
        if upper.size:
            out["path_mean"] = {**stats(upper), "until_s": float(self.t[: upper.size][-1])}
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {"t": self.t, "static": self.static, "static_positions": self.static_positions, "achieved": self.achieved,
                "achieved_positions": self.achieved_positions, "achieved_axes": self.achieved_axes,
                "relays": np.array(self.relays), "flyable": self.flyable, "flyable_positions": self.flyable_positions,
                "flyable_axes": self.flyable_axes,
                "path_mean": self.path_mean, "path_mean_position": self.path_mean_position}

    def frame(self) -> pd.DataFrame:
        cols: dict[str, np.ndarray] = {"t": self.t, "static": self.static, "achieved": self.achieved}
        fly = len(self.flyable) == len(self.t)
        if fly:
            cols["flyable"] = self.flyable
        if len(self.path_mean) == len(self.t):
            cols["path_mean"] = self.path_mean
            for i, ax in enumerate("xyz"):
                cols[f"path_mean.p_{ax}"] = self.path_mean_position[:, i]
        for k, name in enumerate(self.relays):
            for i, ax in enumerate("xyz"):
                cols[f"static.{name}.p_{ax}"] = self.static_positions[:, k, i]
                cols[f"achieved.{name}.p_{ax}"] = self.achieved_positions[:, k, i]
                cols[f"achieved.{name}.axis_{ax}"] = self.achieved_axes[:, k, i]
                if fly:
                    cols[f"flyable.{name}.p_{ax}"] = self.flyable_positions[:, k, i]
                    cols[f"flyable.{name}.axis_{ax}"] = self.flyable_axes[:, k, i]
        return pd.DataFrame(cols)


def relay_forest(routes: Sequence[Sequence[str]], relays: Sequence[str]) -> tuple[list, dict]:
    """The hops as terms: ``unary`` ``[(relay, other node, relay is tx, count)]`` for hops between a relay
    and a fixed node, ``pairs`` ``{(tx, rx): count}`` between two relays; ``ValueError`` when the
    relay-relay hops hold a cycle (no exact min-sum by elimination)."""
    unary: dict[tuple[str, str, bool], int] = {}
    pairs: dict[tuple[str, str], int] = {}
    rs = set(relays)
    for r in routes:
        for tx, rx in zip(r[:-1], r[1:], strict=True):
            if tx in rs and rx in rs:
                pairs[tx, rx] = pairs.get((tx, rx), 0) + 1
            elif tx in rs or rx in rs:
                key = (tx, rx, True) if tx in rs else (rx, tx, False)
                unary[key] = unary.get(key, 0) + 1
    parent = {r: r for r in relays}

    def root(a):
        while parent[a] != a:
            a = parent[a]
        return a
    for a, b in {tuple(sorted(p)) for p in pairs}:
        ra, rb = root(a), root(b)
        if ra == rb:
            raise ValueError(f"network bound: the relays' hops form a cycle through {a!r} and {b!r}; no exact bound")
        parent[ra] = rb
    return [(r, o, is_tx, n) for (r, o, is_tx), n in unary.items()], pairs


class OffsetTable:
    """Every displacement between two cells of a regular grid of ``shape`` cells ``step`` m apart
    (``vectors``, ``(2 nx - 1) (2 ny - 1) (2 nz - 1)`` of them, m) and, for a block of cells against
    every cell, the index of their displacement in it (one subtraction: the cells' flat offsets are
    linear in their grid indices)."""

    def __init__(self, shape: Sequence[int], step: float):
        n = np.asarray(shape, np.int64)
        span = 2 * n - 1
        strides = np.array([span[1] * span[2], span[2], 1], np.int64)
        ix = np.indices(tuple(int(k) for k in n)).reshape(3, -1).T  # each cell's grid index, in position_grid's (ij) order
        self.flat = ix @ strides
        self.centre = int((n - 1) @ strides)
        o = np.indices(tuple(int(k) for k in span)).reshape(3, -1).T - (n - 1)
        self.vectors = o * float(step)

    def between(self, rows: slice, rows_are_tx: bool) -> np.ndarray:
        """``(rows, M)`` indices into ``vectors`` of the link from ``rows`` to every cell
        (``rows_are_tx``), or from every cell to ``rows``."""
        here, there = self.flat[rows][:, None], self.flat[None, :]
        return (there - here if rows_are_tx else here - there) + self.centre


def cell_grid(lo, hi, step: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Grid axes and ``(M, 3)`` centres of cubes of side ``step`` (m) that cover the box ``[lo, hi]``: the first
    cube's corner at ``lo``, as many along each axis as reach ``hi`` (the last may reach past it)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    n = np.maximum(1, np.ceil((hi - lo) / step - 1e-9).astype(int))
    grid = [lo[i] + step * (0.5 + np.arange(n[i])) for i in range(3)]
    X, Y, Z = np.meshgrid(*grid, indexing="ij")
    return grid, np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])


def cube_footprint(reach_m: float, side_m: float) -> np.ndarray:
    """The cubes (side ``side_m``, m) a point in the centre cube can reach moving at most ``reach_m`` (m): those
    whose least distance to it, ``side * |max(|offset| - 1, 0)|`` in cells, is at most ``reach_m`` (boolean,
    odd on each axis, centred)."""
    r = int(np.floor(reach_m / side_m + 1e-9)) + 1
    g = np.arange(-r, r + 1)
    off = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1)
    gap = side_m * np.linalg.norm(np.maximum(np.abs(off) - 1, 0), axis=-1)
    return gap <= reach_m + 1e-9


def reach_from_rest(t: np.ndarray, max_speed: float, max_accel: float | None) -> np.ndarray:
    """The farthest (m) a vehicle at rest at ``t = 0`` can be from its start at ``t`` (s) with speed at most
    ``max_speed`` (m/s) and acceleration at most ``max_accel`` (m/s^2; None: unbounded): ``a t^2 / 2`` while
    speeding up, then ``v t - v^2 / (2 a)`` (along a straight line at full acceleration, then full speed)."""
    t = np.asarray(t, float)
    if max_accel is None:
        return max_speed * t
    t_up = max_speed / max_accel
    return np.where(t <= t_up, 0.5 * max_accel * t**2, max_speed * t - max_speed**2 / (2.0 * max_accel))


def forest_min_marginals(nodes: Sequence[str], unary: Mapping[str, np.ndarray], neighbours: Mapping[str, set],
                         block) -> tuple[float, dict[str, np.ndarray]]:
    """The min-sum of ``unary`` terms and pair terms over a forest (``neighbours``), exactly, and each node's
    min-marginal (the least total with that node at each of its states): messages up from the leaves and
    back down. ``block(a, b, rows)``: the pair terms ``(len(rows), n_b)`` of ``a``'s states ``rows`` against
    every state of ``b``."""
    remaining, order = set(nodes), []
    parent: dict[str, str | None] = {}
    while remaining:
        leaf = next(n for n in nodes if n in remaining and len(neighbours[n] & remaining) <= 1)
        remaining.discard(leaf)
        order.append(leaf)
        rest = neighbours[leaf] & remaining
        parent[leaf] = next(iter(rest)) if rest else None
    msgs: dict[tuple[str, str], np.ndarray] = {}

    def belief(a: str, without: str | None) -> np.ndarray:
        v = np.array(unary[a], float)
        for c in neighbours[a]:
            if c != without and (c, a) in msgs:
                v = v + msgs[c, a]
        return v

    def message(a: str, b: str) -> np.ndarray:
        v, n_a = belief(a, b), len(unary[a])
        out = np.full(len(unary[b]), np.inf)
        for start in range(0, n_a, CHUNK):
            rows = slice(start, min(start + CHUNK, n_a))
            out = np.minimum(out, (v[rows][:, None] + block(a, b, rows)).min(axis=0))
        return out

    for a in order:
        p = parent[a]
        if p is not None:
            msgs[a, p] = message(a, p)
    for a in reversed(order):
        p = parent[a]
        if p is not None:
            msgs[p, a] = message(p, a)
    marginals = {n: belief(n, None) for n in nodes}
    return float(sum(marginals[n].min() for n in nodes if parent[n] is None)), marginals


@dataclass
class CellSets:
    """Each relay's cells at one level of the search: centres ``(n_r, 3)`` (m) of cubes of half-sides ``(n_r,)``
    (m; cubes of several sizes side by side), and the grid's cube each lies in (``roots``, ``(n_r,)``)."""

    centres: dict[str, np.ndarray]
    halves: dict[str, np.ndarray]
    roots: dict[str, np.ndarray]

    def split(self, keep: Mapping[str, np.ndarray], split: Mapping[str, np.ndarray]) -> CellSets:
        """The cells ``keep`` (boolean per cell) as they are and the cells ``split`` (within ``keep``) in eight."""
        centres, halves, roots = {}, {}, {}
        for r, c in self.centres.items():
            stay, cut = keep[r] & ~split[r], split[r]
            h = self.halves[r][cut] / 2.0
            centres[r] = np.concatenate([c[stay], (c[cut][:, None, :] + h[:, None, None] * CUBE_CORNERS[None]).reshape(-1, 3)])
            halves[r] = np.concatenate([self.halves[r][stay], np.repeat(h, 8)])
            roots[r] = np.concatenate([self.roots[r][stay], np.repeat(self.roots[r][cut], 8)])
        return CellSets(centres, halves, roots)


class NetworkBoundSolver:
    """The per-instant certified bound (one instance per problem): every hop's term bounded from below over
    whole cells (cubes of side ``bound.network_grid_m`` covering the workspace box), a min-sum over the
    relays' cells, then branch and bound (cells that cannot hold the optimum dropped, the others split in
    eight) until the bound is within ``tolerance`` of a configuration the physics allows."""

    def __init__(self, pb: NetworkBoundProblem, tolerance: float = 0.01, max_levels: int | None = None,
                 max_pairs: float | None = None):
        self.pb, self.scene = pb, pb.scene
        self.tolerance, self.max_pairs = tolerance, pb.branch_pairs if max_pairs is None else max_pairs
        self.max_levels = pb.branch_levels if max_levels is None else max_levels
        self.relays = [n.name for n in pb.scene.nodes if n.role == "relay"]
        self.unary, self.pairs = relay_forest(pb.scene.all_routes, self.relays)
        # hops between two nodes the bound does not place (a route that skips every relay: the direct link): exact terms
        self.fixed_hops: dict[tuple[str, str], int] = {}
        for route in pb.scene.all_routes:
            for h in zip(route[:-1], route[1:], strict=True):
                if h[0] not in self.relays and h[1] not in self.relays:
                    self.fixed_hops[h] = self.fixed_hops.get(h, 0) + 1
        aimed = [j.name for j in pb.scene.jammers if j.point_at in self.relays]
        if aimed:
            raise ValueError(f"network bound: jammer(s) {aimed} aim at a relay, whose place the bound searches; not supported")
        unbounded = [n.name for n in pb.scene.nodes if not hasattr(n.antenna.pattern, "gain_bounds")]
        unbounded += [j.name for j in pb.scene.jammers if not hasattr(j.pattern, "gain_bounds")]
        if unbounded:
            raise ValueError(f"network bound: the antennas of {unbounded} have no gain_bounds (their least and largest gain "
                             "over an interval of directions): no certified bound")
        res = pb.resolution
        self.lo, self.hi = np.asarray(pb.workspace_min, float), np.asarray(pb.workspace_max, float)
        grid, self.cells = cell_grid(self.lo, self.hi, res.grid_m)
        self.shape = tuple(len(g) for g in grid)
        self.half = 0.5 * res.grid_m
        self.configurations = FleetConfigurations(pb.scene, self.relays, self.lo, self.hi, pb.tilt_limits,
                                                  np.radians(res.axis_step_deg), pb.separation_m, pb.obstacles)
        self.offsets = OffsetTable([len(g) for g in grid], res.grid_m)
        self.signal = {(tx, rx): self.signal_bound(tx, rx, self.offsets.vectors, 2.0 * self.half) for tx, rx in self.pairs}
        # at the cubes' centres alone (the relaxed terms of the grid's points): where the refinement starts from
        self.signal_at_centres = {(tx, rx): self.signal_bound(tx, rx, self.offsets.vectors, 0.0) for tx, rx in self.pairs}
        self.edges: dict[tuple, list[tuple[str, str, int]]] = {tuple(sorted(p)): [] for p in self.pairs}
        for (tx, rx), count in self.pairs.items():
            self.edges[tuple(sorted((tx, rx)))].append((tx, rx, count))
        self.neighbours: dict[str, set] = {r: set() for r in self.relays}
        for a, b in self.edges:
            self.neighbours[a].add(b)
            self.neighbours[b].add(a)

    # -- channel pieces, bounded over cubes ----------------------------------------------------
    def fixed_poses(self, t: float) -> dict[str, NodePose]:
        """Every source at its pose on its mission at ``t``, the fixed nodes as placed."""
        return mission_poses(self.scene, self.pb.sources, t, self.pb.gravity)

    def _path_most(self, r_min: np.ndarray) -> np.ndarray:
        """The largest path gain of a link at least ``r_min`` m long (and at least the separation): the gain
        falls with the length (RMa-AV: its upper bound over aerial heights, ``gain_from_d2``)."""
        r = np.maximum(r_min, self.pb.separation_m)
        with np.errstate(divide="ignore"):
            return np.asarray(self.scene.path_gain.gain_from_d2(r * r), float)

    def _path_least(self, r_max: np.ndarray) -> np.ndarray:
        """The least path gain of a link at most ``r_max`` m long: a length-only gain at ``r_max``; 0 for a gain
        that depends on where the ends are (no lower bound taken)."""
        pg = self.scene.path_gain
        return np.asarray(pg.gain_from_d2(r_max * r_max), float) if pg.distance_only else np.zeros(np.shape(r_max))

    def relay_gains(self, relay: str, s_lo, s_hi) -> tuple[np.ndarray, np.ndarray]:
        """Least and largest gain of ``relay``'s antenna toward directions whose elevations' sines are within
        ``[s_lo, s_hi]`` (``intervals.link_ranges``) over every axis it can hold (tilt up to its hover limit, any yaw)."""
        return gain_bounds(self.scene.node(relay).antenna.pattern, *cone_cos_range(s_lo, s_hi, self.pb.tilt_limits[relay]))

    def least_interference(self, t: float, relay: str, poses: Mapping[str, NodePose], centres=None, half=None) -> np.ndarray:
        """``(n,)`` W: a lower bound of the jammers' interference at ``relay``'s receiver anywhere in each cube
        (``centres``, half-side ``half``; default the grid's) with any axis of its cone."""
        centres = self.cells if centres is None else centres
        half = self.half if half is None else half
        out = np.zeros(len(centres))
        for e in self.scene.emitters(t, poses):
            if e.power == 0.0:
                continue
            lo, hi = centres - half - e.position, centres + half - e.position  # jammer -> cube
            _, r_max, s_lo, s_hi = link_ranges(lo, hi)
            g_j = gain_bounds(e.pattern, *axis_cos_range(lo, hi, e.axis))[0]
            g_r = self.relay_gains(relay, -s_hi, -s_lo)[0]  # the relay toward the jammer
            out = out + e.power * g_j * g_r * self._path_least(r_max)
        return out

    def _term(self, gamma):
        """``1 / log2(1 + Gamma)``, inf for a dead hop (Gamma = 0), 0 for an unbounded one."""
        se = spectral_efficiency(gamma)
        with np.errstate(divide="ignore"):
            return np.reciprocal(se, out=se) if isinstance(se, np.ndarray) else 1.0 / se

    def _excluded(self, poses, centres, half) -> np.ndarray:
        """``(n,)``: inf at the cubes no relay may be anywhere in (wholly inside one obstacle's margin, or
        wholly closer than the separation to a source or the base station), else 0."""
        out = np.zeros(len(centres))
        half = np.asarray(half, float)  # a scalar, or (n, 1): each cube's own
        corners = centres[:, None, :] + half[..., None] * CUBE_CORNERS
        for o in self.pb.obstacles:  # convex: a cube whose corners are all inside is inside
            out[np.all(o.signed_distance(corners) < 0, axis=1)] = np.inf
        sep = self.pb.separation_m
        if sep > 0:
            for pose in poses.values():
                _, r_max = distance_range(centres - half - pose.position, centres + half - pose.position)
                out[r_max < sep] = np.inf
        return out

    def unary_terms(self, t: float, poses, interference, centres=None, half=None, only: str | None = None) -> dict[str, np.ndarray]:
        """Each relay's terms ``(n,)`` from its hops with fixed nodes, bounded from below over each cube (its
        axis relaxed: its best over the cone toward each node); inf at the cubes it may not be in. ``only``:
        that relay's alone."""
        centres = self.cells if centres is None else centres
        half = self.half if half is None else half
        b = self.scene.budget
        excluded = self._excluded(poses, centres, half)
        out = {r: excluded.copy() for r in self.relays if only is None or r == only}
        for r, other, is_tx, count in self.unary:
            if r not in out:
                continue
            o = poses[other]
            pat_o = self.scene.node(other).antenna.pattern
            lo, hi = centres - half - o.position, centres + half - o.position  # the node -> the cube
            r_min, _, s_lo, s_hi = link_ranges(lo, hi)
            g = gain_bounds(pat_o, *axis_cos_range(lo, hi, o.axis))[1] * self.relay_gains(r, -s_hi, -s_lo)[1]
            if is_tx:  # relay -> fixed node: the node's own interference
                i_rx = self.scene.interference(self.scene.emitters(t, poses), o, pat_o) if self.scene.jammers else 0.0
            else:
                i_rx = interference[r]
            with np.errstate(divide="ignore", invalid="ignore"):
                gamma = np.nan_to_num(g * self._path_most(r_min) * b.tx_power / (np.asarray(i_rx, float) + b.noise_power),
                                      nan=np.inf)
            out[r] = out[r] + count * self._term(gamma)
        return out

    def signal_bound(self, tx: str, rx: str, d_centre: np.ndarray, spread: float) -> np.ndarray:
        """The largest received power (W) of the hop ``tx -> rx`` with its displacement anywhere in the cubes
        ``d_centre +- spread`` (m; two cells' half-sides summed): each end's best holdable gain over the
        directions, the path gain at the least length (at least the separation); 0 where the two relays
        would be closer than the separation everywhere."""
        lo, hi = d_centre - spread, d_centre + spread
        r_min, r_max, s_lo, s_hi = link_ranges(lo, hi)
        g = self.relay_gains(tx, s_lo, s_hi)[1] * self.relay_gains(rx, -s_hi, -s_lo)[1]
        with np.errstate(invalid="ignore"):
            s = np.nan_to_num(g * self._path_most(r_min) * self.scene.budget.tx_power, nan=np.inf)
        if self.pb.separation_m > 0:
            s = np.where(r_max < self.pb.separation_m, 0.0, s)
        return s

    def pair_terms(self, tx: str, rx: str, rows: slice, interference, rows_are_tx: bool = True,
                   at_centres: bool = False) -> np.ndarray:
        """``(rows, M)``: the hop ``tx -> rx``'s term bounded over the grid's cells (``at_centres``: at their
        centres), ``rows`` for ``tx`` (``rows_are_tx``) or for ``rx``, every cell for the other end (the signal
        read from the offset table)."""
        i_rx = interference[rx][None, :] if rows_are_tx else interference[rx][rows][:, None]
        table = self.signal_at_centres if at_centres else self.signal
        s = table[tx, rx][self.offsets.between(rows, rows_are_tx)]
        with np.errstate(divide="ignore", invalid="ignore"):
            return self._term(s / (i_rx + self.scene.budget.noise_power))

    # -- min-sum on the forest, branch and bound ------------------------------------------------
    def _grid_block(self, interference, at_centres: bool = False):
        def block(a: str, b: str, rows: slice) -> np.ndarray:
            out: np.ndarray | float = 0.0
            for tx, rx, count in self.edges[tuple(sorted((a, b)))]:
                out = out + count * self.pair_terms(tx, rx, rows, interference, rows_are_tx=tx == a, at_centres=at_centres)
            return np.asarray(out)
        return block

    def centres_optimum(self, t: float, poses) -> np.ndarray:
        """Each relay's cell ``(K,)`` of the relaxed min-sum at the cubes' centres (not a bound: the terms at the
        grid's points), where the refinement starts."""
        interference = {r: self.least_interference(t, r, poses, self.cells, 0.0) for r in self.relays}
        unary = self.unary_terms(t, poses, interference, self.cells, 0.0)
        _, marginals = forest_min_marginals(self.relays, unary, self.neighbours, self._grid_block(interference, True))
        return np.array([int(np.argmin(marginals[r])) for r in self.relays], dtype=int)

    def _sets_block(self, sets: CellSets, interference):
        def block(a: str, b: str, rows: slice) -> np.ndarray:
            out: np.ndarray | float = 0.0
            for tx, rx, count in self.edges[tuple(sorted((a, b)))]:
                ca, cb = sets.centres[a][rows], sets.centres[b]
                d = cb[None, :, :] - ca[:, None, :]  # a -> b
                d = d if tx == a else -d  # tx -> rx
                spread = sets.halves[a][rows][:, None, None] + sets.halves[b][None, :, None]  # the two cubes' half-sides
                s = self.signal_bound(tx, rx, d, spread)
                i_rx = interference[rx][None, :] if rx == b else interference[rx][rows][:, None]
                with np.errstate(divide="ignore", invalid="ignore"):
                    out = out + count * self._term(s / (i_rx + self.scene.budget.noise_power))
            return np.asarray(out)
        return block

    def solve_level(self, t: float, poses, sets: CellSets | None, excluded: Mapping[str, np.ndarray] | None = None
                    ) -> tuple[float, dict[str, np.ndarray]]:
        """The certified min-sum over the cells of ``sets`` (None: the whole grid; there ``excluded``, ``{relay:
        (M,)}``, inf at the cells a relay may not be in and 0 elsewhere, is added to its terms) and each relay's
        min-marginals."""
        if sets is None:
            interference = {r: self.least_interference(t, r, poses) for r in self.relays}
            unary = self.unary_terms(t, poses, interference)
            if excluded is not None:
                unary = {r: u + excluded[r] for r, u in unary.items()}
            block = self._grid_block(interference)
        else:
            half = {r: sets.halves[r][:, None] for r in self.relays}
            interference = {r: self.least_interference(t, r, poses, sets.centres[r], half[r]) for r in self.relays}
            unary = {r: self.unary_terms(t, poses, interference, sets.centres[r], half[r], only=r)[r] for r in self.relays}
            block = self._sets_block(sets, interference)
        total, marginals = forest_min_marginals(self.relays, unary, self.neighbours, block)
        if not self.fixed_hops:
            return total, marginals
        fixed = self.fixed_term(t, poses)
        return total + fixed, {r: m + fixed for r, m in marginals.items()}

    def fixed_term(self, t: float, poses) -> float:
        """The terms of the hops between nodes the bound does not place (``fixed_hops``), exact at ``t``: a
        configuration-free part of every configuration's sum."""
        b, out = self.scene.budget, 0.0
        for (tx, rx), count in self.fixed_hops.items():
            a, c = poses[tx], poses[rx]
            pat_rx = self.scene.node(rx).antenna.pattern
            g = link_gain(a.position, a.axis, self.scene.node(tx).antenna.pattern, c.position, c.axis, pat_rx,
                          self.scene.path_gain)
            i_rx = self.scene.interference(self.scene.emitters(t, poses), c, pat_rx) if self.scene.jammers else 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                gamma = np.nan_to_num(np.asarray(g * b.tx_power / (i_rx + b.noise_power), float), nan=np.inf)
            out += count * float(self._term(gamma))
        return out

    def solve(self, t: float) -> tuple[float, np.ndarray]:
        """The certified smallest sum of hop terms on the grid's cells and each relay's best cell index ``(K,)``."""
        total, marginals = self.solve_level(t, self.fixed_poses(t), None)
        return total, np.array([int(np.argmin(marginals[r])) for r in self.relays], dtype=int)

    def _split_threshold(self, marginals: Mapping[str, np.ndarray], kept: Mapping[str, np.ndarray]) -> float | None:
        """The largest min-marginal up to which the kept cells can be split in eight with the next level's pair terms
        within ``max_pairs`` and every relay's cells within ``BRANCH_CELLS`` (None: not even the best cells can)."""
        values = np.unique(np.concatenate([marginals[r][kept[r]] for r in self.relays]))
        kept_n = {r: int(kept[r].sum()) for r in self.relays}

        def fits(tau: float) -> bool:
            n = {r: kept_n[r] + 7 * int(np.count_nonzero(kept[r] & (marginals[r] <= tau))) for r in self.relays}
            work = sum(n[a] * n[b] for a, b in self.edges)
            return work <= self.max_pairs and max(n.values()) <= BRANCH_CELLS

        if not len(values) or not fits(values[0]):
            return None
        lo, hi = 0, len(values) - 1  # fits(values[lo]) holds; the largest index that fits (work grows with tau)
        while lo < hi:
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if fits(values[mid]) else (lo, mid - 1)
        return float(values[lo])

    def certify(self, t: float, total: float, marginals: dict[str, np.ndarray], feasible_sum: float
                ) -> tuple[float, dict, dict[str, np.ndarray]]:
        """Best-first branch and bound from the grid's certified ``total`` and min-marginals: cells whose min-marginal
        exceeds ``feasible_sum`` (the terms' sum of a configuration the physics allows, which the optimum's cannot
        exceed) are dropped; of the others those with the least min-marginals, as many as keep the next level's pair
        terms within ``max_pairs``, are split in eight, and every relay's cells (of several sizes) are bounded again,
        until the bound is within ``tolerance`` of ``feasible_sum`` or after ``max_levels`` levels. Returns the
        certified sum (a lower bound of every configuration's), what the search did, and each relay's min-marginals
        on the grid's cubes tightened by the search ``{relay: (M,)}``: a grid cube's is at least ``min(feasible_sum,
        its kept sub-cubes' least)`` (a configuration with another relay in a dropped cube sums above
        ``feasible_sum``), and at least its grid value."""
        poses, M = self.fixed_poses(t), len(self.cells)
        sets = CellSets({r: self.cells for r in self.relays}, {r: np.full(M, self.half) for r in self.relays},
                        {r: np.arange(M) for r in self.relays})
        tight = {r: np.array(marginals[r], float) for r in self.relays}
        cap, levels = feasible_sum * (1 + 1e-12), 0
        while feasible_sum / total - 1.0 > self.tolerance and levels < self.max_levels:
            kept = {r: marginals[r] <= cap for r in self.relays}
            tau = self._split_threshold(marginals, kept)
            if tau is None:
                break
            sets = sets.split(kept, {r: kept[r] & (marginals[r] <= tau) for r in self.relays})
            level_total, marginals = self.solve_level(t, poses, sets)
            total, levels = max(total, level_total), levels + 1  # every level's sum is a lower bound
            for r in self.relays:
                per_root = np.full(M, feasible_sum)
                np.minimum.at(per_root, sets.roots[r], np.minimum(marginals[r], feasible_sum))
                tight[r] = np.maximum(tight[r], per_root)
        cells = {r: int(len(sets.centres[r])) for r in self.relays}
        return total, {"levels": levels, "cells": cells, "half_min_m": float(min((h.min() for h in sets.halves.values()), default=self.half))}, tight

    # -- refinement (planning.fleet_configuration) ---------------------------------------------
    def rate(self, t: float, positions: np.ndarray, axes: np.ndarray, poses) -> float:
        """The true network rate with the relays at ``positions`` ``(K, 3)`` with antenna ``axes`` ``(K, 3)``."""
        return self.configurations.rate(t, positions, axes, poses)

    def best_axes(self, t: float, P: np.ndarray, poses, thrust: np.ndarray | None = None) -> np.ndarray:
        """Each relay's best holdable cone axis ``(K, 3)`` for the relays at ``P`` (``FleetConfigurations.best_axes``)."""
        return self.configurations.best_axes(t, P, poses, thrust)

    def reach(self, t: float) -> float:
        """How far (m) a relay at rest at its start at ``t = 0`` can be by ``t`` (s) within the speed and acceleration
        limits (``reach_from_rest``)."""
        res = self.pb.resolution
        return float(reach_from_rest(np.array([t]), res.max_speed_m_s, res.max_accel_m_s2)[0])

    def out_of_reach(self, t: float) -> dict[str, np.ndarray]:
        """``{relay: (M,)}``: inf at the grid's cubes no point of which a relay at rest at its start at ``t = 0``
        can reach by ``t`` (s) (``reach``), 0 elsewhere."""
        reach = self.reach(t)
        out = {}
        for r in self.relays:
            gap = np.linalg.norm(np.maximum(np.abs(self.cells - np.asarray(self.pb.starts[r], float)) - self.half, 0.0), axis=1)
            out[r] = np.where(gap > reach + 1e-9, np.inf, 0.0)
        return out

    def upper_path(self, times: np.ndarray, marginals: Sequence[Sequence[Mapping[str, np.ndarray]]],
                   static: Sequence[np.ndarray], reach_cap: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, str]:
        """The upper path bound: no fleet flying from the starts at most ``max_speed_m_s`` (and speeding up at most
        ``max_accel_m_s2`` from rest) has a higher mean rate over ``times``.

        Proof: ``marginals[i][k]``, relay ``k``'s min-marginal of the certified cube terms with every relay kept to
        the cubes it can reach by ``times[i]`` (``out_of_reach``; tightened by branch and bound, each cube's at most
        the least over its sub-cubes, ``_reachable_tightened``), is at most the sum of hop terms of every
        configuration a flyable fleet can be in at that instant with ``k`` in cube ``c``; so the fleet's rate there
        is at most ``u_k,t(c) = min(B / m_k,t(c), static_t)``, for every ``k``. Along a flyable path ``k``'s cube
        moves between samples to one within ``max_speed * dt`` (``cube_footprint``); the best such cube path of
        ``u_k`` from ``k``'s start (dynamic programming, ``bound._dp``) bounds every flyable fleet's mean rate, and
        so does the least of them over the relays. Returns that relay's per-sample values ``(T,)``, its cube
        centres ``(T, 3)`` (m) and its name.

        ``marginals`` and ``static`` are given per network the fleet may be (one; or, with routes that may end at
        several base stations, one per combination of ends, ``end_choices``): the fleet's rate is then the best
        combination's, at most ``max_e u_{e,k,t}(c)``, which the values take (the cubes are the same grid).

        ``reach_cap`` ``(T,)``: a certified bound on the rate of every configuration with each relay within its reach
        from rest of its start at that instant (SCIP's, ``_globally_tightened``); every value is capped by it there."""
        res, bw = self.pb.resolution, self.scene.budget.bandwidth
        if not self.relays:  # the direct link: nothing moves, the path bound is the static one (the best network's)
            values = np.max(np.array(static, float), axis=0)
            return (values if reach_cap is None else np.minimum(values, reach_cap)), np.full((len(times), 3), np.nan), "no relay"
        dt = float(times[1] - times[0]) if len(times) > 1 else res.dt_s
        footprint = cube_footprint(res.max_speed_m_s * dt, res.grid_m)
        best = None
        for r in self.relays:
            start = np.asarray(self.pb.starts[r], float)
            values = np.full((len(times), len(self.cells)), -np.inf)
            for m_e, s_e in zip(marginals, static, strict=True):
                for i in range(len(times)):
                    with np.errstate(divide="ignore"):
                        u = np.minimum(bw / m_e[i][r], s_e[i])
                    u[~np.isfinite(m_e[i][r])] = -np.inf  # out of reach (or where no relay may be)
                    values[i] = np.maximum(values[i], u)
            if reach_cap is not None:
                values = np.minimum(values, np.asarray(reach_cap, float)[:, None])
            cell0 = tuple(int(v) for v in np.clip(np.floor((start - self.lo) / res.grid_m), 0, np.array(self.shape) - 1))
            idx = _dp(values.reshape(len(times), *self.shape), cell0, footprint, "mean")
            flat = np.array([np.ravel_multi_index(ix, self.shape) for ix in idx])
            series = values[np.arange(len(times)), flat]
            if best is None or series.mean() < best[0].mean():
                best = (series, self.cells[flat], r)
        assert best is not None  # a network has a relay
        return best

    def flyable(self, times: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, str]:
        """The lower path bound, a flyable fleet path optimized jointly: first each relay from its start (at
        rest) chasing its refined place ``targets`` ``(T, K, 3)`` at most ``max_speed_m_s`` and changing its move
        by at most ``max_accel_m_s2`` per sample (``feasible_path.speed_limited``) with each relay's best
        holdable axis there, then every relay's positions and axes together on the network's true rate
        (``feasible_path.best_feasible_fleet_path``: the speed and acceleration limits, each axis within its
        tilt limit of the thrust its path needs, the separation after the start). Its true rate ``(T,)``,
        positions and axes ``(T, K, 3)``, the closest it brings a relay to another vehicle or the base station
        (m) and IPOPT's status."""
        res = self.pb.resolution
        poses = [self.fixed_poses(float(t)) for t in times]
        if not self.relays:  # the direct link: no path to fly, its rate at every sample
            none = np.zeros((len(times), 0, 3))
            return (np.array([self.rate(float(t), none[i], none[i], poses[i]) for i, t in enumerate(times)]), none, none,
                    np.inf, "no relay")
        fleet = flyable_fleet_path(self.configurations, times, targets, np.stack([self.pb.starts[r] for r in self.relays]), poses,
                                   speed_m_s=res.max_speed_m_s, accel_m_s2=res.max_accel_m_s2, gravity=self.pb.gravity)
        fixed = np.stack([np.array([p.position for p in pz.values()]) for pz in poses])
        P, A = fleet.position, fleet.axis
        rate = np.array([self.rate(float(t), P[i], A[i], poses[i]) for i, t in enumerate(times)])  # numpy, unregularized
        closest = np.inf
        for i in range(len(times)):
            gaps = [np.linalg.norm(fixed[i] - q, axis=1).min() for q in P[i]]
            gaps += [np.linalg.norm(P[i, a] - P[i, b]) for a in range(len(P[i])) for b in range(a + 1, len(P[i]))]
            closest = min(closest, float(min(gaps)))
        return rate, P, A, closest, fleet.status

    def refine(self, t: float, cells: np.ndarray | None = None, start: np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray]:
        """The relays at the grid's ``cells`` (or at the positions ``start`` ``(K, 3)``, m) refined on the true rate
        (``FleetConfigurations.refine``): the rate, positions ``(K, 3)`` and axes ``(K, 3)``."""
        first = self.cells[cells] if start is None else np.asarray(start, float)
        return self.configurations.refine(t, first, self.fixed_poses(t))


@dataclass
class _Instants:
    """The per-instant pieces of one network's bound (``compute_network_bound``)."""

    solver: NetworkBoundSolver
    times: np.ndarray
    static: np.ndarray
    static_positions: np.ndarray
    achieved: np.ndarray
    achieved_positions: np.ndarray
    achieved_axes: np.ndarray
    reachable: list  # per instant, (the min-sum, each relay's min-marginals) kept to what it can reach from its start
    searches: list


def _instants(pb: NetworkBoundProblem, progress=None) -> _Instants:
    solver = NetworkBoundSolver(pb)
    res, bw = pb.resolution, pb.scene.budget.bandwidth
    times = np.arange(0.0, pb.duration_s + 1e-9, res.dt_s)
    K = len(solver.relays)
    static, achieved = np.empty(len(times)), np.empty(len(times))
    sp, ap, ax = np.empty((len(times), K, 3)), np.empty((len(times), K, 3)), np.empty((len(times), K, 3))
    searches, level0 = [], []
    for k, t in enumerate(times):
        poses = solver.fixed_poses(float(t))
        total, marginals = solver.solve_level(float(t), poses, None)
        if set(pb.starts) >= set(solver.relays):  # every relay kept to what it can reach from its start (the path bound)
            level0.append(solver.solve_level(float(t), poses, None, solver.out_of_reach(float(t))))
        bounded = np.array([int(np.argmin(marginals[r])) for r in solver.relays], dtype=int)
        sp[k] = solver.cells[bounded]
        # refined from the relaxed optimum at the cubes' centres, from the bound's best cubes and from the last instant's
        # refined configuration (the best one moves with the sources): the best of them
        tries = [solver.refine(float(t), c) for c in (solver.centres_optimum(float(t), poses), bounded)]
        if k > 0 and np.all(np.isfinite(ap[k - 1])):
            tries.append(solver.refine(float(t), start=ap[k - 1]))
        achieved[k], ap[k], ax[k] = max(tries, key=lambda r: r[0])
        if np.isfinite(total) and total > 0 and achieved[k] > 0:
            total, search, _ = solver.certify(float(t), total, marginals, bw / achieved[k])
            searches.append(search)
        static[k] = bw / total if np.isfinite(total) and total > 0 else np.inf
        if progress is not None:
            progress(k + 1, len(times))
    return _Instants(solver, times, static, sp, achieved, ap, ax, level0, searches)


def _globally_tightened(part: _Instants, pb: NetworkBoundProblem, progress=None) -> dict:
    """``part``'s static bound at every instant lowered to SCIP's certified dual bound where that is tighter, and its
    achieved configuration replaced by SCIP's where that flies better (its true rate: ``NetworkBoundSolver.rate``);
    what SCIP did, per instant (``planning.network_bound_global``). Nothing where SCIP cannot express the scene."""
    why = expressible(pb.scene)
    if why is not None:
        if progress is not None:
            progress(len(part.times), len(part.times))
        return {"solver": "SCIP", "used": False, "why_not": why}
    solver = part.solver
    rows: list[dict] = []
    for k, t in enumerate(part.times):
        poses = solver.fixed_poses(float(t))
        r = solve_static(pb.scene, float(t), poses, solver.relays, solver.lo, solver.hi, pb.tilt_limits, pb.separation_m,
                         time_limit_s=pb.global_seconds, gap=pb.global_gap, node_limit=pb.global_nodes)
        rate = solver.rate(float(t), r.positions, r.axes, poses) if np.all(np.isfinite(r.positions)) else 0.0
        inside = all(o.signed_distance(q) >= 0 for o in pb.obstacles for q in r.positions) if rate > 0 else False
        cube = float(part.static[k])
        # every bound is at least a configuration the physics allows: SCIP below one failed numerically (a root LP
        # cut off as infeasible on a physical-unit geometry was seen: its dual bound then reads 1e20): not taken
        trusted = r.upper >= max(part.achieved[k], rate) * (1 - 1e-9)
        if trusted and r.upper < cube:
            part.static[k] = r.upper
        if inside and rate > part.achieved[k]:
            part.achieved[k], part.achieved_positions[k], part.achieved_axes[k] = rate, r.positions, r.axes
        row = {"t": float(t), "upper": r.upper, "cube_upper": cube, "rate": rate, "status": r.status, "gap": r.gap,
               "seconds": r.seconds, "nodes": r.nodes, "trusted": bool(trusted)}
        if set(pb.starts) >= set(solver.relays):  # the path bound's: every relay within its reach from rest of its start
            row |= _reach_limited(solver, pb, float(t), poses, r)
        rows.append(row)
        if progress is not None:
            progress(k + 1, len(part.times))
    return {"solver": "SCIP", "used": True, "time_limit_s": pb.global_seconds, "gap_limit": pb.global_gap,
            "tighter_instants": int(sum(r["trusted"] and r["upper"] < r["cube_upper"] for r in rows)),
            "untrusted_instants": int(sum(not r["trusted"] for r in rows)), "instants": rows}


def _reach_limited(solver: NetworkBoundSolver, pb: NetworkBoundProblem, t: float, poses, static: GlobalResult) -> dict:
    """SCIP's bound at ``t`` with every relay within its reach from rest of its start (``reach_from_rest``, as
    ``NetworkBoundSolver.reach``): the upper path bound's cap there (``upper_path``'s ``reach_cap``). Where
    every relay's reach covers the box it is the static problem's (``static``), solved once. SCIP's best configuration
    there (``reach_positions``) is within the reach: the flyable path's second start (``compute_network_bound``)."""
    reach = solver.reach(t)
    starts = {r: np.asarray(pb.starts[r], float) for r in solver.relays}
    far = max(float(np.linalg.norm(np.maximum(np.abs(solver.lo - q), np.abs(solver.hi - q)))) for q in starts.values())
    if reach >= far:
        return {"reach_m": reach, "reach_upper": static.upper, "reach_seconds": 0.0, "reach_positions": static.positions.tolist()}
    r = solve_static(pb.scene, t, poses, solver.relays, solver.lo, solver.hi, pb.tilt_limits, pb.separation_m,
                     time_limit_s=pb.global_seconds, gap=pb.global_gap, node_limit=pb.global_nodes,
                     within={k: (q, reach) for k, q in starts.items()})
    return {"reach_m": reach, "reach_upper": r.upper, "reach_seconds": r.seconds, "reach_status": r.status,
            "reach_positions": r.positions.tolist()}


def _reach_targets(rows: list[dict]) -> np.ndarray | None:
    """SCIP's best configuration within the relays' reach at every instant ``(T, K, 3)`` (the rows of
    ``_reach_limited``); None where an instant has none."""
    P = np.array([r["reach_positions"] for r in rows], float)
    return P if np.all(np.isfinite(P)) else None


def _reach_caps(rows: list[dict], flyable: np.ndarray) -> np.ndarray:
    """The per-instant caps of the upper path bound from SCIP's reach-limited bounds (the rows of ``_reach_limited``),
    each taken only where it is at least the flyable fleet's rate there (a configuration within the reach: below it
    SCIP failed numerically), inf elsewhere. Marks each row ``reach_trusted``."""
    caps = np.full(len(rows), np.inf)
    for i, (row, f) in enumerate(zip(rows, flyable, strict=True)):
        row["reach_trusted"] = bool(np.isfinite(f) and row["reach_upper"] >= f * (1 - 1e-9))
        if row["reach_trusted"]:
            caps[i] = row["reach_upper"]
    return caps


def _reachable_tightened(part: _Instants, feasible_sums: np.ndarray) -> tuple[list[dict[str, np.ndarray]], list[int]]:
    """Each instant's min-marginals kept to what the relays can reach, tightened by branch and bound
    (``NetworkBoundSolver.certify``) against ``feasible_sums`` ``(T,)``: the terms' sum of a flyable fleet's
    configuration at that instant (the lower path bound's), so a cube whose sub-cubes all sum above it is capped
    there (it cannot beat that fleet at that instant); and the levels each search went."""
    out, levels = [], []
    for (total, marginals), t, feasible in zip(part.reachable, part.times, feasible_sums, strict=True):
        if not (np.isfinite(total) and total > 0 and np.isfinite(feasible) and feasible > 0):
            out.append(marginals)
            continue
        _, search, tight = part.solver.certify(float(t), total, marginals, float(feasible))
        out.append(tight)
        levels.append(search["levels"])
    return out, levels


def end_choices(scene: RadioScene) -> list[RadioScene]:
    """Every network a scene whose routes may change in flight can be (``RadioScene.route_choice``: ends at several
    base stations, relays skipped): one plain scene per combination of its routes' candidates; the scene itself
    when every route is fixed."""
    if not scene.route_choice:
        return [scene]
    options = scene.candidate_routes
    plain = replace(scene, handover=(), skips=())
    return [plain.serving_routes(rs) for rs in product(*options)]


def compute_network_bound(pb: NetworkBoundProblem, progress=None) -> NetworkBound:
    """The static network bound and the refined configuration on the bound's time grid. Routes that may end
    at several base stations: each combination of ends bounded on its own, the network's at every instant
    the best of them (its rate is the best combination's: ``RadioScene.evaluate``), the upper path bound from
    every combination's terms at once (``NetworkBoundSolver.upper_path``), the flyable path the best
    combination's. A schedule other than time division (``RadioScene.schedule``): everything computed under time
    division, then the upper bounds times the most hops of a route (``schedule_factor``: a route under any schedule
    delivers at most its weakest hop's interference-free rate, ``min_k se_k <= H / sum_k 1/se_k``), the achieved and
    flyable rates time division's (what the schedule at least gives: it takes time division where that is more)."""
    if pb.scene.schedule != "tdma":
        b = compute_network_bound(replace(pb, scene=replace(pb.scene, schedule="tdma")), progress)
        factor = float(max(len(r) - 1 for r in pb.scene.all_routes))
        b.resolution = {**b.resolution, "schedule": pb.scene.schedule, "schedule_factor": factor,
                        "schedule_note": "static and path_mean: time division's bound times the most hops of a route "
                        "(any schedule's route rate is at most its weakest hop's alone); achieved and flyable: time "
                        "division's rates of those configurations (a lower estimate under the schedule)"}
        b.static, b.path_mean = b.static * factor, b.path_mean * factor
        return b
    scenes = end_choices(pb.scene)
    passes = 2 if pb.global_seconds > 0 else 1  # the cube bound's instants, then SCIP's
    parts = []
    for i, scene in enumerate(scenes):
        def step(k, n, i=i):
            if progress is not None:
                progress(i * passes * n + k, len(scenes) * passes * n)

        parts.append(_instants(replace(pb, scene=scene), step))
    glob = []
    if pb.global_seconds > 0:
        for i, (part, scene) in enumerate(zip(parts, scenes, strict=True)):
            def scip_step(k, n, i=i):
                if progress is not None:
                    progress((i * passes + 1) * n + k, len(scenes) * passes * n)

            glob.append(_globally_tightened(part, replace(pb, scene=scene), scip_step))
    first = parts[0]
    times, solver = first.times, first.solver
    best = np.argmax(np.stack([p.static for p in parts]), axis=0)
    done = np.argmax(np.stack([p.achieved for p in parts]), axis=0)
    rows = np.arange(len(times))
    static = np.stack([p.static for p in parts])[best, rows]
    sp = np.stack([p.static_positions for p in parts])[best, rows]
    achieved = np.stack([p.achieved for p in parts])[done, rows]
    ap = np.stack([p.achieved_positions for p in parts])[done, rows]
    ax = np.stack([p.achieved_axes for p in parts])[done, rows]
    res = pb.resolution
    searches = [s for p in parts for s in p.searches]
    excess = float(np.max(achieved / np.where(static > 0, static, np.inf) - 1.0, initial=0.0))
    gap = static / np.where(achieved > 0, achieved, np.nan) - 1.0  # how far above a configuration the physics allows
    method = "chain" if len(pb.scene.all_routes) == 1 else "tree"
    resolution = {"grid_m": res.grid_m, "dt_s": res.dt_s, "axis_step_deg": res.axis_step_deg, "cells": int(len(solver.cells)),
                  "times": int(len(times)), "method": f"certified min-sum dynamic programming on the relays' {method}, "
                  f"branch and bound to {solver.tolerance:.0%} of the refined configuration",
                  "tilt_limits_deg": {r: float(np.degrees(v)) for r, v in pb.tilt_limits.items()},
                  "separation_m": pb.separation_m, "grid_excess": max(excess, 0.0),
                  "certified_gap_max": float(np.nanmax(gap, initial=0.0)),
                  "certified_gap_mean": float(np.nanmean(gap)) if np.isfinite(gap).any() else None,
                  "branch_levels_max": max((s["levels"] for s in searches), default=0),
                  "branch_levels": pb.branch_levels, "branch_pairs": pb.branch_pairs}
    if glob:
        resolution["global"] = glob[0] if len(glob) == 1 else glob
        resolution["method"] = f"{resolution['method']}; per instant the tighter of it and SCIP's certified dual bound"
    if len(scenes) > 1:
        resolution["end_combinations"] = [[r[-1] for r in sc.all_routes] for sc in scenes]
        if pb.scene.skips:  # the relays carrying each route in each network bounded
            resolution["route_combinations"] = [[route_via(r) for r in sc.all_routes] for sc in scenes]
    K = len(solver.relays)
    fr, fp, fa = np.empty(0), np.empty((0, K, 3)), np.empty((0, K, 3))
    upper, up = np.empty(0), np.empty((0, 3))
    if set(pb.starts) >= set(solver.relays):
        flown = [p.solver.flyable(times, p.achieved_positions) for p in parts]
        scip = glob[0] if len(glob) == 1 and glob[0].get("used") else None  # SCIP's rows (one network: expressible)
        # the best configurations within the relays' reach: a second start for the flyable path (SCIP's model has no
        # obstacles: only without them)
        reached = _reach_targets(scip["instants"]) if scip is not None and not pb.obstacles else None
        if scip is not None and reached is not None:
            flown.append(solver.flyable(times, reached))
            scip["flyable_from_reach_mean"] = float(np.mean(flown[-1][0]))
        fr, fp, fa, closest, status = max(flown, key=lambda f: float(np.mean(f[0])))  # the best combination's
        with np.errstate(divide="ignore"):
            sums = pb.scene.budget.bandwidth / fr  # the flyable fleet's terms' sum at each instant
        tightened = [_reachable_tightened(p, sums) for p in parts]
        caps = _reach_caps(scip["instants"], fr) if scip is not None else None
        upper, up, binding = solver.upper_path(times, [m for m, _ in tightened], [p.static for p in parts], caps)
        if scip is not None:  # what the caps did: the cube terms' path bound alone, for the record
            cubes, _, _ = solver.upper_path(times, [m for m, _ in tightened], [p.static for p in parts])
            scip["reach_tighter_instants"] = int(np.sum(caps < cubes))
            scip["path_mean_without_reach"] = float(np.mean(cubes))
        levels = [lv for _, lvs in tightened for lv in lvs]
        resolution["path_branch_levels_max"] = max(levels, default=0)
        resolution |= {"flyable_max_speed_m_s": res.max_speed_m_s, "flyable_max_accel_m_s2": res.max_accel_m_s2,
                       "flyable_closest_m": closest, "flyable_status": status, "path_mean_relay": binding,
                       "path_mean_footprint": "cubes within max_speed * dt of each other, within the reach from rest of "
                       "the start"}
    return NetworkBound(times, static, sp, achieved, ap, ax, solver.relays, resolution, pb.outage_threshold,
                        flyable=fr, flyable_positions=fp, flyable_axes=fa, path_mean=upper, path_mean_position=up)


def spliced(parts: list[tuple[float, NetworkBound]]) -> NetworkBound:
    """One bound over a mission whose fleet shrinks: from each part's start time (s) on, that part's
    bound (a fleet without the relays lost by then); the first part's relays, a relay's positions NaN
    once it is gone; the path bounds (flyable and upper) until the first loss. Every part on the same time grid."""
    first = parts[0][1]
    out = NetworkBound(first.t.copy(), first.static.copy(), first.static_positions.copy(), first.achieved.copy(),
                       first.achieved_positions.copy(), first.achieved_axes.copy(), list(first.relays),
                       dict(first.resolution), first.outage_threshold, first.assumptions, first.flyable.copy(),
                       first.flyable_positions.copy(), first.flyable_axes.copy(), first.path_mean.copy(),
                       first.path_mean_position.copy())
    if len(parts) > 1:  # the full fleet's path bounds until the first loss (a path bound is of a whole mission)
        after = out.t >= parts[1][0] - 1e-9
        if len(out.flyable):
            out.flyable[after], out.flyable_positions[after], out.flyable_axes[after] = np.nan, np.nan, np.nan
        if len(out.path_mean):
            out.path_mean[after], out.path_mean_position[after] = np.nan, np.nan
    phases = []
    for t0, b in parts:
        if not np.allclose(b.t, first.t):
            raise ValueError("spliced network bound: the parts' time grids differ")
        rows = first.t >= t0 - 1e-9
        out.static[rows], out.achieved[rows] = b.static[rows], b.achieved[rows]
        for arr, src in ((out.static_positions, b.static_positions), (out.achieved_positions, b.achieved_positions),
                         (out.achieved_axes, b.achieved_axes)):
            arr[rows] = np.nan
            for k, name in enumerate(b.relays):
                arr[rows, out.relays.index(name)] = src[rows, k]
        phases.append({"from_s": float(t0), "relays": list(b.relays), "cells": b.resolution.get("cells"),
                       "grid_excess": b.resolution.get("grid_excess")})
    out.resolution["phases"] = phases
    return out
