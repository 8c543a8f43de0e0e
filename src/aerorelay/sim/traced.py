"""The plant's ray-traced channel (``[channel.propagation] model = "ray_traced"``): every link of the
network flying now (each hop, each receiver's jammer links; ``RadioScene.link_ends``) traced in one
call to Sionna RT (``models/raytrace.py``), weighed by both ends' antennas at their attitudes each
control step, and handed to ``RadioScene.evaluate`` as the links' power gains.

Tracing is slower than the control loop on a CPU (80-190 ms per call in a street canyon, measured),
so the links are traced every ``trace_period_s`` and, in between, carried to where the ends are
(``TracedLinks.moved``: the line of sight exact, every other path's length, delay and phase to first
order, its interactions' coefficients held). What that costs against tracing every step is measured
in docs/concepts/ray-tracing.md. A network that changes (a relay lost) is traced again at once.

Log columns per hop: ``paths_<tx>_<rx>`` (valid paths) and ``delay_spread_ns_<tx>_<rx>`` (RMS, ns, over
the weighed path powers); ``trace_age_s``: seconds since the links were traced (0 on a tracing step).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..models.radio import NodePose, RadioScene
from ..models.raytrace import RayTracer, TracedLinks


class TracedChannel:
    """``gains, values = step(scene, t, poses)``: the power gain of every link of ``scene.link_ends()`` (antennas
    included) and the log values. ``coherent``: the paths summed with their phases, else in power."""

    def __init__(self, tracer: RayTracer, *, trace_period_s: float, coherent: bool):
        self.tracer, self.period, self.coherent = tracer, float(trace_period_s), coherent
        self.carrier_hz = float(tracer.settings.carrier_hz)
        self.traces = 0  # calls to the tracer (cached or not)
        self._links: TracedLinks | None = None
        self._ends: tuple = ()
        self._tx = self._rx = np.zeros((0, 3))
        self._traced_at = -np.inf

    @staticmethod
    def columns(scene: RadioScene) -> list[str]:
        hops = [f"{tx}_{rx}" for tx, rx in scene.hops]
        return [f"paths_{h}" for h in hops] + [f"delay_spread_ns_{h}" for h in hops] + ["trace_age_s"]

    def step(self, scene: RadioScene, t: float, poses: Mapping[str, NodePose]) -> tuple[np.ndarray, dict[str, float]]:
        poses = scene.with_fixed(poses)
        emitters = scene.emitters(t, poses)
        ends = scene.link_ends()
        tx = np.array([poses[a].position if j is None else scene.jammers[j].position_at(t) for a, _, j in ends], float)
        rx = np.array([poses[b].position for _, b, _ in ends], float)
        if self._links is None or tuple(ends) != self._ends or t - self._traced_at >= self.period - 1e-9:
            self._links, self._ends, self._tx, self._rx, self._traced_at = self.tracer.trace(tx, rx), tuple(ends), tx, rx, t
            self.traces += 1
            links = self._links
        else:
            links = self._links.moved(self._tx, self._rx, tx, rx, self.carrier_hz)
        gains = np.zeros(len(ends))
        values: dict[str, float] = {"trace_age_s": float(t - self._traced_at)}
        for k, (a, b, j) in enumerate(ends):
            one = links.take(slice(k, k + 1))
            pat_tx, b_tx, pat_rx, b_rx = scene.end_antennas((a, b, j), poses, emitters)
            gains[k] = float(one.gain(pat_tx, b_tx, pat_rx, b_rx, coherent=self.coherent)[0])
            if j is None:
                values[f"paths_{a}_{b}"] = float(one.paths[0])
                values[f"delay_spread_ns_{a}_{b}"] = float(one.delay_spread(pat_tx, b_tx, pat_rx, b_rx)[0]) * 1e9
        return gains, values
