"""The direct-link baseline (``sim.baseline = "direct"``): is the relay worth it?

Per logged step, the network's rate with no relay at all: each source straight to its base station (the best of
those its route may end at), the source where it flew and with its attitude as logged, the base stations fixed, the
true jammers at that time, on the scene's deterministic channel (path gain, antennas, link budget; the random
channel terms are refused with this setting at load: ``config.scenario``). One hop, so the rate is the single-hop
formula ``B log2(1 + SINR)`` (eq. 5 and 9 with one hop; a network of several sources shares the time as its
routes do). The run's ``c_min`` and ``c_mean`` over this link's are ``c_min_over_direct`` and
``c_mean_over_direct`` in ``metrics.json``."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..models.geometry import rotation_batch
from ..models.radio import RadioScene
from .log_schema import sources_in


def direct_scene(scene: RadioScene) -> RadioScene:
    """``scene`` with every relay gone: each route from its source straight to its base station."""
    return scene.without({n.name for n in scene.nodes if n.role == "relay"})


def direct_rate(scene: RadioScene, log: Mapping[str, np.ndarray]) -> np.ndarray:
    """The direct link's rate at every step of ``log`` (``sim.log_schema``: ``t``, each source's ``p_x..psi``), in
    the scene's capacity unit, with ``scene``'s true jammers."""
    direct = direct_scene(scene)
    t = np.asarray(log["t"], float)
    sources = sources_in(log)
    where = {s: np.column_stack([np.asarray(log[f"{s}.{q}"], float) for q in ("p_x", "p_y", "p_z")]) for s in sources}
    R = {s: rotation_batch(np.column_stack([np.asarray(log[f"{s}.{q}"], float) for q in ("phi", "theta", "psi")]))
         for s in sources}
    out = np.empty(t.size)
    for k in range(t.size):
        poses = {s: direct.pose(s, where[s][k], R[s][k]) for s in sources}
        out[k] = float(direct.evaluate(float(t[k]), poses).capacity)
    return out
