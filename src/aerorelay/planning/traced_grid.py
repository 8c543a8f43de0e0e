"""The capacity planner's candidates scored on the ray-traced channel (``controller.capacity.scoring =
"traced"`` with ``[channel.propagation] model = "ray_traced"``): ``TracedRelayGrid`` has the call of
``relay_grid.CompiledRelayGrid`` (relay positions x antenna axes -> the route's capacity, eq. 5-9) but takes
each hop's gain from one trace of the scene (``models/raytrace.py``): the source, the base station and
every known jammer as transmitters, the candidates (and the base station, for the jammers' links) as
receivers, in one Sionna call; the relay-to-base-station hop traced from the base station (reciprocity:
the same gain, tested in ``tests/models/test_raytrace.py``). Each path weighed by both ends' antennas (the
candidate's at each axis), summed as the plant's channel sums them. The scene is a map the relay is given
(its buildings), not the truth it must not see: the jammers are the ones the relay knows (positions and
powers as handed in)."""

from __future__ import annotations

import numpy as np

from ..models.radio import NodePose, RadioScene, route_capacity
from ..models.raytrace import RayTracer, TracedLinks


class TracedRelayGrid:
    """``grid(positions (M, 3), axes (K, 3), source_pose, jammer_positions (nJ, 3), jammer_powers (nJ,))`` ->
    capacity ``(M, K)`` on the traced channel (see the module); ``coherent``: the paths' sum."""

    def __init__(self, scene: RadioScene, tracer: RayTracer, *, source: str, coherent: bool = False, relay: str | None = None):
        self.scene, self.tracer, self.coherent = scene, tracer, coherent
        self.source, self.relay = source, relay or scene.name_of("relay")
        route = next(r for r in scene.all_routes if self.relay in r)
        self.bs = route[-1]
        if list(route) != [source, self.relay, self.bs] or any(scene.handover):
            raise ValueError(f"traced scoring: the relay's route must be {source} -> {self.relay} -> one base station, got "
                             f"{list(route)}" + (" that may end at several" if any(scene.handover) else ""))
        self.traces = 0

    def _gains(self, links: TracedLinks, pat_tx, b_tx, pat_rx, axes: np.ndarray, rx_is_candidate: bool) -> np.ndarray:
        """``(M, K)``: each link's power gain with the candidate's pattern at each axis (the receiver's, or the
        transmitter's when ``rx_is_candidate`` is False)."""
        out = np.empty((len(links.a), len(axes)))
        for k, b in enumerate(axes):
            if rx_is_candidate:
                out[:, k] = links.gain(pat_tx, b_tx, pat_rx, b, coherent=self.coherent)
            else:
                out[:, k] = links.gain(pat_tx, b, pat_rx, b_tx, coherent=self.coherent)
        return out

    def __call__(self, positions, axes, source_pose: NodePose, jammer_positions, jammer_powers, others=()) -> np.ndarray:
        P, B = np.atleast_2d(np.asarray(positions, float)), np.atleast_2d(np.asarray(axes, float))
        pj = np.asarray(jammer_positions, float).reshape(-1, 3)
        PJ = np.asarray(jammer_powers, float).ravel()
        m, sc = len(P), self.scene
        bs = sc.fixed_pose(self.bs)
        loud = [j for j in range(len(pj)) if PJ[j] > 0]
        tx = [source_pose.position] * m + [bs.position] * m
        rx = [*P, *P]
        for j in loud:
            tx += [pj[j]] * (m + 1)
            rx += [*P, bs.position]
        links = self.tracer.trace(np.array(tx), np.array(rx))
        self.traces += 1
        relay_pat = sc.node(self.relay).antenna.pattern
        h21 = self._gains(links.take(slice(0, m)), sc.node(self.source).antenna.pattern, source_pose.axis, relay_pat, B, True)
        # the relay -> base station hop, traced from the base station: the relay's pattern at the arrival end
        h10 = self._gains(links.take(slice(m, 2 * m)), sc.node(self.bs).antenna.pattern, bs.axis, relay_pat, B, True)
        poses = sc.with_fixed({self.source: source_pose})
        emitters = sc.emitters(0.0, poses, positions=pj, powers=PJ)
        i_relay, i_bs = np.zeros((m, len(B))), 0.0
        at = 2 * m
        for j in loud:
            e = emitters[j]
            i_relay = i_relay + PJ[j] * self._gains(links.take(slice(at, at + m)), e.pattern, e.axis, relay_pat, B, True)
            one = links.take(slice(at + m, at + m + 1))
            i_bs += PJ[j] * float(one.gain(e.pattern, e.axis, sc.node(self.bs).antenna.pattern, bs.axis, coherent=self.coherent)[0])
            at += m + 1
        b = sc.budget
        g21 = h21 * b.tx_power / (i_relay + b.noise_power)
        g10 = h10 * b.tx_power / (i_bs + b.noise_power)
        return np.asarray(route_capacity([g21, g10], b.bandwidth), float)
