"""A fleet's network bound on the ray-traced channel's map (``[channel.propagation] model = "ray_traced"``).

The certified network bound (``planning.network_bound``) bounds every hop over whole cubes with the analytic
channel's interval terms; a traced channel has no such terms. Here the hops' terms are taken **at the cubes'
centres** (the traced map, ``bound.network_grid_m``), traced once per fixed end and instant and, for the hops
between two relays, once per pair of cells (every centre traced to every other: the map's cost grows with
the square of its cells, checked before any work in ``bound_cost.traced_network_bound_cost``):

- a hop between a fixed node (a source at its planned pose, the base station) and a relay: its gain weighed
  by the fixed node's antenna at its axis and the relay's at its best axis of the cone (exact over the cone's
  axes, ``axis_step_deg`` apart, tilt up to the hover limit);
- a hop between two relays: each path weighed by each end's best gain over its cone toward that path (a relay's
  axis need not be the same for every path: at least the best one axis pair's gain, ``(sum_p |a_p| sqrt(G_p))^2``
  for the coherent sum);
- each relay receiver's jammer interference the least over its cone's axes (it may put its null on a jammer),
  a fixed receiver's at its axis.

A relay's axis is relaxed per hop, as in the certified bound, and the same min-sum on the relays' forest
(``forest_min_marginals``) gives ``static``: at least the rate of every configuration of the map's centres with
any holdable axes, **not** of the space between them. ``achieved`` is the traced rate of the ``static`` cells with
one axis per relay (each relay's best with the others held, twice round). The upper path bound is the certified
one's dynamic programming (``NetworkBoundSolver.upper_path``) over these terms kept to what each relay can reach
from its start; the lower one each relay chasing its ``achieved`` cell from its start within the speed and
acceleration limits, its traced rate at each sample with the axes chosen the same way (not refined; its status
says when two relays come closer than the separation on it: then it is no fleet's path)."""

from __future__ import annotations

import numpy as np

from ..models.raytrace import RayTracer, TracedLinks
from .feasible_path import speed_limited
from .fleet_configuration import coordinate_best_axes
from .network_bound import NetworkBound, NetworkBoundProblem, NetworkBoundSolver, forest_min_marginals
from .traced_grid import TracedConfigurations, jammers_at

TRACED_ASSUMPTIONS = ("on the ray-traced channel's map: every hop's term at the cubes' centres (not bounded over the "
                      "cubes), each relay end's best gain over its holdable axes per hop (per path for a hop between "
                      "two relays), each relay receiver's least jammer interference over its axes; min-sum dynamic "
                      "programming over the relays' cells; achieved: the static cells' traced rate with one axis per "
                      "relay; flyable: each relay chasing its achieved cell within the speed and acceleration limits, "
                      "not refined")


