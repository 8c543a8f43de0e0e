"""A relay's battery: the energy it draws (the rotors' shaft power, ``Multirotor.shaft_power``, plus a
constant avionics load) against its usable energy; the state of charge is the usable energy left, as a
fraction (1 full, 0 empty), and the reserve the fraction kept to get home. The power at a control step's
start is held over the step, as the run's ``energy_kJ`` counts it."""

from __future__ import annotations

from dataclasses import dataclass

from . import checks


@dataclass(frozen=True)
class Battery:
    """Usable energy (J), the reserve (fraction of it) and the avionics' load (W)."""

    usable_j: float
    reserve_fraction: float
    avionics_w: float

    def __post_init__(self):
        checks.number("Battery", "usable_j", self.usable_j, lo=0.0, lo_open=True)
        checks.number("Battery", "reserve_fraction", self.reserve_fraction, lo=0.0)
        checks.number("Battery", "avionics_w", self.avionics_w, lo=0.0)

    def state_of_charge(self, drawn_j: float) -> float:
        """The usable energy left after ``drawn_j`` (J), as a fraction (negative once overdrawn)."""
        return 1.0 - drawn_j / self.usable_j

    def draw(self, shaft_power_w: float, seconds: float) -> float:
        """The energy (J) drawn over ``seconds`` at the rotors' ``shaft_power_w`` (W) and the avionics' load."""
        return (shaft_power_w + self.avionics_w) * seconds
