"""Radio blockage by obstacles (``[[obstacles]] nlos_loss_db``): in the plant's true channel a link
whose straight segment crosses an obstacle loses that many dB (the largest loss when it crosses
several). Obstacles with ``nlos_loss_db = 0`` (the default) let radio through. Only the plant's
channel has it: the planners and the bounds plan with line of sight (stated in the docs), so a
blocked link shows what a structure costs a relay that does not know it.

A segment crosses a convex obstacle when the obstacle's signed distance is negative somewhere on
it; the check samples ``SEGMENT_SAMPLES`` evenly spaced points (ends included), so it can miss a
corner the segment clips by less than the spacing. Log columns ``nlos_<tx>_<rx>`` (1 blocked, 0 clear).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..models.obstacles import Obstacle
from ..models.radio import RadioScene

SEGMENT_SAMPLES = 129  # points per link segment (a 30 m link: one every 0.23 m)


def crosses(obstacle: Obstacle, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment from ``a`` to ``b`` (m, world) passes inside ``obstacle``."""
    s = np.linspace(0.0, 1.0, SEGMENT_SAMPLES)[:, None]
    return bool(np.min(obstacle.signed_distance(a + s * (b - a))) < 0)


class Blockage:
    """``gains, values = step(scene, t, positions)``: per link of ``scene.link_ends()`` its power
    multiplier ``10^(-L / 10)`` (1 when clear) and the log values."""

    def __init__(self, obstacles: Sequence[Obstacle], losses_db: Sequence[float]):
        self.obstacles = [(o, float(db)) for o, db in zip(obstacles, losses_db, strict=True) if db > 0]

    @property
    def active(self) -> bool:
        return bool(self.obstacles)

    @staticmethod
    def columns(scene: RadioScene) -> list[str]:
        return [f"nlos_{tx}_{rx}" for tx, rx, _ in scene.link_ends()]

    def step(self, scene: RadioScene, t: float, positions: Mapping[str, np.ndarray]) -> tuple[np.ndarray, dict[str, float]]:
        ends = scene.link_ends()
        gains, values = np.ones(len(ends)), {}
        for k, (tx, rx, j) in enumerate(ends):
            a = scene.jammers[j].position_at(t) if j is not None else positions[tx]
            b = positions[rx]
            loss = max((db for o, db in self.obstacles if crosses(o, np.asarray(a, float), np.asarray(b, float))), default=0.0)
            gains[k] = 10.0 ** (-loss / 10.0)
            values[f"nlos_{tx}_{rx}"] = float(loss > 0)
        return gains, values
