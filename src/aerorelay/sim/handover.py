"""Which base station serves each route that may end at several (``routes = [[..., "any"]]``,
``[[base_stations]]``): the network's handover rule, decided from the true rates of every step.

The rule (docs/concepts/operations.md): at the first step each such route takes the base station
whose route rate is highest; after that it hands over to the best other one when that one's route
rate exceeds the serving one's by ``margin_db`` (``10 log10(C_best / C_serving) > margin_db``; a
dead serving route hands over to any live one) and the serving one has served for at least
``dwell_s``. A route's rate counts every hop of it (``models.radio.route_capacity``), so the
choice weighs the relays' hops as much as the last one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..models import checks
from ..models.radio import ChannelState, RadioScene


@dataclass(frozen=True)
class HandoverRule:
    """``margin_db``: how much better (dB of route rate) another base station must be; ``dwell_s``:
    the least time (s) a base station serves a route after it took it."""

    margin_db: float = 3.0
    dwell_s: float = 2.0

    def __post_init__(self):
        checks.number("HandoverRule", "margin_db", self.margin_db, lo=0.0)
        checks.number("HandoverRule", "dwell_s", self.dwell_s, lo=0.0)


def better(candidate: float, serving: float, margin_db: float) -> bool:
    """Whether a route rate ``candidate`` beats ``serving`` by more than ``margin_db`` (a dead serving
    route: any live candidate does)."""
    if not serving > 0.0:
        return candidate > 0.0
    return candidate > 0.0 and 10.0 * (math.log10(candidate) - math.log10(serving)) > margin_db


class Handover:
    """The serving base station of each route that may take several, by its source (one route per
    source); ``decide`` once a step."""

    def __init__(self, rule: HandoverRule):
        self.rule = rule
        self.since: dict[str, float] = {}  # per source, when its serving base station took it (s)
        self.count: dict[str, int] = {}  # per source, handovers so far (the first choice not counted)

    def decide(self, t: float, scene: RadioScene, state: ChannelState) -> tuple[str, ...] | None:
        """The routes' ends from step ``t``'s true rates (``state``: ``scene.evaluate(..., ends="serving")``):
        None when no route changes its base station, else every route's end."""
        ends = [r[-1] for r in scene.all_routes]
        changed = False
        for i, (routes, rates) in enumerate(zip(scene.candidate_routes, state.candidates, strict=True)):
            if len(routes) < 2:
                continue
            source = routes[0][0]
            stations = [r[-1] for r in routes]
            c = np.array([float(v) for v in rates])
            best = int(np.argmax(c))
            if source not in self.since:  # the first step: the best one serves
                self.since[source], self.count[source] = t, 0
                changed |= stations[best] != ends[i]
                ends[i] = stations[best]
                continue
            serving = stations.index(ends[i])
            if best != serving and t - self.since[source] >= self.rule.dwell_s - 1e-9 \
                    and better(c[best], c[serving], self.rule.margin_db):
                ends[i], changed = stations[best], True
                self.since[source] = t
                self.count[source] += 1
        return tuple(ends) if changed else None
