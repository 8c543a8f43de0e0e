"""Which base station serves each route that may end at several (``routes = [[..., "any"]]``,
``[[base_stations]]``) and which of its relays carry it (``network.route_selection = "subsets"``): the network's
handover rule, decided from the true rates of every step among each route's candidates.

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
from ..models.radio import ChannelState, RadioScene, route_via


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
    """The serving route of each route that may change (its end, its relays), by its source (one route per
    source); ``decide`` once a step."""

    def __init__(self, rule: HandoverRule):
        self.rule = rule
        self.since: dict[str, float] = {}  # per source, when its serving base station took it (s)
        self.count: dict[str, int] = {}  # per source, route changes so far (the first choice not counted)

    def decide(self, t: float, scene: RadioScene, state: ChannelState) -> tuple[tuple[str, ...], ...] | None:
        """The routes from step ``t``'s true rates (``state``: ``scene.evaluate(..., ends="serving")``) among each
        route's candidates (``RadioScene.candidate_routes``: its ends, the subsets of its relays): None when no route
        changes, else every route."""
        current = list(scene.all_routes)
        changed = False
        for i, (routes, rates) in enumerate(zip(scene.candidate_routes, state.candidates, strict=True)):
            if len(routes) < 2:
                continue
            source = routes[0][0]
            c = np.array([float(v) for v in rates])
            best = int(np.argmax(c))
            if source not in self.since:  # the first step: the best one serves
                self.since[source], self.count[source] = t, 0
                changed |= routes[best] != current[i]
                current[i] = routes[best]
                continue
            serving = routes.index(current[i])
            if best != serving and t - self.since[source] >= self.rule.dwell_s - 1e-9 \
                    and better(c[best], c[serving], self.rule.margin_db):
                current[i], changed = routes[best], True
                self.since[source] = t
                self.count[source] += 1
        return tuple(current) if changed else None


def candidate_label(scene: RadioScene, i: int, route: tuple[str, ...]) -> str:
    """Route ``i``'s candidate ``route`` in a column name: its source, the relays carrying it where the route may skip
    relays (``route_via``), its base station where it may end at several (``<source>.<relays>.<base station>``)."""
    skips, ends = bool(scene.skips and scene.skips[i]), bool(scene.route_ends[i])
    return ".".join([route[0], *([route_via(route)] if skips else []), *([route[-1]] if ends or not skips else [])])


def route_columns(scene: RadioScene) -> list[str]:
    """The log's columns of the routes that may change: ``<source>.base_station`` (its serving end, where it may end
    at several), ``<source>.route`` (the relays carrying it, where it may skip some: ``route_via``) and
    ``capacity_via.<candidate>`` (every candidate's rate, ``candidate_label``)."""
    cols: list[str] = []
    for i, rs in enumerate(scene.candidate_routes):
        if len(rs) < 2:
            continue
        cols += [f"{rs[0][0]}.base_station"] if scene.route_ends[i] else []
        cols += [f"{rs[0][0]}.route"] if scene.skips and scene.skips[i] else []
        cols += [f"capacity_via.{candidate_label(scene, i, r)}" for r in rs]
    return cols


def route_values(scene: RadioScene, state: ChannelState) -> dict[str, object]:
    """``route_columns``' values at a step: the serving routes (``scene.all_routes``) and every candidate's rate."""
    values: dict[str, object] = {}
    for i, (rs, route, rates) in enumerate(zip(scene.candidate_routes, scene.all_routes, state.candidates, strict=True)):
        if scene.skips:  # route selection: the relays carrying it (none left to choose from: 'direct')
            values[f"{route[0]}.route"] = route_via(route)
        if len(rs) < 2:
            continue
        if scene.route_ends[i]:
            values[f"{route[0]}.base_station"] = route[-1]
        values |= {f"capacity_via.{candidate_label(scene, i, r)}": float(c) for r, c in zip(rs, rates, strict=True)}
    return values
