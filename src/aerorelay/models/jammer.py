"""Jammers: position (fixed or along timed waypoints), power schedule, antenna, localization delay (Sec. VIII).

Times in s, power in W, positions m (world). "OFF" means zero radiated power. The controller
learns a jammer's position only ``localization_delay`` s after the mission starts (``tau_E``).
The paper's jammer is isotropic and fixed; a directional one (``CosinePattern``) points its
boresight at a named node, tracking it, or along a fixed world direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from . import checks
from .antenna import AntennaPattern, IsotropicPattern
from .backend import is_symbolic
from .geometry import E3
from .mission import SourceTrajectory


@dataclass(frozen=True)
class AlwaysOn:
    """The jammer radiates for the whole mission."""

    def is_on(self, t):
        return np.ones_like(np.asarray(t, dtype=float), dtype=bool)


@dataclass(frozen=True)
class PeriodicOnOff:
    """ON for ``on_s`` then OFF for ``off_s``, repeating from ``phase_s`` (ON first).

    The paper's ON-OFF case is 5 s / 5 s; its fast-switching case is 0.1 s / 0.1 s.
    """

    on_s: float
    off_s: float
    phase_s: float = 0.0

    def __post_init__(self):
        checks.number("PeriodicOnOff", "on_s", self.on_s, lo=0.0, lo_open=True)
        checks.number("PeriodicOnOff", "off_s", self.off_s, lo=0.0, lo_open=True)
        checks.number("PeriodicOnOff", "phase_s", self.phase_s)

    def is_on(self, t):
        tau = np.mod(np.asarray(t, dtype=float) - self.phase_s, self.on_s + self.off_s)
        return tau < self.on_s


@dataclass(frozen=True)
class Jammer:
    """A jammer at ``position`` (m, world; its start when it moves along ``path``) with peak power
    ``power`` (W). Its antenna ``pattern`` is isotropic by default; a directional pattern's
    boresight points at the node named ``point_at`` (tracking it) or along ``boresight`` (world)."""

    position: np.ndarray
    power: float
    schedule: AlwaysOn | PeriodicOnOff = AlwaysOn()
    localization_delay: float = 2.0
    path: SourceTrajectory | None = None
    pattern: AntennaPattern = IsotropicPattern(1.0)
    point_at: str | None = None
    boresight: np.ndarray = field(default_factory=lambda: E3.copy())
    name: str = "jammer"

    def __post_init__(self):
        """Checked when made (``models.checks``): a named error, never a silent NaN or a negative power."""
        checks.text("Jammer", "name", self.name)
        who = f"Jammer({self.name!r})"
        checks.vector(who, "position", self.position)
        checks.number(who, "power", self.power, lo=0.0)
        checks.number(who, "localization_delay", self.localization_delay, lo=0.0)
        checks.has_method(who, "schedule", self.schedule, "is_on", "a schedule (AlwaysOn, PeriodicOnOff)")
        if self.path is not None:
            checks.has_method(who, "path", self.path, "state", "a path (models.mission)")
        checks.has_method(who, "pattern", self.pattern, "gain_from_cos", "an antenna pattern")
        checks.text(who, "point_at", self.point_at, optional=True)
        checks.vector(who, "boresight", self.boresight, nonzero=True)

    def power_at(self, t):
        """Radiated power (W) at time ``t`` s: ``power`` when ON, 0 when OFF."""
        return np.where(self.schedule.is_on(t), self.power, 0.0)

    def position_at(self, t: float) -> np.ndarray:
        """Position (m, world) at time ``t`` s."""
        return np.asarray(self.position, float) if self.path is None else self.path.state(t).p

    def axis(self, position: np.ndarray, target=None) -> np.ndarray:
        """Boresight (unit, world) from ``position`` toward ``target`` (``(..., 3)``, the tracked
        node's position) or the fixed ``boresight``."""
        if self.point_at is None or target is None:
            return np.asarray(self.boresight, float)
        if is_symbolic(target, position):  # CasADi 3-vectors
            d = target - position
            return d / ca.norm_2(d)
        d = np.asarray(target, float) - position
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def is_localized(self, t) -> bool:
        """Whether the controller knows the jammer position at time ``t`` (``t >= tau_E``)."""
        return bool(t >= self.localization_delay)

    def planned_power(self, t: float, senses_state: bool = False) -> float:
        """The power (W) a controller told of this jammer plans with at ``t``: 0 before its localization
        (``tau_E``); afterwards the nominal power, or the power radiated now when it senses the schedule."""
        if not self.is_localized(t):
            return 0.0
        return float(self.power_at(t)) if senses_state else self.power


class JammerTruthHidden(LookupError):
    """A planner or controller asked where a jammer truly is, or what it truly radiates: they know
    only what the relay was told or estimated (``PlannerInput``), never the plant's truth."""


@dataclass(frozen=True)
class HiddenJammer(Jammer):
    """A jammer as the relay's world view holds it: its name, antenna pattern and pointing (what
    the controllers model), no true position, path, power or schedule. ``position_at`` and
    ``power_at`` raise JammerTruthHidden, so a channel evaluated without the known positions and
    powers fails loudly instead of silently using the truth."""

    def __post_init__(self):
        checks.text("Jammer", "name", self.name)

    @classmethod
    def of(cls, j: Jammer) -> HiddenJammer:
        return cls(np.full(3, np.nan), float("nan"), AlwaysOn(), j.localization_delay, None, j.pattern, j.point_at,
                   np.asarray(j.boresight, float).copy(), j.name)

    def position_at(self, t: float) -> np.ndarray:
        raise JammerTruthHidden(f"jammer {self.name!r}: its true position is not in the relay's world view; pass the "
                                "positions the relay knows (PlannerInput.jammer_positions)")

    def power_at(self, t):
        raise JammerTruthHidden(f"jammer {self.name!r}: its true power is not in the relay's world view; pass the powers "
                                "the relay assumes (PlannerInput.jammer_powers)")
