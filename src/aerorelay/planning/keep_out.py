"""Obstacles in the planners' references: a wrapper around any planner (for any number of relays)
that moves every position reference lying inside a grown obstacle (``[[obstacles]]`` with its
margin) onto the obstacle's nearest surface and drops the reference velocity's component into it.
The NMPC keeps out on its own (its separating planes, ``control/terms.py``); this keeps the
references it tracks outside, so no planner, built in or a user's, asks for a place inside. The
planners that search positions (the capacity planners, the bounds) also exclude them from their
searches (``PlannerContext.obstacles``, ``CapacityLandscape``, the network bound)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..models.obstacles import Obstacle, pushed_out, separating_plane
from .base import Reference


def kept_out(ref: Reference, obstacles: tuple[Obstacle, ...]) -> Reference:
    """``ref`` with ``p_ref`` and ``p_opt`` outside every obstacle (unchanged when already outside)."""
    p = np.asarray(ref.p_ref, float)
    q = pushed_out(obstacles, p)
    goal = pushed_out(obstacles, np.asarray(ref.p_opt, float))
    if np.array_equal(q, p) and np.array_equal(goal, ref.p_opt):
        return ref
    v = np.asarray(ref.v_ref, float)
    for o in obstacles:
        n, c = separating_plane(o, q)
        if float(n @ q) - c < 1e-3:  # on this obstacle's surface: no velocity into it
            v = v - min(0.0, float(n @ v)) * n
    return replace(ref, p_ref=q, p_opt=goal, v_ref=v)


class KeepOutPlanner:
    """A planner (``update(FleetInput) -> {relay: Reference}``, any number of relays) whose every relay's references
    stay outside ``obstacles`` (grown by their margins); ``kept_out_steps`` counts the steps it moved one."""

    def __init__(self, planner, obstacles: tuple[Obstacle, ...]):
        self.planner, self.obstacles = planner, obstacles
        self.kept_out_steps = 0

    def __getattr__(self, name: str):  # the wrapped planner's own attributes (preflight_s, clipped_steps, ...)
        if name == "planner":
            raise AttributeError(name)
        return getattr(self.planner, name)

    def update(self, inp) -> dict[str, Reference]:
        refs = self.planner.update(inp)
        out = {name: kept_out(ref, self.obstacles) for name, ref in refs.items()}
        self.kept_out_steps += any(out[n] is not refs[n] for n in refs)
        return out
