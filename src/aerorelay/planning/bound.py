"""The best link the physics allows: capacity bounds of a scenario (no controller involved).

For the scenario's MRAV-2 path and attitude, every jammer's position, antenna and schedule and
the true channel of the radio scene (``models.radio``; fading ignored), on a time grid of
``bound.dt_s``:

- **static bound** ``C_static(t)``: the best end-to-end capacity over relay positions in the
  workspace box and relay antenna axes the platform can hold in hover (``Multirotor.
  hover_tilt_limit``, yaw free; vertical only for a coplanar platform). Grid search
  (``bound.grid_m``, axes every ``bound.axis_step_deg``) refined by a local continuous search
  from the best cell, so it sits at (or within a hair of) the true per-instant maximum.
- **path bounds**: the best relay path from the scenario's start at speed <= ``bound.
  max_speed_m_s``, by dynamic programming over the position grid: once maximizing the mean of
  C (``path_mean``), once its minimum (``path_maxmin``; among the paths keeping that minimum, the
  one with the best mean). Per step the path may move to any cell
  whose centre lies within ``max_speed * dt + grid / 2`` (the half cell absorbs the grid's
  quantization); the attitude at each instant is the best holdable one (attitude changes are
  taken as free). The grid allowance lets such a path fly faster than ``max_speed``, so beside
  each path bound a **flyable path** (``planning/feasible_path.py``): the grid path refined by
  IPOPT into one at exactly ``<= max_speed`` (Euclidean; accelerating at ``<= max_accel_m_s2``
  from rest) from the relay's own start, continuous
  positions and holdable axes: a path a relay could fly, so a lower estimate of the best one.
  The best path at ``max_speed`` lies between the flyable path and the path bound.

``compute_bound(problem)`` returns a ``CapacityBound`` for a ``BoundProblem`` (the parts the
composition root builds from a scenario); ``cached_bound`` keeps it on disk under a key of
everything it depends on.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import ndimage
from scipy.optimize import minimize

from ..models.axes import axis_cone, tilted_axes
from ..models.geometry import E3, thrust_direction_from_acceleration
from ..models.mission import SourceTrajectory
from ..models.obstacles import inside_any
from ..models.propagation import LargeScaleRealization
from ..models.radio import NodePose, RadioScene
from ..models.raytrace import RayTracer
from ..models.vehicle import Multirotor
from ..store.cache import cache_dir, cache_lock, entry_is_intact, publish_checked
from .feasible_path import best_feasible_path, leaning_capacity, speed_limited
from .traced_grid import TracedRelayGrid, jammers_at

log = logging.getLogger(__name__)
BOUND_VERSION = "11"  # bump when the computation changes: cached bounds are recomputed


@dataclass(frozen=True, kw_only=True)
class BoundResolution:
    """The bound's resolution (``[bound]``): position grid (m), time grid (s), antenna-axis spacing
    (deg), the paths' speed limit (m/s) and the flyable paths' acceleration limit (m/s^2; None: none)."""

    grid_m: float = 0.5
    dt_s: float = 0.5
    axis_step_deg: float = 5.0
    max_speed_m_s: float = 1.0
    max_accel_m_s2: float | None = 4.0


@dataclass(frozen=True)
class BoundProblem:
    """What a bound depends on: the radio scene, MRAV-2's path, the relay vehicle (its hover-tilt
    limit), the workspace box and relay start (m, world), the mission length (s), the resolution
    (``[bound]``: ``grid_m``, ``dt_s``, ``axis_step_deg``, ``max_speed_m_s``) and the outage threshold."""

    scene: RadioScene
    source: SourceTrajectory
    vehicle: Multirotor
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    relay_start: np.ndarray
    duration_s: float
    resolution: BoundResolution
    outage_threshold: float = 1e-3
    realization: LargeScaleRealization | None = None  # the run's shadowing field / LoS states (None: deterministic)
    obstacles: tuple = ()  # models.obstacles shapes grown by their margins: the relay is never inside one
    tracer: RayTracer | None = None  # the bound on the ray-traced channel at its cells
    traced_coherent: bool = False  # ... its paths summed with their phases (else in power)


@dataclass
class CapacityBound:
    """Bounds on a time grid (s); capacities normalized (B = 1 gives bit/s/Hz); positions m, world."""

    t: np.ndarray
    static: np.ndarray
    static_position: np.ndarray
    static_axis: np.ndarray
    path_mean: np.ndarray
    path_mean_position: np.ndarray
    path_maxmin: np.ndarray
    path_maxmin_position: np.ndarray
    flyable_mean: np.ndarray
    flyable_mean_position: np.ndarray
    flyable_maxmin: np.ndarray
    flyable_maxmin_position: np.ndarray
    resolution: dict = field(default_factory=dict)
    outage_threshold: float = 1e-3
    assumptions: str = ""

    def summary(self) -> dict:
        """``bound.json``: mean / min / outage of each bound and the resolution used."""
        def stats(c: np.ndarray) -> dict:
            return {"mean": float(c.mean()), "min": float(c.min()), "outage_fraction": float(np.mean(c < self.outage_threshold))}

        return {"static": stats(self.static), "path_mean": stats(self.path_mean), "path_maxmin": stats(self.path_maxmin),
                "flyable_mean": stats(self.flyable_mean), "flyable_maxmin": stats(self.flyable_maxmin),
                "resolution": self.resolution, "assumptions": self.assumptions}

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in ("t", "static", "static_position", "static_axis", "path_mean",
                                              "path_mean_position", "path_maxmin", "path_maxmin_position", "flyable_mean",
                                              "flyable_mean_position", "flyable_maxmin", "flyable_maxmin_position")}

    def frame(self) -> pd.DataFrame:
        """Time series as a DataFrame (one row per time of the bound's grid)."""
        cols: dict[str, np.ndarray] = {"t": self.t, "static": self.static, "path_mean": self.path_mean,
                                       "path_maxmin": self.path_maxmin, "flyable_mean": self.flyable_mean,
                                       "flyable_maxmin": self.flyable_maxmin}
        for name in ("static_position", "static_axis", "path_mean_position", "path_maxmin_position",
                     "flyable_mean_position", "flyable_maxmin_position"):
            for i, ax in enumerate("xyz"):
                cols[f"{name}_{ax}"] = getattr(self, name)[:, i]
        return pd.DataFrame(cols)


ASSUMPTIONS = ("small-scale fading ignored; the run's large-scale realization (shadowing field, LoS states) "
               "included where the channel has one; relay anywhere in the workspace box with any antenna axis the platform can hold in hover "
               "(yaw free); attitude changes free; path bounds on the position grid, one move per time step to a cell "
               "within max_speed * dt + grid / 2 (the grid allowance: resolution.max_path_speed_m_s is the fastest such "
               "move, so the path bounds stay upper bounds at max_speed)")


TRACED_ASSUMPTIONS = ("on the ray-traced channel at the grid's cells (the traced map: every cell traced from the source at "
                      "every instant and from the fixed ends once; static the best cell, not refined between cells); "
                      "relay at any cell of the workspace box with any antenna axis the platform can hold in hover "
                      "(yaw free); attitude changes free; path bounds one move per time step to a cell within "
                      "max_speed * dt + grid / 2; the flyable paths the grid paths pulled back to the speed and "
                      "acceleration limits (not refined)")


class CapacityLandscape:
    """The true end-to-end capacity over relay poses at time t (``jammer_known=False``: as planned
    before take-off, with every jammer silent)."""

    def __init__(self, scene: RadioScene, source: SourceTrajectory, gravity: float, jammer_known: bool = True,
                 realization: LargeScaleRealization | None = None, keep_out: tuple = (),
                 traced: TracedRelayGrid | None = None):
        """``keep_out``: obstacles (grown by their margins) where the relay may not be: capacity 0 there.
        ``traced``: the capacity on the ray-traced channel (``planning.traced_grid``) instead of eq. 5-9's
        analytic links (the jammers at their true positions and powers at t, or silent)."""
        self.scene, self.source, self.gravity = scene, source, gravity
        self.keep_out, self.traced = keep_out, traced
        self.silent = None if jammer_known else np.zeros(len(scene.jammers))
        self.source_name = scene.name_of("source")
        self.relay_name = scene.name_of("relay")
        self.realization = realization if realization is not None and realization.active else None

    def source_pose(self, t: float) -> NodePose:
        s = self.source.state(t)
        return NodePose(s.p, thrust_direction_from_acceleration(s.a, self.gravity))

    def capacity(self, t: float, positions, axes) -> np.ndarray:
        """``(M, K)`` for relay positions ``(M, 3)`` x antenna axes ``(K, 3)``."""
        source = self.source_pose(t)
        P = np.atleast_2d(np.asarray(positions, float))
        inside = inside_any(self.keep_out, P) if self.keep_out else np.zeros(len(P), bool)
        if self.traced is not None:  # the cells inside an obstacle are not traced (no receiver inside a building)
            pj, powers = jammers_at(self.scene, t, silent=self.silent is not None)  # silent: a planner does not know where
            C = np.zeros((len(P), len(np.atleast_2d(axes))))
            if not inside.all():
                C[~inside] = self.traced(P[~inside], axes, source, pj, powers)
            return C
        fading = None if self.realization is None else self._large_scale(t, P, source)
        C = self.scene.relay_grid(t, positions, axes, {self.source_name: source}, jammer_powers=self.silent, fading=fading)
        return np.where(inside[:, None], 0.0, C) if self.keep_out else C

    def _large_scale(self, t: float, relay: np.ndarray, source: NodePose) -> list:
        """Each link's realized power multiplier at these relay positions: ``(M, 1)`` or a scalar."""
        assert self.realization is not None

        def where(name: str, j: int | None):
            if j is not None:
                return self.scene.jammers[j].position_at(t)
            if name == self.relay_name:
                return relay
            return source.position if name == self.source_name else self.scene.fixed_pose(name).position

        out = []
        for k, (tx, rx, j) in enumerate(self.scene.link_ends()):
            g = np.asarray(self.realization.link(k, where(tx, j), where(rx, None)).gain, float)
            out.append(g[:, None] if g.ndim == 1 else g)
        return out


def _refine(scene: CapacityLandscape, t: float, p: np.ndarray, b: np.ndarray, lo, hi, max_tilt: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Local continuous maximization of C over (position, axis) from a grid optimum."""
    tilt0, az0 = float(np.arccos(np.clip(b[2], -1, 1))), float(np.arctan2(b[1], b[0]))
    x0 = np.r_[p, tilt0, az0] if max_tilt > 0 else np.asarray(p, float)

    def neg_c(x):
        axis = tilted_axes(x[3], x[4]) if max_tilt > 0 else E3
        return -float(scene.capacity(t, x[:3][None], axis[None])[0, 0])

    bounds = list(zip(lo, hi, strict=True)) + ([(0.0, max_tilt), (None, None)] if max_tilt > 0 else [])
    res = minimize(neg_c, x0, method="L-BFGS-B", bounds=bounds, options={"maxiter": 60})
    x = res.x if -res.fun >= -neg_c(x0) else x0
    axis = tilted_axes(x[3], x[4]) if max_tilt > 0 else E3
    return -neg_c(x), np.asarray(x[:3], float), axis


def _footprint(radius_cells: float) -> np.ndarray:
    r = int(np.floor(radius_cells))
    g = np.arange(-r, r + 1)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    return (X**2 + Y**2 + Z**2) <= radius_cells**2 + 1e-9


def fastest_step_m_s(footprint: np.ndarray, grid_m: float, dt_s: float) -> float:
    """The fastest Euclidean speed (m/s) one move of ``footprint`` allows: above ``max_speed`` by
    the grid allowance (a diagonal move at 1 m/s, 0.5 m grid, 0.5 s is 1.41 m/s), so the path
    bounds stay upper bounds for a relay at ``max_speed``."""
    offsets = np.argwhere(footprint) - np.array(footprint.shape) // 2
    return float(np.linalg.norm(offsets, axis=1).max() * grid_m / dt_s)


def _dp(values: np.ndarray, start: tuple[int, ...], footprint: np.ndarray, kind: str) -> list[tuple[int, ...]]:
    """Best path through ``values`` (T, nx, ny, nz) from ``start``: max sum (``mean``) or max min."""
    T = values.shape[0]
    V = np.empty_like(values)
    V[-1] = values[-1]
    for k in range(T - 2, -1, -1):
        reach = ndimage.maximum_filter(V[k + 1], footprint=footprint, mode="constant", cval=-np.inf)
        V[k] = values[k] + reach if kind == "mean" else np.minimum(values[k], reach)
    offsets = np.argwhere(footprint) - np.array(footprint.shape) // 2
    path = [start]
    for k in range(1, T):
        cand = np.array(path[-1]) + offsets
        ok = np.all((cand >= 0) & (cand < np.array(values.shape[1:])), axis=1)
        cand = cand[ok]
        best = cand[np.argmax(V[k][tuple(cand.T)])]
        path.append(tuple(int(i) for i in best))
    return path


def position_grid(lo, hi, step: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Grid axes and the ``(M, 3)`` cell centres of the box ``[lo, hi]`` every ``step`` m."""
    grid = [np.arange(lo[i], hi[i] + 1e-9, step) for i in range(3)]
    X, Y, Z = np.meshgrid(*grid, indexing="ij")
    return grid, np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])


