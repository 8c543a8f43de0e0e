"""Capacity planners' candidates scored on the ray-traced channel (``controller.capacity.scoring = "traced"``
with ``[channel.propagation] model = "ray_traced"``), for one relay and for a fleet.

``TracedNetwork`` is the one machinery: the network's rate (eq. 5-9) of a batch of configurations, every
link of the scene (``RadioScene.link_ends``: each hop, each hop receiver's jammer links) for every
configuration traced in one Sionna call (``models/raytrace.py``), weighed by both ends' antennas at their
axes and summed as the plant's channel sums them (``sim/traced.py``), then handed to
``RadioScene.evaluate`` as the links' power gains. A link whose transmitter moves across the batch while
its receiver does not is traced from the receiver (reciprocity: the same gain, tested in
``tests/models/test_raytrace.py``), so the few fixed ends are Sionna's transmitters and the many candidates
its receivers. ``TracedRelayGrid`` has the call of ``relay_grid.CompiledRelayGrid`` (relay positions x
antenna axes -> the network's rate) and ``TracedConfigurations`` that of ``relay_grid.CompiledConfigurations``
(a fleet's joint moves). The scene is a map the relays are given (its buildings), not the truth they must
not see: the jammers are the ones the fleet knows (positions and powers as handed in)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..models.radio import NodePose, RadioScene
from ..models.raytrace import RayTracer

ROWS_PER_CALL = 20_000  # configurations weighed at once (each row holds every path's coefficient and directions)


def jammers_at(scene: RadioScene, t: float, silent: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The scene's jammers at ``t`` as the traced scorers take them: positions ``(nJ, 3)`` (m) and powers ``(nJ,)`` (W);
    ``silent``: every power 0 (not localized yet) and the positions 0, where a silent jammer adds nothing."""
    if silent:
        return np.zeros((len(scene.jammers), 3)), np.zeros(len(scene.jammers))
    return (np.array([j.position_at(t) for j in scene.jammers], float).reshape(-1, 3),
            np.array([float(j.power_at(t)) for j in scene.jammers]))


class TracedNetwork:
    """``rates(poses, jammer_positions (nJ, 3), jammer_powers (nJ,), n)`` -> the network's rate ``(n,)`` of ``n``
    configurations on the traced channel (see the module); each node's pose in ``poses`` has a position and an
    axis ``(3,)`` (the same in every configuration) or ``(n, 3)`` (m, unit, world); fixed nodes as placed.
    ``coherent``: the paths summed with their phases, else in power."""

    def __init__(self, scene: RadioScene, tracer: RayTracer, *, coherent: bool = False):
        if scene.route_choice:
            raise ValueError("traced scoring: a route that may end at several base stations ('any') or skip relays "
                             "(network.route_selection) is scored on one traced route only; name its end, fly 'fixed'")
        self.scene, self.tracer, self.coherent = scene, tracer, coherent
        self.traces = 0  # calls to the tracer (cached or not)

    def rates(self, poses: Mapping[str, NodePose], jammer_positions, jammer_powers, n: int) -> np.ndarray:
        sc = self.scene
        poses = sc.with_fixed(poses)
        pj = np.asarray(jammer_positions, float).reshape(-1, 3)
        PJ = np.asarray(jammer_powers, float).ravel()
        emitters = sc.emitters(0.0, poses, positions=pj, powers=PJ)

        def rows(v) -> np.ndarray:
            return np.broadcast_to(np.asarray(v, float), (n, 3))

        # every link's ends (n rows each) and whether it is traced from its receiver
        links: list[tuple[str, str, int | None, bool] | None] = []
        tx: list[np.ndarray] = []
        rx: list[np.ndarray] = []
        for a, b, j in sc.link_ends():
            if j is not None and PJ[j] == 0.0:
                links.append(None)  # a silent jammer adds nothing (RadioScene.interference skips it)
                continue
            p_tx = np.asarray(poses[a].position if j is None else emitters[j].position, float)
            p_rx = poses[b].position
            reverse = np.ndim(p_tx) == 2 and np.ndim(p_rx) == 1  # the moving end as the receiver (reciprocity)
            links.append((a, b, j, reverse))
            tx.append(rows(p_rx if reverse else p_tx))
            rx.append(rows(p_tx if reverse else p_rx))
        traced = self.tracer.trace(np.concatenate(tx), np.concatenate(rx)) if tx else None
        self.traces += 1 if tx else 0
        gains, at = [], 0
        for link in links:
            if link is None:
                gains.append(np.zeros(n))
                continue
            a, b, j, reverse = link
            assert traced is not None
            one = traced.take(slice(at, at + n))
            at += n
            pat_tx, b_tx, pat_rx, b_rx = sc.end_antennas((a, b, j), poses, emitters)
            if reverse:
                gains.append(one.gain(pat_rx, rows(b_rx), pat_tx, rows(b_tx), coherent=self.coherent))
            else:
                gains.append(one.gain(pat_tx, rows(b_tx), pat_rx, rows(b_rx), coherent=self.coherent))
        state = sc.evaluate(0.0, poses, jammer_positions=pj, jammer_powers=PJ, link_gains=gains)
        rate = np.broadcast_to(np.asarray(state.capacity, float), (n,))
        return np.where(np.isfinite(rate), rate, 0.0)  # a jammer on a receiver: capacity 0, as the compiled grid's


