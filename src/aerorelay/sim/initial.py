"""Link budget of a scene's initial geometry (all attitudes zero)."""

from __future__ import annotations

import numpy as np

from ..models.channel import misalignment, mutual_alignment
from ..models.radio import RadioScene


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
