"""A relay's battery: the energy it draws (the rotors' shaft power, ``Multirotor.shaft_power``, plus a
constant avionics load) against its usable energy; the state of charge is the usable energy left, as a
fraction (1 full, 0 empty), and the reserve the fraction kept to get home. The power at a control step's
start is held over the step, as the run's ``energy_kJ`` counts it.

Getting home from ``d`` m away and ``h`` m above the landing height takes ``E_home = (d / v_home + h /
v_land + t_extra) (P_hover + P_avionics)`` (flying level at the return speed, then descending, at the
hover's shaft power; ``t_extra`` the time speeding up, braking and settling add: drag and a climb's extra
power not counted); a relay goes home at the first step at which the energy left is no more than
``E_home`` plus the reserve: ``E_usable - E_drawn <= E_home + reserve E_usable``."""

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

    def energy_home_j(self, distance_m: float, height_m: float, hover_shaft_w: float, return_speed_m_s: float,
                      land_speed_m_s: float, extra_s: float = 0.0) -> float:
        """``E_home`` (J): ``distance_m`` level at ``return_speed_m_s``, then ``height_m`` down at ``land_speed_m_s``, and
        ``extra_s`` more (s), at the hover's shaft power plus the avionics' load (see the module)."""
        flight_s = distance_m / return_speed_m_s + max(height_m, 0.0) / land_speed_m_s + extra_s
        return flight_s * (hover_shaft_w + self.avionics_w)

    def must_go_home(self, drawn_j: float, energy_home_j: float) -> bool:
        """Whether the energy left is no more than getting home needs plus the reserve."""
        return self.usable_j - drawn_j <= energy_home_j + self.reserve_fraction * self.usable_j

    def draw(self, shaft_power_w: float, seconds: float) -> float:
        """The energy (J) drawn over ``seconds`` at the rotors' ``shaft_power_w`` (W) and the avionics' load."""
        return (shaft_power_w + self.avionics_w) * seconds
