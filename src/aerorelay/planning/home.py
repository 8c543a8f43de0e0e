"""A relay flying home to land (its battery's energy left is what getting home needs plus the reserve:
``models/battery.py``): level at its return speed to above its home, then straight down at its landing
speed to its landing point, through the one reference shaper (``planning/shaper.py``: speed, braking on
the goal, bounded acceleration), level-only (no antenna axis to hold: it has left the network). A spare
flying to the place of a relay that will go home (``PlaceFlight``): straight at its return speed to beside
that relay, through the same shaper, until it takes the place."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .shaper import ReferenceShaper, ShaperSettings
from .trajectory_generator import Reference

LANDED_WITHIN_M = 0.3  # the relay is down once its reference is on the landing point and it is this close to it
SETTLE_S = 2.0  # the relay's lag behind its reference at the landing point (the chain's relay: 1.2 s measured, 2026-12-05)


@dataclass(frozen=True)
class HomeSettings:
    """Where a relay lands (m, world: its home's x, y and the landing height), how fast it gets there (m/s:
    level, then down) and its reference shaper's limits on the way."""

    landing_m: tuple[float, float, float]
    return_speed_m_s: float
    land_speed_m_s: float
    shaper: ShaperSettings


def extra_time_s(settings: HomeSettings) -> float:
    """What the way home takes beyond ``d / v_home + h / v_land`` (s): speeding up to the return speed and braking
    from it (``v / 2a`` each), braking the descent, and ``SETTLE_S`` for the relay to follow its reference down."""
    shaper = settings.shaper
    brake = min(shaper.brake_accel_m_s2, shaper.max_accel_m_s2)
    v, w = settings.return_speed_m_s, settings.land_speed_m_s
    return v / (2.0 * shaper.max_accel_m_s2) + v / (2.0 * brake) + w / (2.0 * brake) + SETTLE_S


class _ShapedFlight:
    """A level-only flight through the reference shaper at the return speed (``HomeSettings``) from ``p0`` (m) and
    ``v0`` (m/s): ``_toward(goal, dt, p1, v1)`` moves the reference one step toward ``goal`` (m, world)."""

    def __init__(self, settings: HomeSettings, p0: np.ndarray, v0: np.ndarray):
        self.settings = settings
        self.shaper = ReferenceShaper(replace(settings.shaper, speed_m_s=settings.return_speed_m_s, tilt_limit=0.0))
        self.shaper.p_ref, self.shaper.v_ref = np.asarray(p0, float).copy(), np.asarray(v0, float).copy()

    def _toward(self, goal: np.ndarray, dt: float, p1: np.ndarray, v1: np.ndarray) -> Reference:
        sh = self.shaper
        assert sh.p_ref is not None
        v_ref = sh.advance(goal, dt)
        return Reference(p_opt=goal.copy(), p_ref=sh.p_ref.copy(), v_ref=v_ref, a_ref=sh.acceleration(p1, v1, None), axis=None)


class HomeFlight(_ShapedFlight):
    """``reference(dt, p1, v1)`` each control step from where the relay turned home (``p0`` m, ``v0`` m/s);
    ``landed(p1)`` once it is down (see the module)."""

    def __init__(self, settings: HomeSettings, p0: np.ndarray, v0: np.ndarray):
        super().__init__(settings, p0, v0)
        self.down = np.asarray(settings.landing_m, float)
        self.above = np.array([self.down[0], self.down[1], max(float(p0[2]), float(self.down[2]))])
        self.phase = "return"  # return (level, toward above home), descend

    def reference(self, dt: float, p1: np.ndarray, v1: np.ndarray) -> Reference:
        sh = self.shaper
        assert sh.p_ref is not None
        if self.phase == "return" and float(np.linalg.norm(sh.p_ref - self.above)) < 1e-6:
            self.phase = "descend"
            sh.speed = self.settings.land_speed_m_s
        return self._toward(self.above if self.phase == "return" else self.down, dt, p1, v1)

    def landed(self, p1: np.ndarray) -> bool:
        """Whether the relay is down: its reference on the landing point and itself within ``LANDED_WITHIN_M`` of it."""
        assert self.shaper.p_ref is not None
        return (self.phase == "descend" and float(np.linalg.norm(self.shaper.p_ref - self.down)) < 1e-6
                and float(np.linalg.norm(np.asarray(p1, float) - self.down)) < LANDED_WITHIN_M)


PLACE_CLEARANCE_M = 1.0  # a spare waits this much beyond the separation from the relay whose place it takes (m)


def beside(relay: np.ndarray, spare: np.ndarray, distance_m: float) -> np.ndarray:
    """Where a spare waits for a relay's place: ``distance_m`` from the relay at ``relay`` (m, world), level with
    it, on the side the spare at ``spare`` comes from (along x when it is right above or below)."""
    relay, spare = np.asarray(relay, float), np.asarray(spare, float)
    d = spare[0:2] - relay[0:2]
    n = float(np.linalg.norm(d))
    u = d / n if n > 1e-9 else np.array([1.0, 0.0])
    return np.array([relay[0] + distance_m * u[0], relay[1] + distance_m * u[1], relay[2]])


def transit_time_s(spare: np.ndarray, relay: np.ndarray, relay_velocity: np.ndarray, speed_m_s: float,
                   distance_m: float) -> float:
    """How long a spare at ``spare`` (m) flying at ``speed_m_s`` takes to come within ``distance_m`` of a relay at
    ``relay`` (m) moving at ``relay_velocity`` (m/s): the gap over the closing speed, the spare's speed less the
    relay's speed away from it (at least a quarter of the spare's: a relay flying away as fast is caught up with
    only once it slows), at cruise (the speeding up and braking: ``extra_time_s``)."""
    d = np.asarray(relay, float) - np.asarray(spare, float)
    gap = float(np.linalg.norm(d))
    away = max(0.0, float(np.dot(relay_velocity, d)) / gap) if gap > 1e-9 else 0.0
    return max(gap - distance_m, 0.0) / max(speed_m_s - away, 0.25 * speed_m_s)


class PlaceFlight(_ShapedFlight):
    """``reference(dt, p1, v1, goal)`` each control step from where a spare launched (``p0`` m, ``v0`` m/s) toward
    ``goal`` (m, world; it moves with the relay whose place the spare takes): straight, at the spare's return speed
    (``HomeSettings``), level-only."""

    def reference(self, dt: float, p1: np.ndarray, v1: np.ndarray, goal: np.ndarray) -> Reference:
        return self._toward(np.asarray(goal, float), dt, p1, v1)
