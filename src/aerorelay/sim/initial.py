"""Link budget of a scenario's initial geometry (all attitudes zero)."""

from __future__ import annotations

import numpy as np

from ..config import Scenario
from ..models.channel import end_to_end_capacity, link_sinr, misalignment, mutual_alignment


def initial_link_budget(sc: Scenario) -> dict[str, float]:
    """SINRs, capacity and mutual alignment at t = 0 with level attitudes and the jammer on."""
    I = np.eye(3)
    p0, p1, p2 = (np.array(v, float) for v in (sc.nodes.bs, sc.nodes.relay, sc.mission.start))
    pj = np.array(sc.jammer.position, float)
    kw = dict(
        tx_power=sc.channel.tx_power_w,
        jam_power=sc.jammer.power_w,
        noise_power=sc.channel.noise_power_w,
    )
    pat = sc.antenna.patterns()
    g21 = float(link_sinr(p2, I, p1, I, pj, pattern=pat.source, pattern_rx=pat.relay, **kw))
    g10 = float(link_sinr(p1, I, p0, I, pj, pattern=pat.relay, pattern_rx=pat.bs, **kw))
    cap = float(end_to_end_capacity(g21, g10, sc.channel.bandwidth))
    ma = float(mutual_alignment(misalignment(p1, I, p2), misalignment(p1, I, p0)))
    return {"gamma_21": g21, "gamma_10": g10, "capacity": cap, "mutual_alignment": ma}
