"""The air the relays fly in, per control step: the wind (a mean plus Dryden gusts, one series shared
by every relay: the gusts' scale lengths, 30-300 m at 3-300 m altitude, exceed a fleet's spacing),
each relay's plant with its platform's drag in that wind, and its external-force observer.

Log columns: ``wind_x/y/z`` (the wind, m/s, world), per relay ``a_drag_x/y/z`` (the drag's
acceleration at the step's start, m/s^2, world) and, with the observer, ``a_ext_x/y/z`` (its
estimate, what the NMPC's model adds); a fleet's relay columns are prefixed ``<name>.``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..estimation.disturbance import ExternalAccelerationObserver
from ..models.drag import drag_acceleration
from ..models.state import ETA, V
from ..models.streams import stream
from ..models.wind import DrydenTurbulence, low_altitude_parameters

AXES = "xyz"


@dataclass(frozen=True)
class WindSettings:
    """Mean wind (m/s, world), gusts on/off, the wind at 6 m setting their intensity (m/s), the
    altitude of their scale lengths (m)."""

    mean: tuple[float, float, float]
    gusts: bool = False
    w20_m_s: float = 0.0
    altitude_m: float = 10.0


class WindSeries:
    """The wind at the relays every control step: ``next()`` returns it (m/s, world). The gusts'
    ``u`` lies along the mean wind's horizontal direction (+x when it has none), ``v`` across, ``w`` up."""

    def __init__(self, settings: WindSettings, period_s: float, seed: int):
        self.mean = np.asarray(settings.mean, float)
        heading = math.atan2(self.mean[1], self.mean[0]) if math.hypot(self.mean[0], self.mean[1]) > 1e-9 else 0.0
        c, s = math.cos(heading), math.sin(heading)
        self.to_world = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        airspeed = float(np.linalg.norm(self.mean))
        self.gusts = DrydenTurbulence(low_altitude_parameters(settings.w20_m_s, settings.altitude_m), airspeed, period_s,
                                      seed=stream(seed, "wind")) if settings.gusts else None

    def next(self) -> np.ndarray:
        return self.mean + (self.to_world @ self.gusts.sample() if self.gusts is not None else 0.0)


class HeldWind:
    """A ``WindSeries`` as a wind field ``(t, position) -> wind`` (m/s, world) for a simulator outside
    aerorelay (``flight.airframes``): the series' value of control period ``floor(t / period_s)``, held
    over the period as aerorelay's plant holds it; the same everywhere (see the module)."""

    def __init__(self, series: WindSeries, period_s: float):
        self.series, self.period = series, period_s
        self.values: list[np.ndarray] = []

    def __call__(self, t: float, position: np.ndarray) -> np.ndarray:
        k = max(0, int(math.floor(t / self.period + 1e-9)))
        while len(self.values) <= k:
            self.values.append(self.series.next())
        return self.values[k]


@dataclass(frozen=True)
class AirborneRelay:
    """One relay in the wind: its plant ``(x, u, d, w) -> x`` (with drag), its drag coefficients (kg/m
    per body axis), mass (kg), and its observer (None: off)."""

    plant: ca.Function
    drag: np.ndarray
    mass: float
    observer: ExternalAccelerationObserver | None


class Air:
    """The wind and the relays in it. Each control step: ``begin()`` draws the step's wind; per relay
    ``estimate(name)`` (the NMPC's ``a_ext``, None without an observer), ``values(name, x)`` (its log
    values) and ``advance(name, x, u, d)`` (the plant over the step, then the observer's update)."""

    def __init__(self, wind: WindSeries, relays: dict[str, AirborneRelay]):
        self.wind_series, self.relays = wind, relays
        self.wind = wind.mean.copy()

    def begin(self) -> np.ndarray:
        self.wind = self.wind_series.next()
        return self.wind

    def estimate(self, name: str) -> np.ndarray | None:
        obs = self.relays[name].observer
        return None if obs is None else obs.estimate

    def advance(self, name: str, x: np.ndarray, u: np.ndarray, d: np.ndarray) -> np.ndarray:
        r = self.relays[name]
        x_next = np.asarray(r.plant(x, u, d, self.wind)).ravel()
        if r.observer is not None:
            r.observer.update(x, u, x_next)
        return x_next

    def drag(self, name: str, x: np.ndarray) -> np.ndarray:
        r = self.relays[name]
        return np.asarray(drag_acceleration(x[ETA], x[V], self.wind, r.drag, r.mass), float)

    def columns(self, name: str, prefix: str = "") -> list[str]:
        """The relay's columns (``prefix``: ``"<name>."`` in a fleet's log)."""
        own = [f"a_drag_{a}" for a in AXES] + ([f"a_ext_{a}" for a in AXES] if self.relays[name].observer else [])
        return [f"{prefix}{c}" for c in own]

    def wind_columns(self) -> list[str]:
        return [f"wind_{a}" for a in AXES]

    def wind_values(self) -> dict[str, float]:
        return {f"wind_{a}": float(v) for a, v in zip(AXES, self.wind, strict=True)}

    def values(self, name: str, x: np.ndarray, prefix: str = "") -> dict[str, float]:
        """The relay's log values at the step's start (before ``advance``)."""
        out = {f"{prefix}a_drag_{a}": float(v) for a, v in zip(AXES, self.drag(name, x), strict=True)}
        est = self.estimate(name)
        if est is not None:
            out |= {f"{prefix}a_ext_{a}": float(v) for a, v in zip(AXES, est, strict=True)}
        return out
