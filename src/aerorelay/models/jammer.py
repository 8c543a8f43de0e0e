"""Ground jammer: isotropic radiator with a power schedule and a localization delay (Sec. VIII).

Times in s, power in W. "OFF" means zero radiated power. The controller learns the jammer's
position only ``localization_delay`` s after the mission starts (``tau_E``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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

    def is_on(self, t):
        tau = np.mod(np.asarray(t, dtype=float) - self.phase_s, self.on_s + self.off_s)
        return tau < self.on_s


@dataclass(frozen=True)
class Jammer:
    """Isotropic ground jammer at ``position`` (m, world) with peak power ``power`` (W)."""

    position: np.ndarray
    power: float
    schedule: AlwaysOn | PeriodicOnOff = AlwaysOn()
    localization_delay: float = 2.0

    def power_at(self, t):
        """Radiated power (W) at time ``t`` s: ``power`` when ON, 0 when OFF."""
        return np.where(self.schedule.is_on(t), self.power, 0.0)

    def is_localized(self, t) -> bool:
        """Whether the controller knows the jammer position at time ``t`` (``t >= tau_E``)."""
        return bool(t >= self.localization_delay)