def best_path(scene: CapacityLandscape, cells: np.ndarray, shape: tuple[int, ...], axes: np.ndarray, times: np.ndarray,
              start: tuple[int, ...], radius_cells: float) -> np.ndarray:
    """Positions ``(T, 3)`` of the max-mean path through the best-axis capacity landscape."""
    values = np.stack([scene.capacity(t, cells, axes).max(axis=1) for t in times]).reshape(len(times), *shape)
    idx = _dp(values, start, _footprint(radius_cells), "mean")
    return cells[[np.ravel_multi_index(ix, shape) for ix in idx]]


def compute_bound(pb: BoundProblem, progress=None) -> CapacityBound:
    """The static and path bounds of a problem (see the module docstring)."""
    b = pb.resolution
    traced = None if pb.tracer is None else TracedRelayGrid(pb.scene, pb.tracer, source=pb.scene.name_of("source"),
                                                            coherent=pb.traced_coherent)
    scene = CapacityLandscape(pb.scene, pb.source, pb.vehicle.gravity, realization=pb.realization, keep_out=pb.obstacles,
                              traced=traced)
    max_tilt = pb.vehicle.hover_tilt_limit
    axes = axis_cone(max_tilt, np.radians(b.axis_step_deg))
    lo, hi = np.asarray(pb.workspace_min, float), np.asarray(pb.workspace_max, float)
    grid, cells = position_grid(lo, hi, b.grid_m)
    shape = tuple(len(g) for g in grid)
    times = np.arange(0.0, pb.duration_s + 1e-9, b.dt_s)
    best = np.empty((len(times), cells.shape[0]))
    best_axis = np.empty((len(times), cells.shape[0]), dtype=np.int32)
    static, static_p, static_b = np.empty(len(times)), np.empty((len(times), 3)), np.empty((len(times), 3))
    for k, t in enumerate(times):
        C = scene.capacity(t, cells, axes)
        best_axis[k] = np.argmax(C, axis=1)
        best[k] = C[np.arange(C.shape[0]), best_axis[k]]
        i = int(np.argmax(best[k]))
        if traced is None:
            static[k], static_p[k], static_b[k] = _refine(scene, t, cells[i], axes[best_axis[k, i]], lo, hi, max_tilt)
        else:  # on the traced map's cells: a continuous search would trace at every step of it
            static[k], static_p[k], static_b[k] = best[k, i], cells[i], axes[best_axis[k, i]]
        if progress is not None:
            progress(k + 1, len(times))
    start = tuple(int(np.argmin(np.abs(grid[i] - pb.relay_start[i]))) for i in range(3))
    fp = _footprint((b.max_speed_m_s * b.dt_s + 0.5 * b.grid_m) / b.grid_m)
    values = best.reshape(len(times), *shape)
    paths = {}
    for kind in ("mean", "maxmin"):
        idx = _dp(values, start, fp, kind)
        if kind == "maxmin":  # among the paths that keep the best minimum, the one with the best mean
            floor = min(values[(k, *ix)] for k, ix in enumerate(idx))
            idx = _dp(np.where(values >= floor, values, -np.inf), start, fp, "mean")
        flat = np.array([np.ravel_multi_index(ix, shape) for ix in idx])
        paths[kind] = (best[np.arange(len(times)), flat], cells[flat])
    flyable: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    statuses: dict[str, str] = {}
    for kind in ("mean", "maxmin"):
        # the max-min path also from the flyable max-mean one (a second start: at 2 m/s the max-min
        # solve from its own grid path ended at a local minimum 13x below the grid's)
        starts = [paths[kind][1]] + ([flyable["mean"][1]] if kind == "maxmin" else [])
        runs = [_flyable(scene, times, guess, pb, max_tilt, kind) for guess in starts]
        score = [float(np.min(r[0][0])) if kind == "maxmin" else float(np.mean(r[0][0])) for r in runs]
        flyable[kind], statuses[kind] = runs[int(np.argmax(score))]
    resolution = {"grid_m": b.grid_m, "dt_s": b.dt_s, "axis_step_deg": b.axis_step_deg, "max_speed_m_s": b.max_speed_m_s,
                  "hover_tilt_limit_deg": float(np.degrees(max_tilt)), "axes": int(len(axes)), "cells": int(cells.shape[0]),
                  "times": int(len(times)), "path_step_radius_m": float(b.max_speed_m_s * b.dt_s + 0.5 * b.grid_m),
                  "max_path_speed_m_s": fastest_step_m_s(fp, b.grid_m, b.dt_s), "flyable_status": statuses,
                  "flyable_max_accel_m_s2": b.max_accel_m_s2}
    if pb.tracer is not None:
        resolution["traced_calls"] = int(pb.tracer.calls)
    return CapacityBound(times, static, static_p, static_b, paths["mean"][0], paths["mean"][1], paths["maxmin"][0],
                         paths["maxmin"][1], *flyable["mean"], *flyable["maxmin"], resolution, pb.outage_threshold,
                         f"{pb.scene.describe()}; {TRACED_ASSUMPTIONS if traced is not None else ASSUMPTIONS}")


