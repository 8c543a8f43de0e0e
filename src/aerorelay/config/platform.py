"""``[platform]``: the relay vehicle (MRAV-1) as data. The vehicle model is built from it in
``assembly.vehicle``; whether it can hover with its margin is checked there (``assembly.checks``)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ..models.vehicle import HEXAROTOR_ARM_LENGTH_M
from .base import Strict, Vec3, nonzero_direction

MIN_MOTOR_RATE_HZ_S = 20.0  # slower motors cannot follow a braking manoeuvre (|omega_dot| bounds below this are rejected)


class Rotor(Strict):
    """One rotor of a custom GTMR layout (body frame)."""

    position: Vec3 = Field(description="the rotor's position p_m_i, m (body frame)")
    axis: Vec3 = Field(description="the rotor's thrust axis z_P_i (body frame; normalized, not zero)")
    spin: Literal[-1, 1] = Field(description="s_i: the sign of the rotor's drag moment about its axis")

    _nonzero = field_validator("axis")(lambda v: nonzero_direction(v, "a rotor's thrust axis"))


FOOTPRINT_PER_ARM = 1.5  # a vehicle's reach over its farthest rotor centre: the arm plus a rotor of half its length


class BatteryConfig(Strict):
    """A relay's battery (``[platform.battery]``): its energy, the share of it that can be drawn, the reserve
    kept to get home, and the avionics' constant load besides the rotors' shaft power."""

    capacity_wh: float = Field(gt=0.0, le=1e5, description="nominal energy, Wh")
    usable_fraction: float = Field(0.9, gt=0.0, le=1.0, description="the share of capacity_wh that can be drawn")
    reserve_fraction: float = Field(0.2, ge=0.0, lt=1.0, description="the share of the usable energy kept to get home: "
                                    "reaching it is logged and timed")
    avionics_w: float = Field(15.0, ge=0.0, le=1e4, description="constant electrical load besides the rotors, W")
    go_home: bool = Field(True, description="fly home (the relay's start) and land once the energy left is what getting "
                          "there needs plus the reserve; the relay leaves the network then (the others re-plan)")
    return_speed_m_s: float = Field(2.0, gt=0.0, le=20.0, description="the speed it flies home at, m/s")
    land_speed_m_s: float = Field(0.5, gt=0.0, le=5.0, description="the speed it descends at once home, m/s")


class PlatformConfig(Strict):
    """Relay vehicle (MRAV-1). Hexarotor by default; ``rotors`` overrides the layout."""

    rotor_count: int = Field(6, ge=3, le=16, description="rotors of the star layout (arms evenly spaced)")
    tilt_deg: float = Field(20.0, ge=0.0, le=60.0, description="alternating tilt of each rotor about its arm, deg")
    arm_length_m: float = Field(HEXAROTOR_ARM_LENGTH_M, gt=0.0, le=5.0, description="star layout: distance of every rotor "
                                "from the centre of mass, m")
    rotors: list[Rotor] | None = Field(None, min_length=4, description="custom layout; overrides tilt/arm")
    battery: BatteryConfig | None = Field(None, description="its battery: state of charge logged per relay (none: not "
                                          "modelled)")
    mass_kg: float = Field(2.57, gt=0.0, description="m, kg (Table I)")
    inertia_kgm2: Vec3 = Field(default_factory=lambda: [0.11, 0.11, 0.19], description="diagonal of J, kg m^2")
    gravity_m_s2: float = Field(9.81, gt=0.0, description="g, m/s^2")
    c_xi: float = Field(1.18e-3, gt=0.0, description="thrust coefficient, N/Hz^2")
    c_tau: float = Field(2.5e-5, ge=0.0, description="drag-moment coefficient, N m/Hz^2")
    omega_min_hz: float = Field(16.0, ge=0.0, description="lowest motor speed Omega, Hz (rev/s; thrust c_xi Omega^2)")
    omega_max_hz: float = Field(100.0, gt=0.0, description="highest motor speed Omega, Hz")
    omega_dot_min_hz_s: float = Field(-300.0, le=-MIN_MOTOR_RATE_HZ_S, description="most negative motor acceleration, Hz/s")
    omega_dot_max_hz_s: float = Field(400.0, ge=MIN_MOTOR_RATE_HZ_S, description="largest motor acceleration, Hz/s")
    drag_area_m2: Vec3 = Field(default_factory=lambda: [0.05, 0.05, 0.12], description="C_d A along body x, y, z, "
                               "m^2: the parasitic drag 0.5 rho C_d A |v_air| v_air per body axis (RotorPy's drag model); "
                               "default an estimate for a 0.7 m hexarotor (frame and arms ~0.05 m^2 side-on, the rotor "
                               "disks face-on), not a measurement; only [wind] uses it")
    min_hover_margin: float = Field(0.2, ge=0.0, lt=1.0, description="fraction of omega_max_hz every motor keeps "
                                    "above its hover speed (thrust headroom to brake and recover)")

    @property
    def footprint_radius_m(self) -> float:
        """How far the vehicle reaches from its centre of mass, m: its farthest rotor centre times
        ``FOOTPRINT_PER_ARM`` (the arm plus a rotor disc of half the arm's length; rotor sizes are not
        modelled, this is a stated allowance)."""
        arm = self.arm_length_m if self.rotors is None else max(math.hypot(*r.position) for r in self.rotors)
        return FOOTPRINT_PER_ARM * arm

    @field_validator("drag_area_m2")
    @classmethod
    def _non_negative_drag(cls, v):
        if min(v) < 0:
            raise ValueError(f"every drag area must be >= 0 m^2, got {v}")
        return v

    @field_validator("inertia_kgm2")
    @classmethod
    def _positive_inertia(cls, v):
        if min(v) <= 0:
            raise ValueError(f"every principal inertia must be > 0 kg m^2, got {v}")
        return v

    @model_validator(mode="after")
    def _ordered_speeds(self):
        if self.omega_min_hz >= self.omega_max_hz:
            raise ValueError(
                f"omega_min_hz ({self.omega_min_hz}) must be < omega_max_hz ({self.omega_max_hz})"
            )
        return self
