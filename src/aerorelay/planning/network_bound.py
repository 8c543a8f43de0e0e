"""The best network the physics allows: a static upper bound on a fleet's rate, per instant.

The network rate ``R = B / sum_s sum_{k in route s} 1/log2(1 + Gamma_{s,k})`` (``models.radio.
network_rate``) is largest where the sum of the hops' terms is smallest. Over relay positions on
the position grid (``bound.grid_m`` in the workspace box) that sum is a min-sum problem whose
variables are the relays' cells: a hop between a fixed node (a source at its pose on its mission,
the base station) and a relay is a term of that relay's cell, a hop between two relays a term of
the pair. When the relays' hops form a forest (every chain, and routes that merge toward the base
station like two sources sharing a chain), dynamic programming solves it exactly, leaf by leaf:
``O(cells^2)`` per relay-relay hop.

A relay's antenna axis is shared by its hops, which would make the states (cell, axis) and the
pair terms ``(cells x axes)^2``; the bound relaxes it instead (an **upper bound**, stated in its
assumptions): every hop takes, at each of its relay ends, the best gain any holdable axis gives
toward the other end (tilt up to the platform's hover limit, yaw free: the link's cosine to the
axis anywhere in ``[sin(e - tilt), sin(e + tilt)]`` for a link at elevation ``e``), and each relay
receiver the smallest jammer interference any axis of the cone gives. With isotropic relays (or no
relay-relay hop) the relaxation is exact. The grid optimum is then refined (L-BFGS-B on the true
network rate, positions and axes jointly, from the grid's chain with each relay's best cone axis):
``achieved``, a configuration the physics allows at that instant, below the true optimum; the true
optimum lies between ``achieved`` and ``static`` up to the grid's resolution (the stated tolerance:
the largest gain of ``achieved`` over the grid's value seen, ``resolution.grid_excess``; where it
gains, ``static`` is raised to it).

One relay on one route is the single-relay bound (``planning.bound``): the composition root
dispatches it there (same grid, same numbers).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from ..models.antenna import AntennaPattern
from ..models.axes import axis_cone, tilted_axes
from ..models.geometry import rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.obstacles import inside_any
from ..models.radio import NodePose, RadioScene, spectral_efficiency
from .bound import BoundResolution, position_grid
from .feasible_path import speed_limited

NETWORK_BOUND_VERSION = "4"  # bump when the computation changes: cached network bounds are recomputed
CHUNK = 256  # rows of a pair-term block (cells x cells, float64): 256 measured 1.5x faster than 2048 (cache)

ASSUMPTIONS = ("small-scale fading ignored; every relay anywhere on the position grid of the workspace box at least the "
               "separation from the sources, the base station and its route neighbours (not from relays it shares no hop "
               "with); upper bound: "
               "each hop takes at each relay end the best gain any holdable axis gives toward the other end (tilt up to "
               "the hover limit, yaw free) and each relay receiver the least jammer interference over its axis cone, so a "
               "relay's hops need not agree on its axis (exact for isotropic relays); min-sum dynamic programming over "
               "the relays' cells (exact on the grid for a forest of relay-relay hops); achieved: the grid optimum "
               "refined on the true rate with one axis per relay")


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
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {"t": self.t, "static": self.static, "static_positions": self.static_positions, "achieved": self.achieved,
                "achieved_positions": self.achieved_positions, "achieved_axes": self.achieved_axes,
                "relays": np.array(self.relays), "flyable": self.flyable, "flyable_positions": self.flyable_positions,
                "flyable_axes": self.flyable_axes}

    def frame(self) -> pd.DataFrame:
        cols: dict[str, np.ndarray] = {"t": self.t, "static": self.static, "achieved": self.achieved}
        fly = len(self.flyable) == len(self.t)
        if fly:
            cols["flyable"] = self.flyable
        for k, name in enumerate(self.relays):
            for i, ax in enumerate("xyz"):
                cols[f"static.{name}.p_{ax}"] = self.static_positions[:, k, i]
                cols[f"achieved.{name}.p_{ax}"] = self.achieved_positions[:, k, i]
                cols[f"achieved.{name}.axis_{ax}"] = self.achieved_axes[:, k, i]
                if fly:
                    cols[f"flyable.{name}.p_{ax}"] = self.flyable_positions[:, k, i]
                    cols[f"flyable.{name}.axis_{ax}"] = self.flyable_axes[:, k, i]
        return pd.DataFrame(cols)


class BestGain:
    """A pattern's best gain toward a link at elevation ``e`` over every axis within ``max_tilt`` of
    vertical with free yaw: ``max g(c)`` for ``c`` in ``[sin(e - max_tilt), sin(e + max_tilt)]``
    (every cosine in between is reached by some such axis), tabulated over ``sin e`` and read as the
    larger of the two neighbouring entries (an upper reading)."""

    def __init__(self, pattern: AntennaPattern, max_tilt: float, n: int = 4001, samples: int = 401):
        s = np.linspace(-1.0, 1.0, n)
        e = np.arcsin(s)
        lo, hi = np.sin(np.clip(e - max_tilt, -np.pi / 2, np.pi / 2)), np.sin(np.clip(e + max_tilt, -np.pi / 2, np.pi / 2))
        c = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, samples)[None, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.nan_to_num(np.asarray(pattern.gain_from_cos(np.clip(c, -1.0, 1.0)), float), nan=0.0)
        table = np.broadcast_to(g, c.shape).max(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):  # a dipole's peak is broadside (c = 0): read it
            g0 = float(np.nan_to_num(np.asarray(pattern.gain_from_cos(0.0), float), nan=0.0))  # where the interval holds it
        table = np.where((lo <= 0.0) & (hi >= 0.0), np.maximum(table, g0), table)
        self.table = np.maximum(table, np.r_[table[1:], table[-1]])
        self.n = n

    def __call__(self, sin_e: np.ndarray) -> np.ndarray:
        i = np.clip(np.floor((np.asarray(sin_e) + 1.0) * 0.5 * (self.n - 1)).astype(np.int64), 0, self.n - 1)
        return self.table[i]


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


class NetworkBoundSolver:
    """The per-instant bound on a fixed grid (one instance per problem)."""

    def __init__(self, pb: NetworkBoundProblem):
        self.pb, self.scene = pb, pb.scene
        self.relays = [n.name for n in pb.scene.nodes if n.role == "relay"]
        self.unary, self.pairs = relay_forest(pb.scene.all_routes, self.relays)
        aimed = [j.name for j in pb.scene.jammers if j.point_at in self.relays]
        if aimed:
            raise ValueError(f"network bound: jammer(s) {aimed} aim at a relay, whose place the bound searches; not supported")
        res = pb.resolution
        self.lo, self.hi = np.asarray(pb.workspace_min, float), np.asarray(pb.workspace_max, float)
        grid, self.cells = position_grid(self.lo, self.hi, res.grid_m)
        self.blocked = inside_any(pb.obstacles, self.cells)  # cells inside an obstacle's margin: no relay there
        self.best = {r: BestGain(pb.scene.node(r).antenna.pattern, pb.tilt_limits[r]) for r in self.relays}
        self.cones = {r: axis_cone(pb.tilt_limits[r], np.radians(res.axis_step_deg)) for r in self.relays}
        self.offsets = OffsetTable([len(g) for g in grid], res.grid_m) if pb.scene.path_gain.distance_only else None
        zero = np.zeros(3)
        self.signal = {} if self.offsets is None else {(tx, rx): self._signal(tx, rx, zero, self.offsets.vectors)
                                                       for tx, rx in self.pairs}

    # -- channel pieces -------------------------------------------------------------------
    def fixed_poses(self, t: float) -> dict[str, NodePose]:
        """Every source at its pose on its mission at ``t``, the fixed nodes as placed."""
        poses = {n.name: self.scene.fixed_pose(n.name) for n in self.scene.nodes if n.position is not None}
        for name, path in self.pb.sources.items():
            s = path.state(t)
            poses[name] = self.scene.pose(name, s.p, rotation_zyx(s.attitude(self.pb.gravity)))
        return poses

    def _path(self, p_tx, p_rx):
        d = p_rx - p_tx
        d2 = np.einsum("...i,...i->...", d, d)
        pg = self.scene.path_gain
        with np.errstate(divide="ignore"):  # two relays in one cell: no link between them (term inf)
            return d, d2, (1.0 / d2 if pg.is_paper else pg.gain_between(p_tx, p_rx, d2))

    def least_interference(self, t: float, relay: str, poses: Mapping[str, NodePose]) -> np.ndarray:
        """``(M,)`` W: each cell's jammer interference at ``relay``'s receiver, least over its axis cone."""
        if not self.scene.jammers:
            return np.zeros(len(self.cells))
        P, B = self.cells[:, None, :], self.cones[relay][None, :, :]
        emitters = self.scene.emitters(t, {**poses, relay: NodePose(P, B)})
        with np.errstate(divide="ignore", invalid="ignore"):
            i = self.scene.interference(emitters, NodePose(P, B), self.scene.node(relay).antenna.pattern)
        i = np.nan_to_num(np.broadcast_to(np.asarray(i, float), (len(self.cells), B.shape[1])), nan=np.inf)
        return i.min(axis=1)

    def _term(self, gamma):
        """``1 / log2(1 + Gamma)``, inf for a dead hop (Gamma = 0)."""
        se = spectral_efficiency(gamma)
        with np.errstate(divide="ignore"):
            return np.reciprocal(se, out=se) if isinstance(se, np.ndarray) else 1.0 / se

    def _too_close(self, poses) -> np.ndarray:
        """``(M,)``: inf at the cells inside an obstacle's margin or closer than the separation to a source or the
        base station, else 0."""
        sep = self.pb.separation_m
        out = np.where(self.blocked, np.inf, 0.0)
        if sep > 0:
            for pose in poses.values():
                out[np.linalg.norm(self.cells - pose.position, axis=1) < sep] = np.inf
        return out

    def unary_terms(self, t: float, poses, interference) -> dict[str, np.ndarray]:
        """Each relay's terms ``(M,)`` from its hops with fixed nodes (relaxed relay axis); inf where it
        would be closer than the separation to one of them."""
        b = self.scene.budget
        out = {r: self._too_close(poses) for r in self.relays}
        for r, other, is_tx, count in self.unary:
            o = poses[other]
            pat_o = self.scene.node(other).antenna.pattern
            p_tx, p_rx = (self.cells, o.position) if is_tx else (o.position, self.cells)
            d, d2, path = self._path(p_tx, p_rx)
            n = np.sqrt(d2)
            with np.errstate(divide="ignore", invalid="ignore"):
                if is_tx:  # relay -> fixed node: the relay's best gain toward it, the node's own axis
                    g = self.best[r](d[:, 2] / n) * pat_o.gain_from_cos(-(d @ o.axis) / n)
                    i_rx = self.scene.interference(self.scene.emitters(t, poses), o, pat_o) if self.scene.jammers else 0.0
                else:  # fixed node -> relay
                    g = pat_o.gain_from_cos((d @ o.axis) / n) * self.best[r](-d[:, 2] / n)
                    i_rx = interference[r]
                gamma = np.nan_to_num(g * path * b.tx_power / (np.asarray(i_rx, float) + b.noise_power), nan=0.0)
            out[r] = out[r] + count * self._term(gamma)
        return out

    def _signal(self, tx: str, rx: str, p_tx: np.ndarray, p_rx: np.ndarray) -> np.ndarray:
        """The relaxed received power of the hop ``tx -> rx`` between ``p_tx`` and ``p_rx`` (m, world,
        broadcast), W: ``P_U g_tx g_rx h``, each end's best holdable gain toward the other; 0 for a link
        shorter than the separation (not a place the pair may take) or of zero length (one cell)."""
        d, d2, path = self._path(p_tx, p_rx)
        with np.errstate(divide="ignore", invalid="ignore"):
            sin_e = d[..., 2] / np.sqrt(d2)
            s = np.nan_to_num(self.best[tx](sin_e) * self.best[rx](-sin_e) * path * self.scene.budget.tx_power, nan=0.0,
                              posinf=0.0)
        if self.pb.separation_m > 0:
            s = np.where(d2 < self.pb.separation_m**2, 0.0, s)
        return s

    def pair_terms(self, tx: str, rx: str, rows: slice, interference, rows_are_tx: bool = True) -> np.ndarray:
        """``(rows, M)``: the relaxed term of the hop ``tx -> rx`` with the cells of ``rows`` for ``tx``
        (``rows_are_tx``) or for ``rx``, and every cell for the other end. A path gain of the length
        alone reads each link's signal from the grid's offset table (computed once), else per link."""
        b = self.scene.budget
        i_rx = interference[rx][None, :] if rows_are_tx else interference[rx][rows][:, None]
        if self.offsets is not None:
            s = self.signal[tx, rx][self.offsets.between(rows, rows_are_tx)]
        else:
            here, there = self.cells[rows][:, None, :], self.cells[None, :, :]
            s = self._signal(tx, rx, *((here, there) if rows_are_tx else (there, here)))
        with np.errstate(divide="ignore", invalid="ignore"):
            gamma = s / (i_rx + b.noise_power)
        return self._term(gamma)

    # -- min-sum on the forest ----------------------------------------------------------------
    def solve(self, t: float) -> tuple[float, np.ndarray]:
        """The smallest sum of hop terms on the grid and each relay's cell index (``(K,)``)."""
        poses = self.fixed_poses(t)
        interference = {r: self.least_interference(t, r, poses) for r in self.relays}
        local = self.unary_terms(t, poses, interference)
        edges: dict[tuple, list[tuple[str, str, int]]] = {tuple(sorted(p)): [] for p in self.pairs}
        for (tx, rx), count in self.pairs.items():
            edges[tuple(sorted((tx, rx)))].append((tx, rx, count))
        neighbours: dict[str, set] = {r: set() for r in self.relays}
        for a, b in edges:
            neighbours[a].add(b)
            neighbours[b].add(a)
        argbest: dict[str, tuple[str, np.ndarray]] = {}  # eliminated relay -> (its neighbour, its best cell per neighbour cell)
        alive = set(self.relays)
        order = []
        while len(alive) > 0:
            leaf = next((r for r in self.relays if r in alive and len(neighbours[r] & alive) <= 1), None)
            assert leaf is not None  # a forest always has a leaf
            alive.discard(leaf)
            order.append(leaf)
            rest = neighbours[leaf] & alive
            if not rest:
                continue
            other = rest.pop()
            M = len(self.cells)
            best_val, best_idx = np.full(M, np.inf), np.zeros(M, dtype=np.int64)
            for start in range(0, M, CHUNK):  # rows: the leaf's cells; columns: the neighbour's
                rows = slice(start, min(start + CHUNK, M))
                block = local[leaf][rows][:, None] + self._pair_block(leaf, other, rows, interference, edges)
                i = np.argmin(block, axis=0)
                v = block[i, np.arange(M)]
                better = v < best_val
                best_val[better], best_idx[better] = v[better], i[better] + start
            local[other] = local[other] + best_val
            argbest[leaf] = (other, best_idx)
        cells: dict[str, int] = {}
        total = 0.0
        for r in reversed(order):
            if r not in argbest:
                cells[r] = int(np.argmin(local[r]))
                total += float(local[r][cells[r]])
            else:
                other, idx = argbest[r]
                cells[r] = int(idx[cells[other]])
        return total, np.array([cells[r] for r in self.relays])

    def _pair_block(self, leaf: str, other: str, rows: slice, interference, edges) -> np.ndarray:
        """Every hop between ``leaf`` (its cells ``rows``) and ``other`` (every cell), summed with their counts."""
        out = 0.0
        for tx, rx, count in edges[tuple(sorted((leaf, other)))]:
            out = out + count * self.pair_terms(tx, rx, rows, interference, rows_are_tx=tx == leaf)
        return np.asarray(out)

    # -- refinement ---------------------------------------------------------------------------
    def rate(self, t: float, positions: np.ndarray, axes: np.ndarray, poses) -> float:
        """The true network rate with the relays at ``positions`` ``(K, 3)`` with antenna ``axes`` ``(K, 3)``."""
        relay_poses = {r: NodePose(positions[k], axes[k]) for k, r in enumerate(self.relays)}
        with np.errstate(divide="ignore", invalid="ignore"):
            return float(np.nan_to_num(self.scene.evaluate(t, {**poses, **relay_poses}).capacity, nan=0.0))

    def best_axes(self, t: float, P: np.ndarray, poses) -> np.ndarray:
        """Each relay's best axis of its cone for the relays at ``P`` ``(K, 3)`` on the true rate, one
        relay at a time, twice round (``(K, 3)``, unit, world)."""
        A = np.tile([0.0, 0.0, 1.0], (len(self.relays), 1))
        for _ in range(2):
            for k, r in enumerate(self.relays):
                scores = []
                for a in self.cones[r]:
                    A[k] = a
                    scores.append(self.rate(t, P, A, poses))
                A[k] = self.cones[r][int(np.argmax(scores))]
        return A

    def flyable(self, times: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """The flyable fleet path: each relay from its start (at rest) chasing its refined place
        ``targets`` ``(T, K, 3)`` at most ``max_speed_m_s`` and changing its move by at most
        ``max_accel_m_s2`` per sample (``feasible_path.speed_limited``), with each relay's best cone axis
        at each sample (holdable in hover). Its true rate ``(T,)``, positions and axes ``(T, K, 3)``, and
        the closest it brings a relay to another vehicle or the base station (m)."""
        res = self.pb.resolution
        dt = float(times[1] - times[0]) if len(times) > 1 else res.dt_s
        dv = None if res.max_accel_m_s2 is None else res.max_accel_m_s2 * dt**2
        P = np.stack([speed_limited(targets[:, k], self.pb.starts[r], res.max_speed_m_s * dt, dv)
                      for k, r in enumerate(self.relays)], axis=1)
        rate, A, closest = np.empty(len(times)), np.empty_like(P), np.inf
        for i, t in enumerate(times):
            poses = self.fixed_poses(float(t))
            A[i] = self.best_axes(float(t), P[i], poses)
            rate[i] = self.rate(float(t), P[i], A[i], poses)
            others = np.array([p.position for p in poses.values()])
            gaps = [np.linalg.norm(others - q, axis=1).min() for q in P[i]]
            gaps += [np.linalg.norm(P[i, a] - P[i, b]) for a in range(len(P[i])) for b in range(a + 1, len(P[i]))]
            closest = min(closest, float(min(gaps)))
        return rate, P, A, closest

    def refine(self, t: float, cells: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """The grid chain refined on the true rate: each relay's best cone axis there (one at a time),
        then L-BFGS-B over every position and (tilt, azimuth) jointly inside the box and tilt limits."""
        poses = self.fixed_poses(t)
        P = self.cells[cells].copy()
        A = self.best_axes(t, P, poses)
        limits = [self.pb.tilt_limits[r] for r in self.relays]
        tilt0 = np.arccos(np.clip(A[:, 2], -1, 1))
        az0 = np.arctan2(A[:, 1], A[:, 0])
        x0 = np.concatenate([P.ravel(), tilt0, az0])
        K = len(self.relays)

        def unpack(x):
            return x[: 3 * K].reshape(K, 3), tilted_axes(x[3 * K : 4 * K], x[4 * K :])

        def neg(x):
            return -self.rate(t, *unpack(x), poses)

        bounds = [(lo, hi) for _ in range(K) for lo, hi in zip(self.lo, self.hi, strict=True)]
        bounds += [(0.0, lim) for lim in limits] + [(None, None)] * K
        sep = self.pb.separation_m
        if sep <= 0:
            res = minimize(neg, x0, method="L-BFGS-B", bounds=bounds, options={"maxiter": 80})
        else:  # every relay the separation from the fixed nodes and from every other relay (m^2 margins >= 0)
            fixed = np.array([p.position for p in poses.values()])

            def margins(x):
                P = x[: 3 * K].reshape(K, 3)
                out = [(np.sum((P[:, None, :] - fixed[None, :, :]) ** 2, axis=-1) - sep**2).ravel()]
                out += [[np.sum((P[i] - P[j]) ** 2) - sep**2 for i in range(K) for j in range(i + 1, K)]]
                return np.concatenate(out)
            res = minimize(neg, x0, method="SLSQP", bounds=bounds, constraints=[{"type": "ineq", "fun": margins}],
                           options={"maxiter": 80})
            if np.min(margins(res.x)) < -1e-6:
                res.fun = np.inf  # ended outside the separation: keep the start
        better = -res.fun >= -neg(x0) and not np.any(inside_any(self.pb.obstacles, unpack(res.x)[0]))
        x = res.x if better else x0
        return -neg(x), *unpack(x)


def compute_network_bound(pb: NetworkBoundProblem, progress=None) -> NetworkBound:
    """The static network bound and the refined configuration on the bound's time grid."""
    solver = NetworkBoundSolver(pb)
    res, bw = pb.resolution, pb.scene.budget.bandwidth
    times = np.arange(0.0, pb.duration_s + 1e-9, res.dt_s)
    K = len(solver.relays)
    static, achieved = np.empty(len(times)), np.empty(len(times))
    sp, ap, ax = np.empty((len(times), K, 3)), np.empty((len(times), K, 3)), np.empty((len(times), K, 3))
    for k, t in enumerate(times):
        total, cells = solver.solve(float(t))
        static[k] = bw / total if np.isfinite(total) and total > 0 else 0.0
        sp[k] = solver.cells[cells]
        achieved[k], ap[k], ax[k] = solver.refine(float(t), cells)
        if progress is not None:
            progress(k + 1, len(times))
    excess = float(np.max(achieved / np.where(static > 0, static, np.inf) - 1.0, initial=0.0))
    static = np.maximum(static, achieved)  # where the refined configuration beats the grid, the grid missed that much
    method = "chain" if len(pb.scene.all_routes) == 1 else "tree"
    resolution = {"grid_m": res.grid_m, "dt_s": res.dt_s, "axis_step_deg": res.axis_step_deg, "cells": int(len(solver.cells)),
                  "times": int(len(times)), "method": f"min-sum dynamic programming on the relays' {method}",
                  "tilt_limits_deg": {r: float(np.degrees(v)) for r, v in pb.tilt_limits.items()},
                  "separation_m": pb.separation_m, "grid_excess": max(excess, 0.0)}
    fr, fp, fa = np.empty(0), np.empty((0, K, 3)), np.empty((0, K, 3))
    if set(pb.starts) >= set(solver.relays):
        fr, fp, fa, closest = solver.flyable(times, ap)
        resolution |= {"flyable_max_speed_m_s": res.max_speed_m_s, "flyable_max_accel_m_s2": res.max_accel_m_s2,
                       "flyable_closest_m": closest}
    return NetworkBound(times, static, sp, achieved, ap, ax, solver.relays, resolution, pb.outage_threshold,
                        flyable=fr, flyable_positions=fp, flyable_axes=fa)


def spliced(parts: list[tuple[float, NetworkBound]]) -> NetworkBound:
    """One bound over a mission whose fleet shrinks: from each part's start time (s) on, that part's
    bound (a fleet without the relays lost by then); the first part's relays, a relay's positions NaN
    once it is gone; the flyable path until the first loss. Every part on the same time grid."""
    first = parts[0][1]
    out = NetworkBound(first.t.copy(), first.static.copy(), first.static_positions.copy(), first.achieved.copy(),
                       first.achieved_positions.copy(), first.achieved_axes.copy(), list(first.relays),
                       dict(first.resolution), first.outage_threshold, first.assumptions, first.flyable.copy(),
                       first.flyable_positions.copy(), first.flyable_axes.copy())
    if len(out.flyable) and len(parts) > 1:  # the full fleet's flyable path, until the first loss (not flown after)
        after = out.t >= parts[1][0] - 1e-9
        out.flyable[after], out.flyable_positions[after], out.flyable_axes[after] = np.nan, np.nan, np.nan
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
