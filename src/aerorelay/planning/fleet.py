"""Planners for a fleet of relays (``[[relays]]``): one call per control step plans every relay.

A fleet planner is an object with ``update(FleetInput) -> dict[relay name, Reference]``, called with
what the fleet knows: every relay's measured state and every source's position over its optical
link. ``EquidistantPlanner`` is what operators do today (Pinto & Almeida, Sensors 2022, compare
optimized chains against it): each relay on its route's straight line from the base station to the
source, evenly spaced.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .trajectory_generator import Reference


@dataclass(frozen=True, kw_only=True)
class FleetInput:
    """What the fleet knows at one control step (world frame, SI units): every vehicle's position
    (m) and velocity (m/s) by node name (relays: measured; sources: over their optical links)."""

    t: float
    dt: float
    positions: Mapping[str, np.ndarray]
    velocities: Mapping[str, np.ndarray]


class FleetPlanner(Protocol):
    def update(self, inp: FleetInput) -> dict[str, Reference]: ...


@dataclass(frozen=True, kw_only=True)
class EquidistantSettings:
    """The reference moves toward its target at most ``speed_m_s`` (m/s) and stays ``margin_m`` (m)
    inside the workspace box ``[workspace_min, workspace_max]`` (m, world)."""

    speed_m_s: float = 1.0
    margin_m: float = 0.05
    workspace_min: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    workspace_max: tuple[float, float, float] = (np.inf, np.inf, np.inf)


def equidistant_targets(routes: Sequence[Sequence[str]], positions: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each relay's place on its route: relay ``k`` (1-based from the base station) of a route with
    ``K`` relays at ``p_bs + k / (K + 1) (p_source - p_bs)``; a relay on several routes at the mean
    of its places. ``routes``: ``[source, relay, ..., bs]``; ``positions``: the sources' and the base
    station's (m, world)."""
    places: dict[str, list[np.ndarray]] = {}
    for route in routes:
        src, relays, bs = route[0], list(route[1:-1]), route[-1]
        p_src, p_bs = np.asarray(positions[src], float), np.asarray(positions[bs], float)
        n = len(relays)
        for k, name in enumerate(reversed(relays), start=1):  # counted from the base station
            places.setdefault(name, []).append(p_bs + k / (n + 1) * (p_src - p_bs))
    return {name: np.mean(p, axis=0) for name, p in places.items()}


class EquidistantPlanner:
    """Relays evenly spaced on the line from the base station to their source
    (``equidistant_targets``), each reference moving toward its place at a speed limit and kept
    inside the workspace; no antenna-axis reference (the thrust direction follows the flight, as an
    operator's relay flies)."""

    def __init__(self, routes: Sequence[Sequence[str]], relay_starts: Mapping[str, np.ndarray], settings: EquidistantSettings):
        self.routes = [list(r) for r in routes]
        self.settings = settings
        self.refs = {n: np.asarray(p, float).copy() for n, p in relay_starts.items()}
        lo, hi = np.asarray(settings.workspace_min, float), np.asarray(settings.workspace_max, float)
        self.lo, self.hi = lo + settings.margin_m, hi - settings.margin_m

    def update(self, inp: FleetInput) -> dict[str, Reference]:
        targets = equidistant_targets(self.routes, inp.positions)
        out = {}
        for name, ref in self.refs.items():
            goal = np.clip(targets[name], self.lo, self.hi)
            step = goal - ref
            dist = float(np.linalg.norm(step))
            most = self.settings.speed_m_s * inp.dt
            if dist > most:
                step = step * (most / dist)
            new = ref + step
            self.refs[name] = new
            out[name] = Reference(p_opt=goal, p_ref=new.copy(), v_ref=step / inp.dt, a_ref=np.zeros(3))
        return out