class TracedRelayGrid:
    """``grid(positions (M, 3), axes (K, 3), source_pose, jammer_positions (nJ, 3), jammer_powers (nJ,), others=())`` ->
    the network's rate ``(M, K)`` on the traced channel with ``relay`` at each position and axis, the source and
    ``moving`` (their poses ``others``, in that order: a fleet's other sources and relays) as given: the call of
    ``relay_grid.CompiledRelayGrid``."""

    def __init__(self, scene: RadioScene, tracer: RayTracer, *, source: str, coherent: bool = False, relay: str | None = None,
                 moving: tuple[str, ...] = ()):
        self.network = TracedNetwork(scene, tracer, coherent=coherent)
        self.source, self.relay, self.moving = source, relay or scene.name_of("relay"), tuple(moving)

    @property
    def traces(self) -> int:
        return self.network.traces

    def __call__(self, positions, axes, source_pose: NodePose, jammer_positions, jammer_powers,
                 others: tuple[NodePose, ...] = ()) -> np.ndarray:
        P, B = np.atleast_2d(np.asarray(positions, float)), np.atleast_2d(np.asarray(axes, float))
        m, k = len(P), len(B)
        if len(others) != len(self.moving):
            raise ValueError(f"traced relay grid: built for {len(self.moving)} other moving node(s), got {len(others)}")
        fixed = {self.source: source_pose, **dict(zip(self.moving, others, strict=True))}
        out = np.empty((m, k))
        block = max(1, ROWS_PER_CALL // m)  # axes per call: a radio map's thousands of cells x every axis in blocks
        for a in range(0, k, block):  # (the positions' trace is the same each block: from the tracer's memory)
            kb = len(B[a:a + block])
            poses = fixed | {self.relay: NodePose(np.repeat(P, kb, axis=0), np.tile(B[a:a + block], (m, 1)))}  # position-major
            out[:, a:a + kb] = self.network.rates(poses, jammer_positions, jammer_powers, m * kb).reshape(m, kb)
        return out


class TracedConfigurations:
    """``rates(positions (n, K, 3), axes (n, K, 3), sources, jammer_positions (nJ, 3), jammer_powers (nJ,))`` -> the
    network's rate ``(n,)`` of ``n`` configurations of ``relays`` on the traced channel, the ``source_names``' poses
    ``sources`` in that order: the call of ``relay_grid.CompiledConfigurations``."""

    def __init__(self, scene: RadioScene, tracer: RayTracer, relays: tuple[str, ...], source_names: tuple[str, ...], *,
                 coherent: bool = False):
        self.network = TracedNetwork(scene, tracer, coherent=coherent)
        self.relays, self.sources = tuple(relays), tuple(source_names)

    def __call__(self, positions, axes, sources: tuple[NodePose, ...], jammer_positions, jammer_powers) -> np.ndarray:
        P, B = np.asarray(positions, float), np.asarray(axes, float)
        if P.ndim != 3 or P.shape[1:] != (len(self.relays), 3) or B.shape != P.shape or len(sources) != len(self.sources):
            raise ValueError(f"traced configurations: expected (n, {len(self.relays)}, 3) positions and axes and "
                             f"{len(self.sources)} source pose(s), got {P.shape}, {B.shape}, {len(sources)}")
        poses = dict(zip(self.sources, sources, strict=True))
        poses |= {r: NodePose(P[:, k], B[:, k]) for k, r in enumerate(self.relays)}
        return self.network.rates(poses, jammer_positions, jammer_powers, len(P))