def _flyable(scene: CapacityLandscape, times: np.ndarray, grid_path: np.ndarray, pb: BoundProblem, max_tilt: float,
             kind: str) -> tuple[tuple[np.ndarray, np.ndarray], str]:
    """The flyable path near a grid path: ``((capacity, position), status)``. With a large-scale
    realization (a shadowing field is not symbolic) or a traced channel the grid path pulled back to the speed and
    acceleration limits, its best axis per sample among those the platform can lean to there
    (``leaning_capacity``), unrefined: still flyable, a weaker lower estimate."""
    lo, hi = np.asarray(pb.workspace_min, float), np.asarray(pb.workspace_max, float)
    v, accel = pb.resolution.max_speed_m_s, pb.resolution.max_accel_m_s2
    if scene.realization is None and scene.traced is None:
        fp = best_feasible_path(scene, times, grid_path, pb.relay_start, lo, hi, v, max_tilt, kind, max_accel=accel)
        return (fp.capacity, fp.position), fp.status
    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    pos = np.clip(speed_limited(grid_path, np.clip(pb.relay_start, lo, hi), v * dt, None if accel is None else accel * dt**2), lo, hi)
    cap = leaning_capacity(scene, times, pos, axis_cone(max_tilt, np.radians(pb.resolution.axis_step_deg)), max_tilt)
    why = "traced channel" if scene.traced is not None else "large-scale realization"
    return (cap, pos), f"not refined ({why})"