def best_over_cone(pattern, directions: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``(...)``: ``pattern``'s largest gain toward each unit direction ``(..., 3)`` over the axes ``(K, 3)``."""
    return np.asarray(pattern.gain_from_cos(np.clip(directions @ axes.T, -1.0, 1.0)), float).max(axis=-1)


class TracedTerms:
    """The hops' terms at the cubes' centres on the traced channel (see the module), for ``NetworkBoundSolver``'s
    forest: ``unary(t, poses)`` and ``block`` for ``forest_min_marginals``."""

    def __init__(self, solver: NetworkBoundSolver, tracer: RayTracer, coherent: bool):
        self.solver, self.tracer, self.coherent = solver, tracer, coherent
        pb = solver.pb
        self.scene, self.cells = pb.scene, solver.cells
        self.axes = solver.configurations.cones  # each relay's holdable axes (axis_step_deg apart, up to its hover limit)
        self.open = np.isfinite(solver._excluded({}, self.cells, 0.0))  # centres not inside an obstacle's margin
        self.pair_gain = {(tx, rx): self._pair_gains(tx, rx) for tx, rx in solver.pairs}

    def _links(self, origin, n: np.ndarray | None = None) -> TracedLinks:
        cells = self.cells if n is None else self.cells[n]
        return self.tracer.trace(np.broadcast_to(np.asarray(origin, float), cells.shape), cells)

    def _relay_gain(self, links: TracedLinks, relay: str, pat_o, axis_o) -> np.ndarray:
        """``(M,)``: a fixed node's links to every cell weighed by its antenna at ``axis_o`` and ``relay``'s at its
        best axis (exact over the cone's axes)."""
        pat_r = self.scene.node(relay).antenna.pattern
        return np.max([links.gain(pat_o, axis_o, pat_r, b, coherent=self.coherent) for b in self.axes[relay]], axis=0)

    def _pair_gains(self, tx: str, rx: str) -> np.ndarray:
        """``(M, M)``: the hop ``tx -> rx``'s gain between every two open cells (``tx`` at the row's), each path at
        both ends' best gains over their cones; 0 within the separation or where a cell is not open."""
        M = len(self.cells)
        out = np.zeros((M, M))
        pat_t, pat_r = self.scene.node(tx).antenna.pattern, self.scene.node(rx).antenna.pattern
        sep = max(self.solver.pb.separation_m, 1e-6)
        for i in np.flatnonzero(self.open):
            others = np.flatnonzero(self.open & (np.linalg.norm(self.cells - self.cells[i], axis=1) >= sep))
            if not len(others):
                continue
            links = self._links(self.cells[i], others)
            w = best_over_cone(pat_t, links.departure, self.axes[tx]) * best_over_cone(pat_r, links.arrival, self.axes[rx])
            w = np.where(links.valid, w, 0.0)
            if self.coherent:  # |sum a_p sqrt(G_p)|^2 <= (sum |a_p| sqrt(G_p))^2
                out[i, others] = np.sum(np.abs(links.a) * np.sqrt(w), axis=1) ** 2
            else:
                out[i, others] = np.sum(np.abs(links.a) ** 2 * w, axis=1)
        return out

    def interference(self, t: float, poses) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """Each relay's least jammer interference at every cell over its axes ``(M,)`` and each fixed node's that receives a
        relay's hop (W)."""
        emitters = self.scene.emitters(t, poses)
        at_relays = {r: np.zeros(len(self.cells)) for r in self.solver.relays}
        at_fixed: dict[str, float] = {}
        for e in emitters:
            if e.power == 0.0:
                continue
            links = self._links(e.position)
            for r in self.solver.relays:
                pat_r = self.scene.node(r).antenna.pattern
                per_axis = [links.gain(e.pattern, e.axis, pat_r, b, coherent=self.coherent) for b in self.axes[r]]
                at_relays[r] = at_relays[r] + e.power * np.min(per_axis, axis=0)
        for name in {other for _, other, is_tx, _ in self.solver.unary if is_tx}:  # fixed receivers of relays' hops
            pose, total = poses[name], 0.0
            for e in emitters:
                if e.power == 0.0:
                    continue
                one = self.tracer.trace(np.asarray(e.position, float)[None], np.asarray(pose.position, float)[None])
                total += e.power * float(one.gain(e.pattern, e.axis, self.scene.node(name).antenna.pattern, pose.axis,
                                                  coherent=self.coherent)[0])
            at_fixed[name] = total
        return at_relays, at_fixed

    def unary(self, t: float, poses, at_relays, at_fixed) -> dict[str, np.ndarray]:
        """Each relay's terms ``(M,)`` from its hops with fixed nodes (``inf`` where it may not be)."""
        solver, b = self.solver, self.scene.budget
        out = {r: solver._excluded(poses, self.cells, 0.0) for r in solver.relays}
        for r, other, is_tx, count in solver.unary:
            o = poses[other]
            g = self._relay_gain(self._links(o.position), r, self.scene.node(other).antenna.pattern, o.axis)
            i_rx = at_fixed[other] if is_tx else at_relays[r]
            with np.errstate(divide="ignore", invalid="ignore"):
                out[r] = out[r] + count * solver._term(g * b.tx_power / (i_rx + b.noise_power))
        return out

    def block(self, at_relays):
        def terms(a: str, b: str, rows: slice) -> np.ndarray:
            out: np.ndarray | float = 0.0
            for tx, rx, count in self.solver.edges[tuple(sorted((a, b)))]:
                g = self.pair_gain[tx, rx] if tx == a else self.pair_gain[tx, rx].T  # rows are a's cells
                g = g[rows]
                i_rx = at_relays[rx][None, :] if rx == b else at_relays[rx][rows][:, None]
                with np.errstate(divide="ignore", invalid="ignore"):
                    out = out + count * self.solver._term(g * self.scene.budget.tx_power / (i_rx + self.scene.budget.noise_power))
            return np.asarray(out)
        return terms


def _axes_for(configs: TracedConfigurations, terms: TracedTerms, t: float, P: np.ndarray, poses) -> tuple[float, np.ndarray]:
    """The traced rate of the relays at ``P`` ``(K, 3)`` and their axes ``(K, 3)`` (``coordinate_best_axes`` over their
    cones, each batch of axes in one traced call)."""
    sources = tuple(poses[s] for s in configs.sources)
    pj, PJ = jammers_at(terms.scene, t)
    A, rate = coordinate_best_axes([terms.axes[r] for r in terms.solver.relays],
                                   lambda batch: configs(np.repeat(P[None], len(batch), axis=0), batch, sources, pj, PJ))
    return rate, A


def compute_traced_network_bound(pb: NetworkBoundProblem, tracer: RayTracer, coherent: bool, progress=None) -> NetworkBound:
    """The network bound on the traced map (see the module)."""
    solver = NetworkBoundSolver(pb)
    terms = TracedTerms(solver, tracer, coherent)
    res, bw = pb.resolution, pb.scene.budget.bandwidth
    sources = tuple(n.name for n in pb.scene.nodes if n.role == "source")
    configs = TracedConfigurations(pb.scene, tracer, tuple(solver.relays), sources, coherent=coherent)
    times = np.arange(0.0, pb.duration_s + 1e-9, res.dt_s)
    K = len(solver.relays)
    static, achieved = np.empty(len(times)), np.empty(len(times))
    sp, ap, ax = np.empty((len(times), K, 3)), np.empty((len(times), K, 3)), np.empty((len(times), K, 3))
    reachable = []
    with_starts = set(pb.starts) >= set(solver.relays)
    for k, t in enumerate(times):
        poses = solver.fixed_poses(float(t))
        at_relays, at_fixed = terms.interference(float(t), poses)
        unary = terms.unary(float(t), poses, at_relays, at_fixed)
        block = terms.block(at_relays)
        total, marginals = forest_min_marginals(solver.relays, unary, solver.neighbours, block)
        static[k] = bw / total if total > 0 else np.inf  # a dead hop everywhere: total inf, static 0
        cells = np.array([int(np.argmin(marginals[r])) for r in solver.relays], dtype=int)
        sp[k] = ap[k] = solver.cells[cells]
        achieved[k], ax[k] = _axes_for(configs, terms, float(t), sp[k], poses)
        if with_starts:
            reach = solver.out_of_reach(float(t))
            reachable.append(forest_min_marginals(solver.relays, {r: u + reach[r] for r, u in unary.items()},
                                                  solver.neighbours, block)[1])
        if progress is not None:
            progress(k + 1, len(times))
    resolution = {"grid_m": res.grid_m, "dt_s": res.dt_s, "axis_step_deg": res.axis_step_deg, "cells": int(len(solver.cells)),
                  "open_cells": int(terms.open.sum()), "times": int(len(times)), "method": "min-sum dynamic programming on "
                  "the relays' forest over the traced map's cube centres (not certified between them)",
                  "tilt_limits_deg": {r: float(np.degrees(v)) for r, v in pb.tilt_limits.items()},
                  "separation_m": pb.separation_m}
    fr, fp, fa = np.empty(0), np.empty((0, K, 3)), np.empty((0, K, 3))
    upper, up = np.empty(0), np.empty((0, 3))
    if with_starts:
        upper, up, binding = solver.upper_path(times, [reachable], [static])
        dt = float(times[1] - times[0]) if len(times) > 1 else res.dt_s
        accel = None if res.max_accel_m_s2 is None else res.max_accel_m_s2 * dt**2
        fp = np.stack([speed_limited(ap[:, i], np.clip(pb.starts[r], solver.lo, solver.hi), res.max_speed_m_s * dt, accel)
                       for i, r in enumerate(solver.relays)], axis=1)
        fr, fa = np.empty(len(times)), np.empty((len(times), K, 3))
        for i, t in enumerate(times):
            fr[i], fa[i] = _axes_for(configs, terms, float(t), fp[i], solver.fixed_poses(float(t)))
        gaps = [np.linalg.norm(fp[:, a] - fp[:, b], axis=1).min() for a in range(K) for b in range(a + 1, K)]
        closest = float(min(gaps, default=np.inf))
        status = "not refined (traced channel)" + (f"; two relays {closest:.2f} m apart, closer than the separation"
                                                   if closest < pb.separation_m else "")
        resolution |= {"flyable_max_speed_m_s": res.max_speed_m_s, "flyable_max_accel_m_s2": res.max_accel_m_s2,
                       "flyable_status": status, "flyable_closest_relays_m": closest,
                       "path_mean_relay": binding}
    resolution["traced_calls"] = int(tracer.calls)
    return NetworkBound(times, static, sp, achieved, ap, ax, solver.relays, resolution, pb.outage_threshold,
                        TRACED_ASSUMPTIONS, flyable=fr, flyable_positions=fp, flyable_axes=fa, path_mean=upper,
                        path_mean_position=up)
