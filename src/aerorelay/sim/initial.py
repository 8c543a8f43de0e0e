"""Link budget of a scene's initial geometry (all attitudes zero)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..models.channel import misalignment, mutual_alignment
from ..models.radio import NodePose, RadioScene


def initial_link_budget(scene: RadioScene, relay_position, source_position) -> dict[str, float]:
    """SINRs, capacity and mutual alignment at t = 0 with level attitudes and every jammer at its
    t = 0 position and peak power; ``gamma_21`` / ``gamma_10`` are the route's two hops, and
    ``inr_*`` each receiver's interference-to-noise ratio (dB)."""
    I = np.eye(3)
    p1, p2 = np.asarray(relay_position, float), np.asarray(source_position, float)
    relay, source, bs = scene.name_of("relay"), scene.name_of("source"), scene.name_of("base_station")
    poses = {relay: scene.pose(relay, p1, I), source: scene.pose(source, p2, I)}
    peak = np.array([j.power for j in scene.jammers])
    state = scene.evaluate(0.0, poses, jammer_powers=peak)
    g21, g10 = (float(g) for g in state.sinr)
    p0 = scene.fixed_pose(bs).position
    ma = float(mutual_alignment(misalignment(p1, I, p2), misalignment(p1, I, p0)))
    inr = [10 * np.log10(float(i) / scene.budget.noise_power) if float(i) > 0 else -np.inf for i in state.interference]
    return {"gamma_21": g21, "gamma_10": g10, "capacity": float(state.capacity), "mutual_alignment": ma,
            "inr_relay_db": inr[0], "inr_bs_db": inr[1]}


def _db(x: float) -> float:
    return 10.0 * float(np.log10(x)) if x > 0 else -np.inf


def start_poses(scene: RadioScene, starts: Mapping[str, object]) -> dict[str, NodePose]:
    """Every node's pose at the start: the moving ones at ``starts`` (name -> m, world) with level
    attitudes (a start of no node of the scene, a waiting spare's, left out), the fixed ones where they stand."""
    I = np.eye(3)
    names = scene.node_names  # a spare waits outside the network: no node of its scene
    poses = {n: scene.pose(n, np.asarray(p, float), I) for n, p in starts.items() if n in names}
    return {n.name: scene.fixed_pose(n.name) for n in scene.nodes if n.position is not None} | poses


def link_budget_lines(scene: RadioScene, starts: Mapping[str, object], *, physical: bool) -> list[tuple[str, str]]:
    """The initial link budget line by line (level attitudes, jammers at peak) with the moving nodes
    at ``starts`` (name -> m, world): per hop distance, path loss, antenna gains, received,
    interference and noise powers, SINR; the capacity (per route and the network's rate for a
    network). Powers in dBm (``physical``) or dBW (the paper's normalized 1 W units), gains in dBi."""
    poses = start_poses(scene, starts)
    state = scene.evaluate(0.0, poses, jammer_powers=np.array([j.power for j in scene.jammers]))
    b = scene.budget
    unit, off = ("dBm", 30.0) if physical else ("dBW", 0.0)
    rows = [("transmit power", f"{_db(b.tx_power) + off:.1f} {unit}"), ("noise power", f"{_db(b.noise_power) + off:.1f} {unit}")]
    for j in scene.jammers:
        rows.append((f"jammer '{j.name}' peak power", f"{_db(j.power) + off:.1f} {unit}"))
    for k, (tx, rx) in enumerate(state.hops):
        ptx, prx = poses[tx], poses[rx]
        d = prx.position - ptx.position
        dist = float(np.linalg.norm(d))
        g_tx = scene.node(tx).antenna.pattern.gain_from_cos(float(d @ ptx.axis) / dist)
        g_rx = scene.node(rx).antenna.pattern.gain_from_cos(float(-d @ prx.axis) / dist)
        path = float(scene.path_gain.gain_between(ptx.position, prx.position, dist**2))
        loss = -_db(path)
        rx_power = _db(b.tx_power * g_tx * g_rx * path) + off
        rows += [(f"{tx} -> {rx}: distance", f"{dist:.2f} m"), (f"{tx} -> {rx}: path loss", f"{loss:.1f} dB"),
                 (f"{tx} -> {rx}: antenna gains tx / rx", f"{_db(g_tx):.1f} / {_db(g_rx):.1f} dBi"),
                 (f"{tx} -> {rx}: received power", f"{rx_power:.1f} {unit}"),
                 (f"{tx} -> {rx}: interference at {rx}", f"{_db(float(state.interference[k])) + off:.1f} {unit}"),
                 (f"{tx} -> {rx}: SINR", f"{_db(float(state.sinr[k])):.1f} dB")]
    def rate(c) -> str:
        return f"{float(c) / 1e6:.3f} Mbit/s" if physical else f"{float(c):.4g} bit/s/Hz"

    if len(scene.all_routes) == 1:
        rows.append(("end-to-end capacity", rate(state.capacity)))
        return rows
    for route, c in zip(scene.all_routes, state.route_capacity, strict=True):
        rows.append((f"route {' -> '.join(route)}: capacity alone", rate(c)))
    rows.append(("network rate (every source, each hop its own slot)", rate(state.capacity)))
    return rows