def cached_bound(pb, key: str, progress=None, *, compute=None, kind=None):
    """``compute_bound`` once per ``key`` (everything the problem depends on), kept in the cache folder
    (``compute``, ``kind``: another bound's function and class, e.g. a fleet's network bound)."""
    compute, kind = compute or compute_bound, kind or CapacityBound
    path = cache_dir() / "bounds" / f"bound_{key}.npz"
    with cache_lock(path):  # campaign runs sharing a geometry compute it once
        if entry_is_intact(path):
            try:
                with np.load(path, allow_pickle=False) as z:
                    resolution = json.loads(str(z["resolution"]))
                    arrays = {k: z[k] for k in z.files if k not in ("resolution", "outage_threshold", "assumptions")}
                    return kind(**arrays, resolution=resolution, outage_threshold=float(z["outage_threshold"]),
                                assumptions=str(z["assumptions"]))
            except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
                log.warning("cached bound %s is unreadable (%s): recomputed", path, exc)
        bound = compute(pb, progress)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
        with os.fdopen(fd, "wb") as f:
            payload: dict = {**bound.arrays(), "resolution": json.dumps(bound.resolution),
                             "outage_threshold": bound.outage_threshold, "assumptions": bound.assumptions}
            np.savez(f, **payload)
        publish_checked(Path(tmp), path)
    return bound


def bound_key(data: dict) -> str:
    """Cache key of a bound from the plain data it depends on (the composition root gathers it)."""
    text = json.dumps(data, sort_keys=True, default=str) + BOUND_VERSION
    return hashlib.sha256(text.encode()).hexdigest()[:20]
